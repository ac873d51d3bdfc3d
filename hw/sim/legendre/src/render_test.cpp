// SPDX-License-Identifier: MIT
// L3 rendering against closed forms (homogeneous medium) and brute-force
// ray marching of the same non-homogeneous density.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <numbers>

#include "procam/legendre/render.hpp"
#include "test_util.hpp"

namespace procam::legendre {
namespace {

using testing::box2;

// Homogeneous r, light along +y, camera on the +x face:
// E^s(y) = beta Omega r E0 e^{-s r (y - y0)} (1 - e^{-s r Lx}) / (s r), T = e^{-s r Lx}.
TEST(LegendreRender, HomogeneousMediumMatchesClosedForm) {
  const Box b = box2(0, 2, 0, 1);
  Lighting l;
  l.light_axis = 1;
  l.view_axis = 0;
  l.sigma = 0.5;
  l.beta = 0.4;
  l.irradiance = 3.0;
  const double r = 0.3, om = 1.0 / (4 * std::numbers::pi);
  EXPECT_NEAR(l.phase(), om, 1e-15);
  Field d = zero_field(2, 4, b);
  d.c[0] = r;
  const Shape cells{200, 50, 1};
  const RenderResult lr = LegendreRenderer(2, 8, b, l).render(d, cells);
  const RenderResult gr = render_grid(std::vector<double>(200 * 50, r), 2, cells, b, l);
  ASSERT_TRUE(lr.ok) << lr.error;
  ASSERT_EQ(lr.airlight.size(), 50u);
  ASSERT_EQ(gr.airlight.size(), 50u);
  const double sr = l.sigma * r;
  for (size_t j = 0; j < 50; ++j) {
    const double y = (static_cast<double>(j) + 0.5) / 50.0;
    const double es = l.beta * om * r * 3.0 * std::exp(-sr * y) * (1 - std::exp(-sr * 2)) / sr;
    EXPECT_NEAR(lr.airlight[j], es, 1e-7 * es) << j;
    EXPECT_NEAR(gr.airlight[j], es, 1e-5 * es) << j;  // midpoint rule, h = 0.01
    EXPECT_NEAR(lr.transmittance[j], std::exp(-2 * sr), 1e-9);
    EXPECT_NEAR(gr.transmittance[j], std::exp(-2 * sr), 1e-12);
  }
}

// Brute force: march the Legendre density itself, evaluated pointwise, with
// M midpoint samples per axis (independent of the Legendre solver).
std::vector<double> march_2d(const Field& d, const Lighting& l, size_t m, size_t pixels) {
  const Box& b = d.box;
  const double hx = (b.hi[0] - b.lo[0]) / static_cast<double>(m), hy = (b.hi[1] - b.lo[1]) / static_cast<double>(m);
  std::vector<double> out(pixels, 0.0);
  for (size_t p = 0; p < pixels; ++p) {
    const double y = b.lo[1] + (static_cast<double>(p) + 0.5) * (b.hi[1] - b.lo[1]) / static_cast<double>(pixels);
    double es = 0, tau_v = 0;
    for (size_t i = m; i-- > 0;) {  // from the camera (hi x) inwards
      const double x = b.lo[0] + (static_cast<double>(i) + 0.5) * hx;
      const double r = evaluate(d, {x, y, 0});
      double tau_l = 0;  // light from the lo y face to y
      const size_t ml = static_cast<size_t>(std::ceil((y - b.lo[1]) / hy));
      const double hl = (y - b.lo[1]) / static_cast<double>(ml == 0 ? 1 : ml);
      for (size_t k = 0; k < ml; ++k) tau_l += l.sigma * evaluate(d, {x, b.lo[1] + (static_cast<double>(k) + 0.5) * hl, 0}) * hl;
      const double dt = l.sigma * r * hx;
      es += l.beta * l.phase() * r * l.irradiance * std::exp(-tau_l) * hx * std::exp(-(tau_v + 0.5 * dt));
      tau_v += dt;
    }
    out[p] = es;
  }
  return out;
}

TEST(LegendreRender, NonHomogeneousMatchesRayMarching) {
  const Box b = box2(-1, 1, -1, 1);
  Lighting l;
  l.light_axis = 1;
  l.view_axis = 0;
  l.sigma = 0.6;
  l.beta = 0.5;
  l.g = 0.3;
  const Field d = project([](double x, double y, double) { return 0.6 + 0.4 * std::sin(1.5 * x + 0.5) * std::cos(y); },
                          cube_shape(2, 6), b, 12);
  const size_t px = 16;
  const auto truth = march_2d(d, l, 400, px);
  double peak = 0;
  for (double v : truth) peak = std::max(peak, v);
  for (size_t nr : {6u, 10u}) {
    const RenderResult lr = LegendreRenderer(2, nr, b, l).render(d, Shape{px, px, 1});
    ASSERT_TRUE(lr.ok);
    double worst = 0;
    for (size_t p = 0; p < px; ++p) worst = std::max(worst, std::fabs(lr.airlight[p] - truth[p]));
    std::cout << "[ measured ] 2D n_render=" << nr << " max |airlight - march| / peak = " << worst / peak << "\n";
    // Stated tolerance: 1e-3 of the peak air-light with 6 intensity
    // polynomials per axis, 1e-5 with 10 (brute force itself ~1e-6).
    EXPECT_LT(worst, (nr == 6 ? 1e-3 : 1e-5) * peak) << "n_render=" << nr << " worst=" << worst;
  }
}

// 3D: Legendre vs the grid marcher on a fine grid of the same density, for
// light from above and the camera on the -z face (back-lit geometry).
TEST(LegendreRender, ThreeDimensionalMatchesFineGridMarch) {
  Box b;
  b.lo = {0, 0, 0};
  b.hi = {1, 2, 1};
  Lighting l;
  l.light_axis = 1;
  l.light_sign = -1;
  l.view_axis = 2;
  l.view_sign = -1;
  l.sigma = 0.8;
  const Field d = project([](double x, double y, double z) { return 0.5 + 0.3 * x * y - 0.2 * z * z + 0.1 * y; },
                          cube_shape(3, 4), b, 6);
  const Shape g{96, 192, 96};
  const RenderResult gr = render_grid(evaluate_grid(d, g), 3, g, b, l);
  const RenderResult lr = LegendreRenderer(3, 7, b, l).render(d, g);
  ASSERT_TRUE(lr.ok);
  ASSERT_EQ(lr.airlight.size(), gr.airlight.size());
  double peak = 0, worst = 0, worst_t = 0;
  for (size_t i = 0; i < gr.airlight.size(); ++i) {
    peak = std::max(peak, gr.airlight[i]);
    worst = std::max(worst, std::fabs(lr.airlight[i] - gr.airlight[i]));
    worst_t = std::max(worst_t, std::fabs(lr.transmittance[i] - gr.transmittance[i]));
  }
  std::cout << "[ measured ] 3D n_render=7 vs 96x192x96 march: airlight " << worst / peak << " of peak, transmittance "
            << worst_t << "\n";
  EXPECT_LT(worst, 1e-3 * peak);
  EXPECT_LT(worst_t, 1e-4);
}

TEST(LegendreRender, BadGeometryIsRefused) {
  Lighting l;
  l.view_axis = 2;
  EXPECT_THROW(LegendreRenderer(2, 6, Box{}, l), std::invalid_argument);
  l.view_axis = 0;
  l.light_sign = 0;
  EXPECT_THROW(LegendreRenderer(2, 6, Box{}, l), std::invalid_argument);
}

}  // namespace
}  // namespace procam::legendre
