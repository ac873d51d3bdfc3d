// SPDX-License-Identifier: MIT
// L4: the Stable Fluids baseline, and agreement between the grid and the
// Legendre solutions at equal time for smooth initial conditions.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "procam/legendre/fluid.hpp"
#include "procam/legendre/grid_fluid.hpp"

namespace procam::legendre {
namespace {

Box unit_box() {
  Box b;
  b.lo = {-1, -1, 0};
  b.hi = {1, 1, 1};
  return b;
}

// A swirl that is divergence-free with zero normal velocity on the walls:
// psi = A (1-x^2)^2 (1-y^2)^2, u = d psi/dy, v = -d psi/dx.
double swirl_u(double x, double y) { return 0.8 * (1 - x * x) * (1 - x * x) * 2 * (1 - y * y) * (-2 * y); }
double swirl_v(double x, double y) { return -0.8 * (1 - y * y) * (1 - y * y) * 2 * (1 - x * x) * (-2 * x); }
double blob(double x, double y) { return std::exp(-3.0 * ((x - 0.3) * (x - 0.3) + (y + 0.1) * (y + 0.1))); }

// Relative L2 difference of two sampled fields.
double rel_l2(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0, den = 0;
  for (size_t i = 0; i < a.size(); ++i) num += (a[i] - b[i]) * (a[i] - b[i]), den += b[i] * b[i];
  return std::sqrt(num / den);
}

TEST(GridFluid, EnergyDoesNotGrowWithoutForces) {
  GridFluid g(2, Shape{48, 48, 1}, unit_box(), {});
  std::array<Field, 3> u;
  const Box b = unit_box();
  u[0] = project([](double x, double y, double) { return swirl_u(x, y) + 0.3 * x; }, cube_shape(2, 8), b, 10);
  u[1] = project([](double x, double y, double) { return swirl_v(x, y); }, cube_shape(2, 8), b, 10);
  u[2] = zero_field(2, 8, b);
  g.set_from(u, zero_field(2, 8, b));
  g.project();
  double e = g.kinetic_energy();
  for (int s = 0; s < 20; ++s) {
    g.step(0.05);
    EXPECT_LE(g.kinetic_energy(), e * (1 + 1e-9)) << s;
    e = g.kinetic_energy();
  }
  EXPECT_THROW(GridFluid(2, Shape{2, 8, 1}, unit_box(), {}), std::invalid_argument);
}

// The two solvers at equal time (T = 0.5 s, dt = 0.01 s) from the same
// smooth swirl and density blob, the grid's pressure solved by CG (20
// Gauss-Seidel sweeps do not converge on fine grids). Stated tolerance:
// relative L2 difference below 3% for density and u_x at 128^2, and it
// shrinks as the grid refines (measured: 3.9%/4.0% at 64^2, 2.0%/1.8% at
// 128^2, 1.4%/0.9% at 256^2): the difference is the grid's own error.
TEST(GridFluid, AgreesWithLegendreForSmoothFlow) {
  const Box b = unit_box();
  const size_t n = 12;
  LegendreFluid lf(2, n, b, {});
  lf.velocity[0] = project([](double x, double y, double) { return swirl_u(x, y); }, lf.velocity[0].n, b, 16);
  lf.velocity[1] = project([](double x, double y, double) { return swirl_v(x, y); }, lf.velocity[1].n, b, 16);
  lf.density = project([](double x, double y, double) { return blob(x, y); }, lf.density.n, b, 24);
  const auto u0 = lf.velocity;
  const Field r0 = lf.density;
  const double dt = 0.01;
  for (int s = 0; s < 50; ++s) ASSERT_TRUE(lf.step(dt).ok);
  double prev = 1e9;
  for (size_t cells : {64u, 128u}) {
    const Shape g{cells, cells, 1};
    GridParams gp;
    gp.cg_pressure = true;
    GridFluid gf(2, g, b, gp);
    gf.set_from(u0, r0);
    for (int s = 0; s < 50; ++s) gf.step(dt);
    const double er = rel_l2(gf.density, evaluate_grid(lf.density, g));
    const double eu = rel_l2(gf.velocity[0], evaluate_grid(lf.velocity[0], g));
    std::cout << "[ measured ] grid " << cells << "^2 vs Legendre n=" << n << " at T=0.5 s: density rel L2 " << er
              << ", u_x rel L2 " << eu << "\n";
    EXPECT_LT(er, prev);
    prev = er;
    if (cells == 128) {
      EXPECT_LT(er, 0.03);
      EXPECT_LT(eu, 0.03);
    }
  }
}

}  // namespace
}  // namespace procam::legendre
