// SPDX-License-Identifier: MIT
// Tests of the pattern generators (procam/sdk/patterns.hpp) against truth
// built independently here: stripe edges found by walking the pattern,
// sinusoid values at points where cos is known exactly, checkerboards
// compared with a reference that flips colour at every square border, and
// geometric exposure series by their ratios.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "procam/sdk/patterns.hpp"

namespace sdk = procam::sdk;

namespace {

uint32_t frame(sdk::Plan& plan, uint32_t w, uint32_t h, procam_pixel_type t = PROCAM_PIXEL_U8) {
  return plan.add_frame("p", w, h, t);
}

// Reference stripes: walk t = 0..n-1 from a known state. Truth: the pattern
// turns white at t = shift (mod period) and black half a period (rounded up)
// later. Built by toggling, not by the modulo formula under test.
std::vector<uint8_t> reference_stripes(uint32_t n, uint32_t period, int64_t shift) {
  const uint32_t on = (period + 1) / 2;  // white pixels per period
  // Phase of t = 0: how far 0 lies after the last rising edge.
  int64_t phase = -shift;
  while (phase < 0) phase += period;
  while (phase >= int64_t{period}) phase -= period;
  std::vector<uint8_t> v(n);
  for (uint32_t t = 0; t < n; ++t) {
    v[t] = phase < int64_t{on} ? 255 : 0;
    if (++phase == int64_t{period}) phase = 0;
  }
  return v;
}

TEST(SdkPatterns, VerticalStripesMatchAWalkedReference) {
  for (uint32_t period : {2u, 5u, 24u})
    for (int64_t shift : {int64_t{0}, int64_t{1}, int64_t{7}, int64_t{-3}, int64_t{53}}) {
      sdk::Plan plan;
      const uint32_t i = frame(plan, 61, 3);
      sdk::binary_stripes(plan, i, sdk::StripeAxis::vertical, period, shift);
      const std::vector<uint8_t> ref = reference_stripes(61, period, shift);
      auto px = plan.pattern_u8(i);
      for (uint32_t y = 0; y < 3; ++y)
        for (uint32_t x = 0; x < 61; ++x)
          ASSERT_EQ(px[y * 61 + x], ref[x]) << "P=" << period << " s=" << shift << " x=" << x;
    }
}

// Pre-filtered stripes (thesis §2.4 fn. 5): sigma 0 is binary_stripes; the
// blur keeps each period's mean; the k-th harmonic of one period is the
// continuous square wave's, |c_k| = |sin(pi k W / P)| / (pi k) with W the
// white width, scaled by the Gaussian's transfer exp(-2 pi^2 sigma^2 k^2 / P^2)
// (aliases from k +- P are below 1e-10 at sigma 1).
TEST(SdkPatterns, SmoothedStripesAreGaussianFilteredSquareWaves) {
  for (int64_t shift : {int64_t{0}, int64_t{5}, int64_t{-7}}) {
    sdk::Plan plan;
    const uint32_t a = frame(plan, 48, 2), b = frame(plan, 48, 2);
    sdk::binary_stripes(plan, a, sdk::StripeAxis::vertical, 24, shift);
    sdk::smoothed_stripes(plan, b, sdk::StripeAxis::vertical, 24, shift, 0.0);
    for (uint32_t x = 0; x < 96; ++x) ASSERT_EQ(plan.pattern_u8(a)[x], plan.pattern_u8(b)[x]) << x;
  }
  for (double sigma : {1.0, 2.0}) {
    sdk::Plan plan;
    const uint32_t i = frame(plan, 24, 1, PROCAM_PIXEL_F32);
    sdk::smoothed_stripes(plan, i, sdk::StripeAxis::vertical, 24, 3, sigma);
    auto px = plan.pattern_f32(i);
    double mean = 0, re = 0, im = 0;
    for (uint32_t x = 0; x < 24; ++x) {
      const double v = double(px[x]);
      mean += v / 24.0;
      re += v * std::cos(2 * std::numbers::pi * 3 * x / 24.0) / 24.0;
      im += v * std::sin(2 * std::numbers::pi * 3 * x / 24.0) / 24.0;
    }
    EXPECT_NEAR(mean, 0.5, 1e-6) << sigma;
    const double c3 = 1.0 / (3 * std::numbers::pi) *
                      std::exp(-2 * std::numbers::pi * std::numbers::pi * sigma * sigma * 9 / 576.0);
    EXPECT_NEAR(std::hypot(re, im), c3, 2e-6) << sigma;
    size_t grey = 0;  // ramps, not hard edges: both edges of the period have grey pixels
    for (float v : px) grey += (v > 0.01f && v < 0.99f) ? 1u : 0u;
    EXPECT_GE(grey, 4u) << sigma;
  }
  sdk::Plan plan;
  const uint32_t i = frame(plan, 8, 1);
  EXPECT_THROW(sdk::smoothed_stripes(plan, i, sdk::StripeAxis::vertical, 24, 0, -1.0), std::invalid_argument);
  EXPECT_THROW(sdk::smoothed_stripes(plan, i, sdk::StripeAxis::vertical, 1, 0, 1.0), std::invalid_argument);
}

TEST(SdkPatterns, HorizontalStripesVaryWithYOnly) {
  sdk::Plan plan;
  const uint32_t i = frame(plan, 4, 30, PROCAM_PIXEL_F32);
  sdk::binary_stripes(plan, i, sdk::StripeAxis::horizontal, 6, 2);
  const std::vector<uint8_t> ref = reference_stripes(30, 6, 2);
  auto px = plan.pattern_f32(i);
  for (uint32_t y = 0; y < 30; ++y)
    for (uint32_t x = 0; x < 4; ++x) ASSERT_EQ(px[y * 4 + x], ref[y] ? 1.0f : 0.0f) << y;
}

TEST(SdkPatterns, ShiftedSeriesOfThesisSection22) {
  // Period 24 shifted one pixel at a time, 24 frames: every pixel is white in
  // exactly 12 frames, and frame k at x equals frame 0 at x - k.
  sdk::Plan plan;
  const uint32_t first =
      sdk::add_shifted_stripes(plan, "stripes", 100, 2, sdk::StripeAxis::vertical, 24, 24, 1);
  ASSERT_EQ(first, 0u);
  ASSERT_EQ(plan.size(), 24u);
  EXPECT_EQ(plan.label(5), "stripes shift 5");
  for (uint32_t x = 0; x < 100; ++x) {
    int white = 0;
    for (uint32_t k = 0; k < 24; ++k) white += plan.pattern_u8(k)[x] == 255 ? 1 : 0;
    ASSERT_EQ(white, 12) << x;
  }
  for (uint32_t k = 0; k < 24; ++k)
    for (uint32_t x = k; x < 100; ++x) ASSERT_EQ(plan.pattern_u8(k)[x], plan.pattern_u8(0)[x - k]);
}

TEST(SdkPatterns, SinusoidHitsKnownValues) {
  // Period 8, phase pi/2 (maximum at t = 2): cos is exactly 1, 0, -1, 0 at
  // t = 2, 4, 6, 8 (mod 8). Amplitude 0.4 around 0.5.
  sdk::Plan plan;
  const uint32_t f = frame(plan, 16, 1, PROCAM_PIXEL_F32);
  sdk::sinusoid(plan, f, sdk::StripeAxis::vertical, 8.0, std::numbers::pi / 2, 0.4, 0.5);
  auto v = plan.pattern_f32(f);
  const float tol = 1e-6f;
  for (uint32_t base : {0u, 8u}) {
    EXPECT_NEAR(v[base + 2], 0.9f, tol);
    EXPECT_NEAR(v[base + 4], 0.5f, tol);
    EXPECT_NEAR(v[base + 6], 0.1f, tol);
    EXPECT_NEAR(v[base + 0], 0.5f, tol);
    EXPECT_NEAR(v[base + 3], 0.5f + 0.4f * std::sqrt(0.5f), tol);  // 45 degrees past the peak
  }
  // U8: round(255 * value), so within half a digital number of the exact value.
  const uint32_t u = frame(plan, 16, 1);
  sdk::sinusoid(plan, u, sdk::StripeAxis::vertical, 8.0, std::numbers::pi / 2, 0.4, 0.5);
  for (uint32_t x = 0; x < 16; ++x)
    EXPECT_NEAR(plan.pattern_u8(u)[x], 255.0 * static_cast<double>(v[x]), 0.5 + 1e-3) << x;
  // Full swing 0..1 reaches both ends exactly in U16.
  const uint32_t w = frame(plan, 4, 1, PROCAM_PIXEL_U16);
  sdk::sinusoid(plan, w, sdk::StripeAxis::vertical, 4.0, 0.0);
  EXPECT_EQ(plan.pattern_u16(w)[0], 65535);
  EXPECT_EQ(plan.pattern_u16(w)[2], 0);
}

TEST(SdkPatterns, SinusoidRejectsOutOfRangeLevels) {
  sdk::Plan plan;
  const uint32_t f = frame(plan, 4, 1);
  EXPECT_THROW(sdk::sinusoid(plan, f, sdk::StripeAxis::vertical, 8.0, 0.0, 0.6, 0.5), std::invalid_argument);
  EXPECT_THROW(sdk::sinusoid(plan, f, sdk::StripeAxis::vertical, 0.0, 0.0), std::invalid_argument);
  EXPECT_THROW(sdk::sinusoid(plan, f, sdk::StripeAxis::vertical, 8.0, 0.0, -0.1, 0.5), std::invalid_argument);
  EXPECT_THROW(sdk::binary_stripes(plan, f, sdk::StripeAxis::vertical, 1), std::invalid_argument);
  EXPECT_THROW(sdk::checkerboard(plan, f, 0), std::invalid_argument);
  EXPECT_THROW(sdk::binary_stripes(plan, 7, sdk::StripeAxis::vertical, 4), std::out_of_range);
}

// Reference checkerboard: colour flips at every square border along x and y,
// starting white at the corner (sx, sy); walked outward from there.
bool reference_checker(int64_t x, int64_t y, int64_t s, int64_t sx, int64_t sy) {
  int64_t flips = 0;
  for (int64_t t = sx; t < x; ++t) flips += ((t + 1 - sx) % s == 0) ? 1 : 0;  // borders crossed going right
  for (int64_t t = x; t < sx; ++t) flips += ((t + 1 - sx) % s == 0) ? 1 : 0;  // ... going left
  for (int64_t t = sy; t < y; ++t) flips += ((t + 1 - sy) % s == 0) ? 1 : 0;
  for (int64_t t = y; t < sy; ++t) flips += ((t + 1 - sy) % s == 0) ? 1 : 0;
  return flips % 2 == 0;
}

TEST(SdkPatterns, CheckerboardMatchesAWalkedReference) {
  for (int64_t shift : {int64_t{0}, int64_t{3}, int64_t{12}})
    for (uint32_t square : {1u, 3u, 8u}) {
      sdk::Plan plan;
      const uint32_t i = frame(plan, 40, 33);
      sdk::checkerboard(plan, i, square, shift, shift);
      for (uint32_t y = 0; y < 33; ++y)
        for (uint32_t x = 0; x < 40; ++x)
          ASSERT_EQ(plan.pattern_u8(i)[y * 40 + x] == 255, reference_checker(x, y, square, shift, shift))
              << "s=" << square << " shift=" << shift << " at " << x << "," << y;
    }
}

TEST(SdkPatterns, ShiftedCheckerboardsOfThesisSection25) {
  // 8x8 checkers shifted 5x5 times by 3 px: 25 frames; every pixel is lit in
  // some frame and dark in another (what max/min separation needs), and on
  // average lit close to half the time.
  sdk::Plan plan;
  sdk::add_shifted_checkerboards(plan, "checker", 64, 48, 8, 5, 3);
  ASSERT_EQ(plan.size(), 25u);
  EXPECT_EQ(plan.label(7), "checker shift 2,1");
  size_t lit_total = 0;
  for (uint32_t p = 0; p < 64 * 48; ++p) {
    int lit = 0;
    for (uint32_t k = 0; k < 25; ++k) lit += plan.pattern_u8(k)[p] == 255 ? 1 : 0;
    ASSERT_GT(lit, 0) << p;
    ASSERT_LT(lit, 25) << p;
    lit_total += static_cast<size_t>(lit);
  }
  EXPECT_NEAR(static_cast<double>(lit_total) / (64.0 * 48.0 * 25.0), 0.5, 0.05);
  // Frame (kx, ky) = (2, 1) is the base pattern moved by (6, 3).
  for (uint32_t y = 3; y < 48; ++y)
    for (uint32_t x = 6; x < 64; ++x)
      ASSERT_EQ(plan.pattern_u8(7)[y * 64 + x], plan.pattern_u8(0)[(y - 3) * 64 + (x - 6)]);
}

TEST(SdkPatterns, ExposureBracketIsGeometric) {
  const std::vector<double> e = sdk::exposure_bracket(100.0, 6400.0, 7);
  ASSERT_EQ(e.size(), 7u);
  const double truth[] = {100, 200, 400, 800, 1600, 3200, 6400};  // ratio (64)^(1/6) = 2
  for (size_t k = 0; k < 7; ++k) EXPECT_NEAR(e[k], truth[k], 1e-9 * truth[k]) << k;
  EXPECT_EQ(e.front(), 100.0);
  EXPECT_EQ(e.back(), 6400.0);
  EXPECT_EQ(sdk::exposure_bracket(500.0, 900.0, 1), std::vector<double>{500.0});
  EXPECT_EQ(sdk::exposure_bracket(500.0, 500.0, 3), std::vector<double>(3, 500.0));
  EXPECT_THROW(sdk::exposure_bracket(0.0, 10.0, 2), std::invalid_argument);
  EXPECT_THROW(sdk::exposure_bracket(10.0, 5.0, 2), std::invalid_argument);
  EXPECT_THROW(sdk::exposure_bracket(10.0, 20.0, 0), std::invalid_argument);
}

}  // namespace
