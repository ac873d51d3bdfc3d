// SPDX-License-Identifier: MIT
// The separation equations against closed forms: frames are synthesised from
// the model of separation.hpp (projector black level b, ambient A, direct
// L_d through a blurred pattern β, global ½ L_g), so the expected components
// are the L_d, L_g put in, not values the code produced.
#include "separation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

namespace procam::separation {
namespace {

// One pixel under pattern value beta (blurred, in [0, 1]); global light sees
// the pattern's mean (½ on, ½ off).
double pixel(double ld, double lg, double a, double b, double beta) {
  return a + ld * (b + (1 - b) * beta) + lg * (b + (1 - b) * 0.5);
}

// An Extrema of w x 1 pixels fed F32 frames given per pixel by fn(x, t).
template <class Fn>
Extrema series(uint32_t w, int frames, Fn&& fn) {
  Extrema ex(w, 1);
  std::vector<float> row(w);
  for (int t = 0; t < frames; ++t) {
    for (uint32_t x = 0; x < w; ++x) row[x] = static_cast<float>(fn(x, t));
    EXPECT_TRUE(ex.add(sdk::gray_view(row.data(), w, 1), 1).ok());
  }
  return ex;
}

Settings float_settings(double b) {
  Settings s;
  s.black_level = b;
  s.full_scale = 1.0;
  s.integer_frames = false;
  s.dark_fraction = 0.01;
  return s;
}

TEST(GaussianExtremum, ExactForSampledGaussianAndInverseGaussian) {
  // Gaussian interpolation is exact for a Gaussian: peak 0.8 at index 2.3.
  std::vector<float> g(6), inv(6);
  for (size_t k = 0; k < 6; ++k) {
    g[k] = static_cast<float>(0.8 * std::exp(-(double(k) - 2.3) * (double(k) - 2.3) / (2 * 1.5 * 1.5)));
    inv[k] = static_cast<float>(0.2 / std::exp(-(double(k) - 3.6) * (double(k) - 3.6) / (2 * 2.0 * 2.0)));
  }
  const Extremum hi = gaussian_extremum(g.data(), 6, true, 0.0);
  ASSERT_TRUE(hi.valid);
  EXPECT_NEAR(hi.value, 0.8, 1e-6);
  EXPECT_NEAR(hi.index, 2.3, 1e-5);
  const Extremum lo = gaussian_extremum(inv.data(), 6, false, 0.0);
  ASSERT_TRUE(lo.valid);
  EXPECT_NEAR(lo.value, 0.2, 1e-6);
  EXPECT_NEAR(lo.index, 3.6, 1e-5);
}

TEST(GaussianExtremum, NearTiesFlatAndNonPositiveSamplesStayFinite) {
  const std::vector<float> tie = {0.1f, 0.5f, 0.5f, 0.1f};
  const Extremum t = gaussian_extremum(tie.data(), 4, true, 0.0);
  ASSERT_TRUE(t.valid);
  EXPECT_NEAR(t.index, 1.5, 1e-9) << "two equal maxima: the vertex lies half-way";
  EXPECT_GT(t.value, 0.5);
  EXPECT_LT(t.value, 0.5 * std::exp(std::log(5.0) / 8) + 1e-6) << "overshoot bounded by (drop in ln)/8";
  const std::vector<float> flat = {0.4f, 0.4f, 0.4f, 0.4f};
  const Extremum f = gaussian_extremum(flat.data(), 4, true, 0.0);
  ASSERT_TRUE(f.valid) << "a flat curve is a tie with the ends, inside the sweep";
  EXPECT_EQ(f.value, 0.4f);
  const std::vector<float> zero_min = {0.3f, 0.0f, -0.001f, 0.2f};
  const Extremum z = gaussian_extremum(zero_min.data(), 4, false, 0.0);
  ASSERT_TRUE(z.valid);
  EXPECT_EQ(z.value, -0.001f) << "ln undefined: the sample itself, no refinement";
}

TEST(GaussianExtremum, NoExtremumInsideTheSweepIsInvalidNeverExtrapolated) {
  const std::vector<float> rising = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f};
  EXPECT_FALSE(gaussian_extremum(rising.data(), 5, true, 0.01).valid);
  EXPECT_FALSE(gaussian_extremum(rising.data(), 5, false, 0.01).valid);
  // Within the tie allowance the end counts as flat: the interior sample is used.
  const std::vector<float> almost = {0.5f, 0.499f, 0.3f, 0.2f};
  const Extremum a = gaussian_extremum(almost.data(), 4, true, 0.005);
  ASSERT_TRUE(a.valid);
  // The parabola's vertex may lie between the end and its neighbour: the
  // value is bounded by the Gaussian-interpolation overshoot (drop in ln)/8.
  EXPECT_LE(a.value, 0.5 * std::exp(std::log(0.5 / 0.3) / 8) + 1e-6);
  EXPECT_GE(a.index, 0.5);
  const std::vector<float> nan = {0.1f, std::nanf(""), 0.3f};
  EXPECT_FALSE(gaussian_extremum(nan.data(), 3, true, 0.0).valid);
  EXPECT_FALSE(gaussian_extremum(rising.data(), 2, true, 0.0).valid) << "fewer than 3 settings";
}

TEST(FromContrast, Eq217And218AndTheZeroDenominator) {
  // L_d = 100, L_g = 30, contrast 0.6: e+ - e- = 60, white = 130.
  const Components c = from_contrast(0.8 * 100 + 15, 0.2 * 100 + 15, 130, 0.6, 0.1);
  EXPECT_NEAR(c.direct, 100, 1e-4);
  EXPECT_NEAR(c.global, 30, 1e-4);
  EXPECT_FALSE(from_contrast(95, 35, 130, 0.0, 0.1).valid()) << "denominator 0";
  EXPECT_FALSE(from_contrast(95, 35, 130, 0.05, 0.1).valid()) << "below min_contrast";
  EXPECT_FALSE(from_contrast(95, 35, 130, std::nan(""), 0.1).valid()) << "depth outside the table";
  EXPECT_NEAR(plane_contrast(95, 35, 100), 0.6, 1e-12);
  EXPECT_TRUE(std::isnan(plane_contrast(95, 35, 0)));
}

// S1 in focus recovers L_d and L_g exactly, with a black frame removing the
// black level and ambient; out of focus it reports (β⁺ − β⁻) L_d as direct
// and L_g + 2 β⁻ L_d as global (thesis Fig. 2.16: direct under-, global over-estimated).
TEST(SeparateChecker, InFocusExactAndDefocusedBiasedAsTheModelSays) {
  const double ld = 0.5, lg = 0.2, a = 0.03, b = 0.01;
  const double beta_hi = 0.8, beta_lo = 0.25;
  // pixel 0 in focus (beta 1 / 0), pixel 1 defocused, over 4 "shifts".
  const Extrema checker = series(2, 4, [&](uint32_t x, int t) {
    const double hi = x == 0 ? 1.0 : beta_hi, lo = x == 0 ? 0.0 : beta_lo;
    return pixel(ld, lg, a, b, t % 2 == 0 ? hi : lo);
  });
  const Extrema black = series(2, 1, [&](uint32_t, int) { return a + b * (ld + lg); });
  Maps m;
  separate_checker(checker, &black, float_settings(b), m);
  EXPECT_NEAR(m.direct[0], ld, 1e-6);
  EXPECT_NEAR(m.global[0], lg, 1e-6);
  EXPECT_NEAR(m.direct[1], (beta_hi - beta_lo) * ld, 1e-6);
  EXPECT_NEAR(m.global[1], lg + 2 * beta_lo * ld, 1e-6);
  EXPECT_EQ(m.valid, 2u);
  // Without the black frame: Nayar et al.'s black-level correction; ambient stays in global.
  separate_checker(checker, nullptr, float_settings(b), m);
  EXPECT_NEAR(m.direct[0], ld, 1e-6);
  EXPECT_NEAR(m.global[0], lg + 2 * a / (1 + b), 1e-6);
}

TEST(SeparateChecker, SaturatedAndBlackPixelsAreInvalidAtEveryBitDepth) {
  for (uint32_t bits : {8u, 12u, 16u}) {
    const uint32_t top = (1u << bits) - 1;
    // pixel 0: fine; 1: saturated in one frame; 2: black; 3: dim but above the dark limit.
    std::vector<std::vector<uint16_t>> frames = {{uint16_t(top / 2), uint16_t(top), 0, uint16_t(top / 50)},
                                                 {uint16_t(top / 10), uint16_t(top / 3), 0, uint16_t(top / 200)}};
    Extrema ex(4, 1);
    std::vector<uint8_t> u8(4);
    for (auto& f : frames) {
      if (bits == 8) {
        for (size_t i = 0; i < 4; ++i) u8[i] = uint8_t(f[i]);
        ASSERT_TRUE(ex.add(sdk::gray_view(u8.data(), 4, 1), 1).ok());
      } else {
        ASSERT_TRUE(ex.add(sdk::gray_view(f.data(), 4, 1, bits), 1).ok());
      }
    }
    Settings s;
    s.black_level = 0;
    s.full_scale = top;
    Maps m;
    separate_checker(ex, nullptr, s, m);
    EXPECT_NEAR(m.direct[0], double(top / 2) - double(top / 10), 1e-3) << bits;
    EXPECT_NEAR(m.global[0], 2.0 * double(top / 10), 1e-3) << bits;
    EXPECT_TRUE(std::isnan(m.direct[1]) && std::isnan(m.global[1])) << "saturated, " << bits << " bits";
    EXPECT_TRUE(std::isnan(m.direct[2]) && std::isnan(m.global[2])) << "black, " << bits << " bits";
    EXPECT_TRUE(std::isfinite(m.direct[3])) << bits;
    EXPECT_EQ(m.valid, 2u);
  }
}

// S2: e⁺(f) = β⁺(f) L_d + ½ L_g with β⁺ − ½ a Gaussian of σ = 1.5 settings
// in the setting index (and β⁻ = 1 − β⁺) whose peak reaches 1 between
// settings: the interpolated extrema give L_d, L_g within 1.5 % of L_d (the
// Gaussian fit to a curve that is not quite Gaussian), where the best single
// setting (S1) is off by up to 8 %.
TEST(SeparateMultiFocal, RecoversComponentsBetweenSettingsAndRejectsPeaksOutside) {
  const double ld = 0.4, lg = 0.3;
  const int nf = 6;
  const double centres[3] = {2.4, 3.0, 5.6};  // pixel 2 peaks outside the sweep (last index 5)
  std::vector<Extrema> per_focus;
  for (int f = 0; f < nf; ++f)
    per_focus.push_back(series(3, 2, [&](uint32_t x, int t) {
      const double hi = 0.5 + 0.5 * std::exp(-(f - centres[x]) * (f - centres[x]) / (2 * 1.5 * 1.5));
      return (t == 0 ? hi : 1 - hi) * ld + 0.5 * lg;  // no black level, no ambient
    }));
  Settings s = float_settings(0);
  s.tie_fraction = 0.001;
  Maps m;
  separate_multi_focal(per_focus, nullptr, s, m);
  // β⁺ − ½ is Gaussian but β⁺ itself is not: allow the interpolation's error
  // for this shape (< 1.5 % of L_d), far below S1's error at the best single setting.
  for (size_t x = 0; x < 2; ++x) {
    EXPECT_NEAR(m.direct[x], ld, 0.015 * ld) << x;
    EXPECT_NEAR(m.global[x], lg, 0.015 * ld) << x;
    EXPECT_NEAR(m.best_focus[x], centres[x], 0.05) << x;
  }
  EXPECT_TRUE(std::isnan(m.direct[2])) << "peak beyond the last setting: invalid, not extrapolated";
  EXPECT_EQ(m.valid, 2u);
}

TEST(SeparateOneFocal, DividesByTheTablesContrastAtEachDepth) {
  sdk::CalibrationTable table;
  table.samples = {{800.0, 0.9}, {1000.0, 0.5}};  // contrast falls linearly with depth
  const double ld = 0.5, lg = 0.2, a = 0.02, b = 0.01;
  const std::vector<float> depth = {800.f, 900.f, 1100.f};
  const auto contrast = [&](uint32_t x) { return x == 0 ? 0.9 : 0.7; };
  const Extrema checker = series(3, 2, [&](uint32_t x, int t) {
    const double c = contrast(x);
    return pixel(ld, lg, a, b, t == 0 ? 0.5 + c / 2 : 0.5 - c / 2);
  });
  const Extrema white = series(3, 1, [&](uint32_t, int) { return a + ld + lg; });
  const Extrema black = series(3, 1, [&](uint32_t, int) { return a + b * (ld + lg); });
  Maps m;
  Settings s = float_settings(b);
  s.min_contrast = 0.1;
  separate_one_focal(checker, white, &black, depth, table, s, m);
  for (size_t x = 0; x < 2; ++x) {
    EXPECT_NEAR(m.direct[x], ld, 1e-5) << x;
    EXPECT_NEAR(m.global[x], lg, 1e-5) << x;
  }
  EXPECT_TRUE(std::isnan(m.direct[2])) << "depth outside the table";
  // Calibration inverts it: the plane's samples are the contrasts put in.
  std::vector<float> zs, cs;
  const Extrema plane = series(3, 2, [&](uint32_t x, int t) {
    const double c = contrast(x);
    return pixel(ld, 0, a, b, t == 0 ? 0.5 + c / 2 : 0.5 - c / 2);
  });
  const Extrema plane_white = series(3, 1, [&](uint32_t, int) { return a + ld; });
  const Extrema plane_black = series(3, 1, [&](uint32_t, int) { return a + b * ld; });
  plane_contrast_samples(plane, plane_white, &plane_black, depth, s, 1, zs, cs);
  EXPECT_NEAR(cs[0], 0.9, 1e-5);
  EXPECT_NEAR(cs[1], 0.7, 1e-5);
  EXPECT_EQ(zs[2], 1100.f);
}

TEST(BoxMeanFinite, AveragesFiniteNeighboursAndKeepsNaN) {
  const float nan = std::nanf("");
  // 4x1 row: box of 3 centred (1 left, 1 right).
  std::vector<float> v = {1.f, 2.f, nan, 6.f};
  box_mean_finite(v, 4, 1, 3);
  EXPECT_FLOAT_EQ(v[0], 1.5f);  // (1 + 2) / 2, clipped at the border
  EXPECT_FLOAT_EQ(v[1], 1.5f);  // (1 + 2) / 2, NaN neighbour skipped
  EXPECT_TRUE(std::isnan(v[2]));
  EXPECT_FLOAT_EQ(v[3], 6.f);
  // A ripple of period 4 averages to its mean over a window of 4.
  std::vector<float> r(16 * 4);
  for (size_t i = 0; i < r.size(); ++i) r[i] = 0.5f + ((i % 16) % 4 < 2 ? 0.1f : -0.1f);
  box_mean_finite(r, 16, 4, 4);
  for (uint32_t x = 2; x < 14; ++x) EXPECT_NEAR(r[16 + x], 0.5f, 1e-6) << x;
}

TEST(CheckerRow, DispatchedKernelMatchesScalarBitForBit) {
  std::mt19937 rng(11);
  for (uint32_t n : {1u, 7u, 8u, 9u, 1921u}) {
    std::vector<uint8_t> mx(n), mn(n), bk(n);
    for (uint32_t i = 0; i < n; ++i) {
      const auto a = uint8_t(rng()), b = uint8_t(rng());
      mx[i] = std::max(a, b);
      mn[i] = std::min(a, b);
      bk[i] = uint8_t(mn[i] / (1 + rng() % 4));
      if (i % 13 == 0) mx[i] = 255;  // saturated
    }
    Settings s;
    const CheckerRowConstants k = checker_constants(s);
    std::vector<float> d1(n), g1(n), d2(n), g2(n);
    const size_t v1 = checker_row<uint8_t>(k, mx.data(), mn.data(), bk.data(), d1.data(), g1.data(), n);
    const size_t v2 = checker_row_scalar(k, mx.data(), mn.data(), bk.data(), d2.data(), g2.data(), n);
    EXPECT_EQ(v1, v2) << n;
    EXPECT_EQ(0, std::memcmp(d1.data(), d2.data(), n * sizeof(float))) << n;
    EXPECT_EQ(0, std::memcmp(g1.data(), g2.data(), n * sizeof(float))) << n;
  }
}

}  // namespace
}  // namespace procam::separation
