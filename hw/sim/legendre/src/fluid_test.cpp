// SPDX-License-Identifier: MIT
// L2: projection, energy, CFL, diffusion and dissipation against closed
// forms and invariants.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "procam/legendre/fluid.hpp"

namespace procam::legendre {
namespace {

Box box_of(size_t dims, double half) {
  Box b;
  for (size_t a = 0; a < 3; ++a) b.lo[a] = -half, b.hi[a] = half;
  if (dims == 2) b.lo[2] = 0, b.hi[2] = 1;
  return b;
}

void randomize(LegendreFluid& f, unsigned seed, double scale) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t a = 0; a < f.dims(); ++a)
    for (size_t i = 0; i < f.velocity[a].size(); ++i) {
      const size_t k = i % f.n() + (i / f.n()) % f.n();  // decay with degree: smooth fields
      f.velocity[a].c[i] = scale * g(rng) / (1.0 + static_cast<double>(k * k));
    }
  for (size_t i = 0; i < f.density.size(); ++i) f.density.c[i] = g(rng) / (1.0 + static_cast<double>(i));
}

// Eq. 6.19-6.20: after projection div u <= 1e-9 in the L2 norm over the box
// (velocity of order 1 m/s on a 2 m box) and u.n <= 1e-9 on every wall.
TEST(LegendreFluid, ProjectionIsDivergenceFreeAndIdempotent) {
  for (size_t dims : {2u, 3u}) {
    LegendreFluid f(dims, dims == 2 ? 10 : 5, box_of(dims, 1.0), {});
    randomize(f, 7, 1.0);
    const double e0 = f.kinetic_energy();
    EXPECT_GT(f.divergence_l2(), 0.1);
    f.project();
    EXPECT_LE(f.divergence_l2(), 1e-9) << dims;
    EXPECT_LE(f.wall_normal_max(), 1e-9) << dims;
    EXPECT_LE(f.kinetic_energy(), e0);     // an orthogonal projection never adds energy
    EXPECT_GT(f.kinetic_energy(), 1e-3);   // and leaves a nontrivial flow
    const auto u = f.velocity;
    f.project();
    for (size_t a = 0; a < dims; ++a)
      for (size_t i = 0; i < u[a].size(); ++i) EXPECT_NEAR(f.velocity[a].c[i], u[a].c[i], 1e-12);
  }
}

// A flow from a stream function that vanishes with its normal derivative on
// the walls is already admissible: projection must not change it.
TEST(LegendreFluid, ProjectionKeepsAnAdmissibleFlow) {
  const Box b = box_of(2, 1.0);
  // psi = (1-x^2)^2 (1-y^2)^2 ; u = d psi/dy, v = -d psi/dx.
  auto u = [](double x, double y, double) { return (1 - x * x) * (1 - x * x) * 2 * (1 - y * y) * (-2 * y); };
  auto v = [](double x, double y, double) { return -(1 - y * y) * (1 - y * y) * 2 * (1 - x * x) * (-2 * x); };
  LegendreFluid f(2, 6, b, {});
  f.velocity[0] = project(u, f.velocity[0].n, b, 8);
  f.velocity[1] = project(v, f.velocity[1].n, b, 8);
  const auto before = f.velocity;
  f.project();
  for (size_t a = 0; a < 2; ++a)
    for (size_t i = 0; i < before[a].size(); ++i) EXPECT_NEAR(f.velocity[a].c[i], before[a].c[i], 1e-12);
}

// Without forces kinetic energy never grows (advection conserves it up to
// the non-expansive RK4 factor, diffusion and projection only remove it),
// and neither does int r^2 without sources.
TEST(LegendreFluid, EnergyNeverGrowsWithoutForces) {
  for (size_t dims : {2u, 3u})
    for (double nu : {0.0, 0.02}) {
      FluidParams p;
      p.viscosity = nu;
      p.diffusion = nu;
      LegendreFluid f(dims, dims == 2 ? 8 : 4, box_of(dims, 1.0), p);
      randomize(f, 3, 2.0);
      f.project();
      const double e_start = f.kinetic_energy();
      double e = e_start, m = squared_norm(f.density);
      for (int s = 0; s < 40; ++s) {
        const StepReport r = f.step(0.02);
        ASSERT_TRUE(r.ok) << r.error;
        EXPECT_LE(r.energy_after, e * (1 + 1e-12)) << "dims=" << dims << " nu=" << nu << " step " << s;
        const double m1 = squared_norm(f.density);
        EXPECT_LE(m1, m * (1 + 1e-12)) << "density, step " << s;
        e = r.energy_after;
        m = m1;
        EXPECT_LE(f.divergence_l2(), 1e-9);
      }
      if (nu > 0) {
        EXPECT_LT(e, 0.99 * e_start);  // viscosity removes energy
      }
    }
}

TEST(LegendreFluid, StepAboveCflIsSubsteppedOrRefused) {
  LegendreFluid f(2, 8, box_of(2, 1.0), {});
  randomize(f, 5, 3.0);
  f.project();
  const double lim = f.dt_limit();
  ASSERT_TRUE(std::isfinite(lim));
  const double e0 = f.kinetic_energy();
  const StepReport r = f.step(20.5 * lim);
  EXPECT_TRUE(r.ok);
  EXPECT_GE(r.substeps, 21);
  EXPECT_NEAR(r.dt_limit, lim, 1e-12 * lim);
  EXPECT_LE(r.energy_after, e0 * (1 + 1e-12));
  for (const auto& u : f.velocity)
    for (double c : u.c) EXPECT_TRUE(std::isfinite(c));

  FluidParams refuse;
  refuse.cfl = CflPolicy::kRefuse;
  LegendreFluid g(2, 8, box_of(2, 1.0), refuse);
  randomize(g, 5, 3.0);
  g.project();
  const auto before = g.velocity;
  const StepReport q = g.step(2.0 * g.dt_limit());
  EXPECT_FALSE(q.ok);
  EXPECT_NE(q.error.find("CFL"), std::string::npos);
  EXPECT_EQ(g.velocity[0].c, before[0].c);  // state untouched
  EXPECT_TRUE(g.step(0.5 * g.dt_limit()).ok);
  EXPECT_FALSE(g.step(-1.0).ok);
}

// Eq. 6.16 for a density at rest: r = 1 + 0.5 cos(pi x) on [-1, 1] decays as
// exp(-kappa pi^2 t) (its Neumann eigenmode); implicit Euler with N steps
// gives (1 + kappa pi^2 dt)^-N, which we compare against (time error 6e-4).
TEST(LegendreFluid, DiffusionMatchesTheHeatEquation) {
  FluidParams p;
  p.diffusion = 0.05;
  const Box b = box_of(2, 1.0);
  LegendreFluid f(2, 14, b, p);
  f.density = project([](double x, double, double) { return 1 + 0.5 * std::cos(std::numbers::pi * x); },
                      f.density.n, b, 30);
  for (int s = 0; s < 100; ++s) ASSERT_TRUE(f.step(0.01).ok);
  const double decay = std::exp(-0.05 * std::numbers::pi * std::numbers::pi);
  for (double x : {-1.0, -0.4, 0.0, 0.7})
    EXPECT_NEAR(evaluate(f.density, {x, 0.3, 0}), 1 + 0.5 * std::cos(std::numbers::pi * x) * decay, 2e-3);
}

// Eq. 6.21: with no flow a uniform density decays as (1 + dt alpha)^-N.
TEST(LegendreFluid, DissipationIsTheClosedForm) {
  FluidParams p;
  p.dissipation = 0.5;
  LegendreFluid f(3, 4, box_of(3, 2.0), p);
  f.density.c[0] = 2.0;
  for (int s = 0; s < 10; ++s) ASSERT_TRUE(f.step(0.1).ok);
  EXPECT_NEAR(f.density.c[0], 2.0 * std::pow(1.05, -10), 1e-14);
  EXPECT_THROW(LegendreFluid(4, 4, Box{}, p), std::invalid_argument);
  EXPECT_THROW(LegendreFluid(2, 2, Box{}, p), std::invalid_argument);
  FluidParams neg;
  neg.viscosity = -1.0;
  EXPECT_THROW(LegendreFluid(2, 4, Box{}, neg), std::invalid_argument);
  // A non-finite state is refused, not propagated.
  f.velocity[0].c[1] = std::nan("");
  const StepReport r = f.step(0.1);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("NaN"), std::string::npos);
}

// A passive scalar (advected albedo) gets the density's transport and
// nothing else. Started equal to the density in a swirling flow: without
// dissipation it stays equal to it (1e-12) and moves; with dissipation
// alpha = 0.3 /s the density's mean decays while the scalar's mean is
// conserved (transport by a divergence-free flow with no flux through the
// walls conserves it, 1e-8). A scalar of another shape is refused, state
// untouched.
TEST(LegendreFluid, PassiveScalarIsCarriedLikeTheDensity) {
  for (double alpha : {0.0, 0.3}) {
    FluidParams p;
    p.dissipation = alpha;
    LegendreFluid f(3, 5, box_of(3, 1.0), p);
    randomize(f, 7, 1.0);
    f.density.c[0] = 2.0;  // a positive mean
    f.project();
    f.passive.push_back(f.density);
    const std::vector<double> start = f.density.c;
    for (int s = 0; s < 20; ++s) {
      const StepReport r = f.step(0.02);
      ASSERT_TRUE(r.ok) << r.error;
    }
    double diff = 0, norm = 0, moved = 0;
    for (size_t i = 0; i < f.density.size(); ++i) {
      diff = std::max(diff, std::abs(f.density.c[i] - f.passive[0].c[i]));
      norm = std::max(norm, std::abs(f.passive[0].c[i]));
      moved = std::max(moved, std::abs(f.passive[0].c[i] - start[i]));
    }
    EXPECT_GT(moved, 1e-3 * norm);
    EXPECT_NEAR(f.passive[0].c[0], 2.0, 2e-8);  // P_0 coefficient = mean over the box
    if (alpha == 0.0) {
      EXPECT_LE(diff, 1e-12 * norm);
    } else {
      EXPECT_LT(f.density.c[0], 2.0 * 0.95);  // (1 + dt alpha)^-N ~ 0.89
    }
    f.passive.push_back(Field({3, 3, 3}, f.density.box, 3));
    const std::vector<double> before = f.passive[0].c;
    const StepReport bad = f.step(0.02);
    EXPECT_FALSE(bad.ok);
    EXPECT_NE(bad.error.find("passive"), std::string::npos);
    EXPECT_EQ(f.passive[0].c, before);
  }
}

}  // namespace
}  // namespace procam::legendre
