// SPDX-License-Identifier: MIT
// Focus measures against closed forms: a Gaussian E(f) sampled at integer
// focus indices has its peak at the Gaussian's centre (Eq. 2.9's
// interpolation is exact for it); hard cases give NaN, never inf.
#include "focus_measures.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iterator>
#include <limits>
#include <vector>

namespace procam::defocus {
namespace {

std::vector<float> gaussian(uint32_t F, double centre, double width, double height) {
  std::vector<float> e(F);
  for (uint32_t k = 0; k < F; ++k)
    e[k] = static_cast<float>(height * std::exp(-0.5 * (k - centre) * (k - centre) / (width * width)));
  return e;
}

TEST(FocusSweep, UniformInInverseDepth) {
  const auto f = focus_sweep_mm(600, 1200, 5);
  ASSERT_EQ(f.size(), 5u);
  EXPECT_DOUBLE_EQ(f.front(), 600);
  EXPECT_DOUBLE_EQ(f.back(), 1200);
  for (size_t k = 1; k < f.size(); ++k)
    EXPECT_NEAR(1 / f[k - 1] - 1 / f[k], (1 / 600.0 - 1 / 1200.0) / 4, 1e-12) << k;
  EXPECT_EQ(focus_sweep_mm(700, 0, 1), std::vector<double>{700});
  EXPECT_THROW(focus_sweep_mm(900, 600, 3), std::invalid_argument);
}

TEST(Fbar, GaussianPeakIsRecoveredExactly) {
  for (double centre : {1.0, 1.37, 2.5, 3.49, 3.9}) {
    for (double width : {0.6, 1.0, 2.0}) {
      const auto e = gaussian(6, centre, width, 40.0);
      EXPECT_NEAR(fbar_from_e3(e.data(), 6, 0.5f), centre, 2e-5) << centre << " " << width;
    }
  }
}

TEST(Fbar, NoPeakInsideTheSweepIsInvalidNotExtrapolated) {
  // Peak beyond either end: monotonic curves.
  const auto rising = gaussian(6, 6.3, 1.0, 40.0);
  const auto falling = gaussian(6, -0.8, 1.0, 40.0);
  EXPECT_TRUE(std::isnan(fbar_from_e3(rising.data(), 6, 0.f)));
  EXPECT_TRUE(std::isnan(fbar_from_e3(falling.data(), 6, 0.f)));
  // Fewer than 3 settings cannot hold an inner peak.
  EXPECT_TRUE(std::isnan(fbar_from_e3(rising.data(), 2, 0.f)));
}

TEST(Fbar, FlatZeroAndWeakProfilesAreInvalid) {
  const std::vector<float> flat(6, 10.f), zero(6, 0.f);
  EXPECT_TRUE(std::isnan(fbar_from_e3(flat.data(), 6, 0.f)));
  EXPECT_TRUE(std::isnan(fbar_from_e3(zero.data(), 6, 0.f)));
  const std::vector<float> zero_neighbour = {1, 0, 5, 0, 1, 1};  // log(0) must not be taken
  EXPECT_TRUE(std::isnan(fbar_from_e3(zero_neighbour.data(), 6, 0.f)));
  const auto weak = gaussian(6, 2.4, 1.0, 1.0);  // below the floor: noise would decide
  EXPECT_TRUE(std::isnan(fbar_from_e3(weak.data(), 6, 2.f)));
}

TEST(Fbar, NearTieBetweenTwoSettingsLandsHalfWay) {
  // Symmetric about 2.5: E(2) == E(3) exactly, and a hair apart either way.
  const auto tie = gaussian(6, 2.5, 1.0, 40.0);
  EXPECT_NEAR(fbar_from_e3(tie.data(), 6, 0.f), 2.5, 1e-5);
  auto a = tie;
  a[2] += 1e-4f;
  auto b = tie;
  b[3] += 1e-4f;
  const float fa = fbar_from_e3(a.data(), 6, 0.f), fb = fbar_from_e3(b.data(), 6, 0.f);
  ASSERT_TRUE(std::isfinite(fa));
  ASSERT_TRUE(std::isfinite(fb));
  EXPECT_NEAR(fa, 2.5, 1e-3);  // continuous across the tie: no jump of one index
  EXPECT_NEAR(fb, 2.5, 1e-3);
}

TEST(GaussianPeakOffset, StaysWithinHalfAStep) {
  EXPECT_NEAR(gaussian_peak_offset(1.f, 2.f, 1.f), 0.f, 1e-7);
  EXPECT_TRUE(std::isnan(gaussian_peak_offset(3.f, 2.f, 1.f)));  // centre is not the max
  EXPECT_TRUE(std::isnan(gaussian_peak_offset(1.f, 1.f, 1.f)));  // no curvature
  EXPECT_TRUE(std::isnan(gaussian_peak_offset(-1.f, 2.f, 1.f)));
}

// A 3 x 1 sweep of 3 settings built through the accumulator from pure
// harmonics, so the map functions see real accumulator state.
E3Accumulator make_acc(const std::vector<std::vector<double>>& e3_per_pixel, const std::vector<double>& means,
                       std::vector<bool> saturate = {}) {
  const uint32_t w = static_cast<uint32_t>(means.size());
  const uint32_t F = static_cast<uint32_t>(e3_per_pixel[0].size());
  E3Accumulator acc(w, 1, F, PROCAM_PIXEL_F32, 1e9, 1);  // values in DN-like units: full scale far above
  for (uint32_t f = 0; f < F; ++f)
    for (uint32_t t = 0; t < 24; ++t) {
      std::vector<float> frame(w);
      for (uint32_t x = 0; x < w; ++x) {
        frame[x] = static_cast<float>(means[x] + e3_per_pixel[x][f] * std::cos(2 * M_PI * 3 * t / 24.0));
        if (!saturate.empty() && saturate[x] && t == 5) frame[x] = std::numeric_limits<float>::infinity();
      }
      EXPECT_TRUE(acc.add(f, t, sdk::gray_view(frame.data(), w, 1)).ok());
    }
  return acc;
}

TEST(OmegaMap, RatioAndGuardedDenominator) {
  Validity rule;
  rule.black_dn = 5;
  rule.min_modulation = 0.02;
  // pixel 0: ratio 0.5; pixel 1: E(f1) = 0 (denominator -> 0); pixel 2: black; pixel 3: saturated.
  auto acc = make_acc({{40, 20}, {0, 30}, {2, 1}, {40, 20}}, {100, 100, 3, 100}, {false, false, false, true});
  std::vector<float> omega;
  EXPECT_EQ(omega_map(acc, 0, 1, rule, 1, omega), 1u);
  EXPECT_NEAR(omega[0], 0.5, 1e-4);
  for (size_t i = 1; i < 4; ++i) EXPECT_TRUE(std::isnan(omega[i])) << i;  // never inf
}

TEST(FbarMap, ValidOnlyWithAnInnerPeak) {
  Validity rule;
  auto acc = make_acc({{10, 30, 20}, {10, 20, 30}, {30, 30, 30}}, {100, 100, 100});
  std::vector<float> fbar;
  EXPECT_EQ(fbar_map(acc, rule, 2, fbar), 1u);
  const double lm = std::log(10.0), l0 = std::log(30.0), lp = std::log(20.0);
  EXPECT_NEAR(fbar[0], 1 + 0.5 * (lm - lp) / (lm - 2 * l0 + lp), 1e-4);
  EXPECT_TRUE(std::isnan(fbar[1]));  // rising to the last setting
  EXPECT_TRUE(std::isnan(fbar[2]));  // flat
}

// The fused, vectorised multi-focal kernel against the per-pixel reference
// (fbar_from_e3 + CalibrationTable::lookup) on random curves, ties, edges,
// flat and weak ones included.
TEST(FbarDepthMap, MatchesThePerPixelReference) {
  const uint32_t F = 6, w = 37;
  std::vector<std::vector<double>> e3(w, std::vector<double>(F));
  std::vector<double> means(w, 100.0);
  uint32_t seed = 12345;
  auto rnd = [&] { return double((seed = seed * 1103515245u + 12345u) >> 8) / double(1u << 24); };
  for (uint32_t x = 0; x < w; ++x)
    for (uint32_t f = 0; f < F; ++f) e3[x][f] = 40.0 * std::exp(-0.5 * std::pow((f - 5.5 * rnd()) / (0.5 + rnd()), 2));
  e3[0] = {10, 20, 20, 10, 5, 1};   // exact tie
  e3[1] = {30, 30, 30, 30, 30, 30};  // flat
  e3[2] = {1, 1.5, 1.9, 1.2, 1, 1};  // below min_modulation (2 % of 100)
  e3[3] = {0, 0, 5, 0, 0, 0};        // zero neighbours
  auto acc = make_acc(e3, means);
  sdk::CalibrationTable table;
  for (int k = 0; k <= 12; ++k) table.samples.emplace_back(0.4 + 0.35 * k + 0.05 * (k % 3), 600 + 37.0 * k * k);
  Validity rule;
  std::vector<float> fbar, depth;
  const size_t valid = fbar_depth_map(acc, rule, &table, 2, fbar, &depth);
  size_t expect_valid = 0;
  for (uint32_t x = 0; x < w; ++x) {
    float e[F];
    for (uint32_t f = 0; f < F; ++f) e[f] = acc.e3(f)[x];
    const float ref = fbar_from_e3(e, F, 0.02f * acc.mean()[x]);
    expect_valid += std::isnan(ref) ? 0u : 1u;
    if (std::isnan(ref)) {
      EXPECT_TRUE(std::isnan(fbar[x])) << x;
      EXPECT_TRUE(std::isnan(depth[x])) << x;
    } else {
      EXPECT_NEAR(fbar[x], ref, 2e-5) << x;
      const float d = table.lookup(double(fbar[x]));
      if (std::isnan(d)) EXPECT_TRUE(std::isnan(depth[x])) << x;
      else EXPECT_NEAR(depth[x], d, 1e-3) << x;
    }
  }
  EXPECT_EQ(valid, expect_valid);
  EXPECT_TRUE(std::isnan(fbar[1]));
  EXPECT_TRUE(std::isnan(fbar[2]));
  EXPECT_TRUE(std::isnan(fbar[3]));
  EXPECT_NEAR(fbar[0], 1.5, 1e-4);
}

// The `valid` map from the bits: every non-finite kind (NaN, +inf, -inf)
// is 0, every finite value (0, -0, denormals, FLT_MAX) 255, the count is
// std::isfinite's, and the second map (calibrate-*) vetoes too; on any
// number of row bands, including more threads than rows.
TEST(ValidWhereFinite, MatchesIsfiniteOnEveryKindOfFloat) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const float kinds[] = {0.f, -0.f, 1.f, -3.5f, std::numeric_limits<float>::denorm_min(),
                         std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                         nan, -nan, inf, -inf, std::numeric_limits<float>::signaling_NaN()};
  const uint32_t rows = 7, w = 13;
  std::vector<float> a(rows * w), b(rows * w);
  for (size_t i = 0; i < a.size(); ++i) {
    a[i] = kinds[i % std::size(kinds)];
    b[i] = kinds[(i * 5 + 3) % std::size(kinds)];
  }
  for (uint32_t threads : {1u, 2u, 3u, 16u}) {
    std::vector<uint8_t> valid(3, 42);  // wrong size and stale contents on entry
    size_t expect = 0;
    const size_t count = valid_where_finite(a, nullptr, rows, threads, valid);
    ASSERT_EQ(valid.size(), a.size());
    for (size_t i = 0; i < a.size(); ++i) {
      const bool ok = std::isfinite(a[i]);
      expect += ok;
      EXPECT_EQ(valid[i], ok ? 255 : 0) << i << " threads " << threads;
    }
    EXPECT_EQ(count, expect) << threads;
    expect = 0;
    const size_t both = valid_where_finite(a, &b, rows, threads, valid);
    for (size_t i = 0; i < a.size(); ++i) {
      const bool ok = std::isfinite(a[i]) && std::isfinite(b[i]);
      expect += ok;
      EXPECT_EQ(valid[i], ok ? 255 : 0) << i << " threads " << threads;
    }
    EXPECT_EQ(both, expect) << threads;
    EXPECT_LT(both, count);  // b vetoes some of a's finite pixels
  }
  std::vector<float> empty;
  std::vector<uint8_t> v(5, 1);
  EXPECT_EQ(valid_where_finite(empty, nullptr, 0, 2, v), 0u);
  EXPECT_TRUE(v.empty());
}

TEST(ModulationMap, AmplitudeOverMean) {
  Validity rule;
  auto acc = make_acc({{25}, {0.5}}, {100, 100});
  std::vector<float> m;
  EXPECT_EQ(modulation_map(acc, 0, rule, 1, m), 1u);
  EXPECT_NEAR(m[0], 0.25, 1e-5);
  EXPECT_TRUE(std::isnan(m[1]));  // 0.5 % modulation: below min_modulation
}

}  // namespace
}  // namespace procam::defocus
