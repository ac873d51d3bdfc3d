// SPDX-License-Identifier: MIT
// Source–camera placement (thesis §5.3): the components against closed forms
// where they exist, and the section's claims — the optimum of CQM·W lies
// strictly inside the separation range for a noisy sensor, the zero-noise
// curve is monotonic, and the optimum moves as sigma changes.
#include "placement.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace procam::polarized_striping {
namespace {

PlacementParams base() {
  PlacementParams p;
  p.steps = 21;
  return p;
}

// D (Eq. 5.11) in units of the clear-air signal: e^{-sigma (d_LO + d)} (d / d_LO)^3
// (inverse square and cos(phi) = d / d_LO).
TEST(Placement, DirectMatchesClosedFormAndNoMediumNoScatter) {
  PlacementParams p = base();
  const PlacementResult r = evaluate_placement(p);
  for (const PlacementSample& s : r.curve) {
    const double d = p.distance_mm, dlo = std::hypot(d, s.separation_mm);
    EXPECT_NEAR(s.d, std::exp(-p.sigma_per_mm * (dlo + d)) * std::pow(d / dlo, 3), 1e-9);
    EXPECT_GT(s.b, 0.0);
    EXPECT_GT(s.a, 0.0);
  }
  p.sigma_per_mm = p.beta_per_mm = 0;  // clear air: no backscatter, no indirect light, D = (d / d_LO)^3
  for (const PlacementSample& s : evaluate_placement(p).curve) {
    EXPECT_EQ(s.a, 0.0);
    EXPECT_EQ(s.b, 0.0);
    EXPECT_NEAR(s.cqm, 1.0, 1e-12);
  }
}

// Backscatter along the ray for a co-located source without attenuation,
// isotropic phase: B = ∫ beta / (4 pi t^2) dt from the near cut (10 mm) to d
// = beta / (4 pi) (1/10 - 1/d), in units of D_clear = R / (pi d^2).
TEST(Placement, BackscatterMatchesClosedFormForIsotropicClearPath) {
  PlacementParams p = base();
  p.sigma_per_mm = 1e-12;
  p.beta_per_mm = 1e-12;
  p.g = 0;
  p.min_separation_mm = 0;
  p.max_separation_mm = 100;
  p.steps = 3;
  p.quality = 4;
  const PlacementResult r = evaluate_placement(p);
  const double d = p.distance_mm, d_clear = p.albedo / M_PI / (d * d);
  const double expect = p.beta_per_mm / (4 * M_PI) * (1.0 / 10.0 - 1.0 / d) / d_clear;
  EXPECT_NEAR(r.curve[0].b, expect, 2e-3 * expect);
}

TEST(Placement, NoisySensorOptimumIsInsideTheRange) {
  const PlacementResult r = evaluate_placement(base());
  EXPECT_GT(r.best_flood_index, 0u);
  EXPECT_LT(r.best_flood_index, r.curve.size() - 1);
  EXPECT_GT(r.best_flood_mm, r.curve.front().separation_mm);
  EXPECT_LT(r.best_flood_mm, r.curve.back().separation_mm);
}

TEST(Placement, ZeroNoiseCurveIsMonotonic) {
  PlacementParams p = base();
  p.noise = 0;
  const PlacementResult r = evaluate_placement(p);
  for (size_t i = 1; i < r.curve.size(); ++i)
    EXPECT_GE(r.curve[i].cqm_w, r.curve[i - 1].cqm_w) << r.curve[i].separation_mm;
  EXPECT_EQ(r.best_flood_index, r.curve.size() - 1);
}

TEST(Placement, OptimumMovesWithSigma) {
  PlacementParams thin = base(), thick = base();
  thin.sigma_per_mm = 0.004;
  thin.beta_per_mm = 0.0032;
  thick.sigma_per_mm = 0.006;
  thick.beta_per_mm = 0.0048;
  const PlacementResult a = evaluate_placement(thin), b = evaluate_placement(thick);
  EXPECT_GT(std::abs(a.best_flood_mm - b.best_flood_mm), 40.0)
      << "thin " << a.best_flood_mm << " thick " << b.best_flood_mm;
}

TEST(Placement, CsvAndPng) {
  const PlacementResult r = evaluate_placement(base());
  const std::string csv = placement_csv(r);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 22);
  const auto png = placement_png(r, 64, 40);
  ASSERT_GT(png.size(), 64u * 40u * 3u);
  EXPECT_EQ(png[0], 0x89);
  EXPECT_EQ(png[1], 'P');
  EXPECT_EQ(std::string(png.end() - 8, png.end() - 4), "IEND");
  PlacementParams bad = base();
  bad.beta_per_mm = 1;
  EXPECT_FALSE(check(bad).empty());
  EXPECT_TRUE(check(base()).empty());
}

}  // namespace
}  // namespace procam::polarized_striping
