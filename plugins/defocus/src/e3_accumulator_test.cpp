// SPDX-License-Identifier: MIT
// E3Accumulator against closed forms: a profile a + b cos(2π·3t/24 - φ) plus
// other harmonics has E3 = b exactly (DFT orthogonality); a binary square
// wave of height H sampled at 24 shifts has E3 = H / (12 sin(π/8)).
#include "e3_accumulator.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace procam::defocus {
namespace {

constexpr double kPi = std::numbers::pi;

// A frame of w x h whose pixel i at shift t has value profile(i, t).
template <class T, class Fn>
std::vector<T> make_frame(uint32_t w, uint32_t h, uint32_t t, Fn&& profile) {
  std::vector<T> v(size_t{w} * h);
  for (size_t i = 0; i < v.size(); ++i) {
    const double x = profile(i, t);
    if constexpr (std::is_floating_point_v<T>) v[i] = static_cast<T>(x);
    else v[i] = static_cast<T>(std::lround(x));
  }
  return v;
}

procam_image view_of(const std::vector<uint8_t>& v, uint32_t w, uint32_t h) { return sdk::gray_view(v.data(), w, h, 8); }
procam_image view_of(const std::vector<uint16_t>& v, uint32_t w, uint32_t h) { return sdk::gray_view(v.data(), w, h, 12); }
procam_image view_of(const std::vector<float>& v, uint32_t w, uint32_t h) { return sdk::gray_view(v.data(), w, h); }

// Pixel i: mean 100 s, 3rd-harmonic amplitude b_i = s (5 + i), a 1st and a
// 5th harmonic that must not leak into E3; s scales to the frame's range.
template <class T>
void check_pure_harmonic(uint32_t pixel_type, double s, double full_scale, double tol) {
  const uint32_t w = 7, h = 3;
  auto profile = [&](size_t i, uint32_t t) {
    const double b = s * (5.0 + double(i));
    return s * 100.0 + b * std::cos(2 * kPi * 3 * t / 24.0 - 0.3 * double(i)) +
           s * 20.0 * std::cos(2 * kPi * t / 24.0 + 1.0) + s * 7.0 * std::cos(2 * kPi * 5 * t / 24.0);
  };
  E3Accumulator acc(w, h, 2, pixel_type, full_scale, 2);
  for (uint32_t f = 0; f < 2; ++f)
    for (uint32_t t = 0; t < 24; ++t) {
      const uint32_t tt = f == 0 ? t : 23 - t;  // setting 1 in reverse order: order must not matter
      auto frame = make_frame<T>(w, h, tt, profile);
      ASSERT_TRUE(acc.add(f, tt, view_of(frame, w, h)).ok());
    }
  ASSERT_TRUE(acc.complete());
  for (size_t i = 0; i < size_t{w} * h; ++i) {
    EXPECT_NEAR(acc.e3(0)[i], s * (5.0 + double(i)), tol * s) << i;
    EXPECT_NEAR(acc.e3(1)[i], s * (5.0 + double(i)), tol * s) << i;
    EXPECT_NEAR(acc.mean()[i], s * 100.0, tol * s) << i;
    EXPECT_FALSE(acc.saturated(uint32_t(i % w), uint32_t(i / w))) << i;
  }
}

// Rounding to integers adds at most 0.5 DN per frame: |ΔE3| <= (2/24)·24·0.5 = 1 DN.
TEST(E3Accumulator, PureThirdHarmonicU8) { check_pure_harmonic<uint8_t>(PROCAM_PIXEL_U8, 1.0, 255, 1.0); }
TEST(E3Accumulator, PureThirdHarmonicU16Twelve) { check_pure_harmonic<uint16_t>(PROCAM_PIXEL_U16, 16.0, 4095, 0.0625); }
TEST(E3Accumulator, PureThirdHarmonicU16Full) { check_pure_harmonic<uint16_t>(PROCAM_PIXEL_U16, 250.0, 65535, 0.01); }
TEST(E3Accumulator, PureThirdHarmonicF32) { check_pure_harmonic<float>(PROCAM_PIXEL_F32, 0.004, 1.0, 1e-3); }

TEST(E3Accumulator, SquareWaveClosedForm) {
  const uint32_t w = 24, h = 1;
  const double H = 200;
  E3Accumulator acc(w, h, 1, PROCAM_PIXEL_U8, 255, 1);
  for (uint32_t t = 0; t < 24; ++t) {
    // pixel x sees the stripe pattern shifted by t: white where (x - t) mod 24 < 12
    auto frame = make_frame<uint8_t>(w, h, t, [&](size_t x, uint32_t tt) {
      return ((int(x) - int(tt)) % 24 + 24) % 24 < 12 ? H : 0.0;
    });
    ASSERT_TRUE(acc.add(0, t, view_of(frame, w, h)).ok());
  }
  const double expected = H / (12.0 * std::sin(kPi / 8));
  for (uint32_t x = 0; x < w; ++x) {
    EXPECT_NEAR(acc.e3(0)[x], expected, 1e-3) << x;  // every phase: the magnitude does not depend on it
    EXPECT_NEAR(acc.mean()[x], H / 2, 1e-4) << x;
  }
}

TEST(E3Accumulator, SaturatedPixelIsFlaggedInAnyFrame) {
  // 41 columns: the 16-pixel SIMD steps and the scalar tail both count.
  const uint32_t w = 41, h = 3;
  const std::vector<size_t> clipped = {5, 15, 16, 31, 40, 41 + 17, 2 * 41 + 39};
  E3Accumulator acc(w, h, 1, PROCAM_PIXEL_U8, 255, 2);
  for (uint32_t t = 0; t < 24; ++t) {
    std::vector<uint8_t> f(w * h, 254);
    f[clipped[t % clipped.size()]] = 255;  // each clips in one or more frames only
    ASSERT_TRUE(acc.add(0, t, view_of(f, w, h)).ok());
  }
  for (size_t i = 0; i < w * h; ++i) {
    const bool expect = std::find(clipped.begin(), clipped.end(), i) != clipped.end();
    EXPECT_EQ(acc.saturated(uint32_t(i % w), uint32_t(i / w)), expect) << i;
  }
}

TEST(E3Accumulator, LowBitDepthU8SaturatesAtItsFullScale) {
  E3Accumulator acc(20, 1, 1, PROCAM_PIXEL_U8, 63, 1);  // a 6-bit camera in U8 frames
  for (uint32_t t = 0; t < 24; ++t) {
    std::vector<uint8_t> f(20, 62);
    if (t == 0) f[18] = 63;
    ASSERT_TRUE(acc.add(0, t, view_of(f, 20, 1)).ok());
  }
  for (uint32_t x = 0; x < 20; ++x) EXPECT_EQ(acc.saturated(x, 0), x == 18) << x;
}

TEST(E3Accumulator, TwelveBitSaturatesAtItsFullScale) {
  E3Accumulator acc(2, 1, 1, PROCAM_PIXEL_U16, 4095, 1);
  for (uint32_t t = 0; t < 24; ++t) {
    std::vector<uint16_t> f = {4094, static_cast<uint16_t>(t == 3 ? 4095 : 1000)};
    ASSERT_TRUE(acc.add(0, t, view_of(f, 2, 1)).ok());
  }
  EXPECT_FALSE(acc.saturated(0, 0));
  EXPECT_TRUE(acc.saturated(1, 0));
}

TEST(E3Accumulator, NonFiniteFloatIsFlagged) {
  E3Accumulator acc(3, 1, 1, PROCAM_PIXEL_F32, 1.0, 1);
  for (uint32_t t = 0; t < 24; ++t) {
    std::vector<float> f = {0.5f, t == 4 ? std::numeric_limits<float>::quiet_NaN() : 0.5f,
                            t == 9 ? std::numeric_limits<float>::infinity() : 0.5f};
    ASSERT_TRUE(acc.add(0, t, view_of(f, 3, 1)).ok());
  }
  EXPECT_FALSE(acc.saturated(0, 0));
  EXPECT_TRUE(acc.saturated(1, 0));
  EXPECT_TRUE(acc.saturated(2, 0));
}

TEST(E3Accumulator, RejectsDuplicatesOutOfRangeAndWrongFormatWithoutChangingState) {
  E3Accumulator acc(2, 2, 1, PROCAM_PIXEL_U8, 255, 1);
  std::vector<uint8_t> f(4, 10);
  ASSERT_TRUE(acc.add(0, 0, view_of(f, 2, 2)).ok());
  EXPECT_EQ(acc.add(0, 0, view_of(f, 2, 2)).code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(acc.add(1, 0, view_of(f, 2, 2)).code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(acc.add(0, 24, view_of(f, 2, 2)).code, PROCAM_ERR_INVALID_ARGUMENT);
  std::vector<uint16_t> g(4, 10);
  const sdk::Error e = acc.add(0, 1, view_of(g, 2, 2));
  EXPECT_EQ(e.code, PROCAM_ERR_BAD_FRAME);
  EXPECT_NE(e.message.find("U8"), std::string::npos) << e.message;
  // shift 1 was not taken: it can still be added
  EXPECT_TRUE(acc.add(0, 1, view_of(f, 2, 2)).ok());
  EXPECT_FALSE(acc.complete());
}

}  // namespace
}  // namespace procam::defocus

namespace procam::defocus {
namespace {

// Buckets are not cleared between focus settings: the first frame of each
// bucket overwrites it. Settings with different amplitudes, the later two
// interleaved in a scrambled order (one of them on recycled buckets holding
// setting 0's sums), must each give their own closed-form E3 and the mean.
TEST(E3Accumulator, ScrambledInterleavedSettingsOnRecycledBuckets) {
  const uint32_t w = 5, h = 2, F = 3;
  const double amp[F] = {9.0, 31.0, 17.0};
  E3Accumulator acc(w, h, F, PROCAM_PIXEL_U16, 65535, 2);
  std::vector<std::pair<uint32_t, uint32_t>> order;
  for (uint32_t t = 0; t < 24; ++t) order.emplace_back(0, (t * 7) % 24);
  for (uint32_t t = 0; t < 24; ++t) {
    order.emplace_back(1, (t * 5 + 3) % 24);
    order.emplace_back(2, (t * 11 + 1) % 24);
  }
  for (const auto& [f, t] : order) {
    auto frame = make_frame<uint16_t>(w, h, t, [&, f = f](size_t i, uint32_t tt) {
      return 1000.0 + 10.0 * double(i) + amp[f] * 16.0 * std::cos(2 * kPi * 3 * tt / 24.0 + 0.2 * double(i));
    });
    ASSERT_TRUE(acc.add(f, t, view_of(frame, w, h)).ok());
  }
  ASSERT_TRUE(acc.complete());
  for (size_t i = 0; i < size_t{w} * h; ++i) {
    for (uint32_t f = 0; f < F; ++f) EXPECT_NEAR(acc.e3(f)[i], amp[f] * 16.0, 1.0) << i << " f " << f;
    EXPECT_NEAR(acc.mean()[i], 1000.0 + 10.0 * double(i), 0.5) << i;
  }
}

// defer_final_fold: only the setting that completes the sweep waits, and
// never setting 0 (its fold also makes the mean); fold_pending() then gives
// the E3 of the closed form like any other fold.
TEST(E3Accumulator, DeferredFoldWaitsOnlyForTheSettingThatCompletesTheSweep) {
  const uint32_t w = 5, h = 2;
  auto profile = [](size_t i, uint32_t t) { return 100.0 + (5.0 + double(i)) * std::cos(2 * kPi * 3 * t / 24.0); };
  for (const bool zero_last : {false, true}) {
    E3Accumulator acc(w, h, 3, PROCAM_PIXEL_U8, 255, 1);
    acc.defer_final_fold(true);
    const uint32_t order[3] = {zero_last ? 1u : 0u, zero_last ? 2u : 1u, zero_last ? 0u : 2u};
    for (uint32_t f : order) {
      for (uint32_t t = 0; t < 24; ++t) {
        auto frame = make_frame<uint8_t>(w, h, t, profile);
        ASSERT_TRUE(acc.add(f, t, view_of(frame, w, h)).ok());
        const bool last = f == order[2] && t == 23;
        if (!last) {
          EXPECT_EQ(acc.pending_buckets().d, nullptr) << f << " " << t;
        }
      }
    }
    ASSERT_TRUE(acc.complete());
    if (zero_last) {
      EXPECT_EQ(acc.pending_buckets().d, nullptr);  // setting 0 folds at once
    } else {
      ASSERT_NE(acc.pending_buckets().d, nullptr);
      EXPECT_EQ(acc.pending_buckets().focus, 2u);
      EXPECT_EQ(acc.e3(2)[0], 0.f);  // not folded yet
      acc.fold_pending();
      EXPECT_EQ(acc.pending_buckets().d, nullptr);
    }
    for (size_t i = 0; i < size_t{w} * h; ++i) {
      for (uint32_t f = 0; f < 3; ++f) EXPECT_NEAR(acc.e3(f)[i], 5.0 + double(i), 0.6) << i;  // 8-bit rounding
      EXPECT_NEAR(acc.mean()[i], 100.0, 0.5) << i;
    }
  }
}

}  // namespace
}  // namespace procam::defocus
