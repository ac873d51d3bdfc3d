// SPDX-License-Identifier: MIT
// Streaming max/min: SIMD kernels against the scalar ones, and the running
// extrema against a brute-force max/min over every pixel type.
#include "extrema.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace procam::separation {
namespace {

TEST(Fold, SimdKernelsMatchScalarOnOddLengths) {
  std::mt19937 rng(7);
  for (size_t n : {0u, 1u, 31u, 32u, 33u, 100u, 1000u}) {
    std::vector<uint8_t> v(n), m(n), k(n);
    std::vector<uint16_t> v16(n), m16(n), k16(n);
    for (size_t i = 0; i < n; ++i) {
      v[i] = uint8_t(rng());
      m[i] = uint8_t(rng());
      k[i] = uint8_t(rng());
      v16[i] = uint16_t(rng());
      m16[i] = uint16_t(rng());
      k16[i] = uint16_t(rng());
    }
    auto m2 = m, k2 = k;
    auto m162 = m16, k162 = k16;
    fold_u8(v.data(), m.data(), k.data(), n);
    fold_u8_scalar(v.data(), m2.data(), k2.data(), n);
    EXPECT_EQ(m, m2) << n;
    EXPECT_EQ(k, k2) << n;
    fold_u16(v16.data(), m16.data(), k16.data(), n);
    fold_u16_scalar(v16.data(), m162.data(), k162.data(), n);
    EXPECT_EQ(m16, m162) << n;
    EXPECT_EQ(k16, k162) << n;
  }
}

// Frames with padded rows (the padding holds values that must never be read).
template <class T>
std::vector<procam_image> make_frames(std::vector<std::vector<T>>& store, uint32_t w, uint32_t h, uint32_t pad,
                                      int count, uint32_t bits, std::mt19937& rng, double top) {
  std::vector<procam_image> views;
  for (int f = 0; f < count; ++f) {
    std::vector<T> px(size_t{w + pad} * h, T(top));
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) px[size_t{y} * (w + pad) + x] = T(std::floor(double(rng() % 1000) / 1000 * top));
    store.push_back(std::move(px));
  }
  for (auto& px : store) {
    procam_image v = sdk::gray_view(px.data(), w, h);
    if constexpr (!std::is_same_v<T, float>) v.bit_depth = bits;
    v.stride_bytes = size_t{w + pad} * sizeof(T);
    views.push_back(v);
  }
  return views;
}

template <class T>
void expect_brute_force(uint32_t bits, double top) {
  const uint32_t w = 37, h = 5;
  std::mt19937 rng(bits);
  std::vector<std::vector<T>> store;
  auto frames = make_frames<T>(store, w, h, 3, 6, bits, rng, top);
  Extrema ex(w, h);
  for (const auto& f : frames) ASSERT_TRUE(ex.add(f, 2).ok());
  EXPECT_EQ(ex.count(), 6u);
  std::vector<float> mx(w), mn(w);
  for (uint32_t y = 0; y < h; ++y) {
    ex.max_row(y, mx.data());
    ex.min_row(y, mn.data());
    for (uint32_t x = 0; x < w; ++x) {
      float a = -1, b = 1e30f;
      for (const auto& px : store) {
        a = std::max(a, float(px[size_t{y} * (w + 3) + x]));
        b = std::min(b, float(px[size_t{y} * (w + 3) + x]));
      }
      ASSERT_EQ(mx[x], a) << x << "," << y;
      ASSERT_EQ(mn[x], b) << x << "," << y;
    }
  }
}

TEST(Extrema, EightBitFrames) { expect_brute_force<uint8_t>(8, 255); }
TEST(Extrema, TwelveBitFrames) { expect_brute_force<uint16_t>(12, 4095); }
TEST(Extrema, SixteenBitFrames) { expect_brute_force<uint16_t>(16, 65535); }
TEST(Extrema, FloatFrames) { expect_brute_force<float>(32, 1.0); }

TEST(Extrema, NanSampleMakesThePixelNanFromThenOn) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> a = {0.5f, 0.5f}, b = {nan, 0.7f}, c = {0.9f, 0.1f};
  Extrema ex(2, 1);
  for (auto* f : {&a, &b, &c}) ASSERT_TRUE(ex.add(sdk::gray_view(f->data(), 2, 1), 1).ok());
  float mx[2], mn[2];
  ex.max_row(0, mx);
  ex.min_row(0, mn);
  EXPECT_TRUE(std::isnan(mx[0]) && std::isnan(mn[0]));
  EXPECT_EQ(mx[1], 0.7f);
  EXPECT_EQ(mn[1], 0.1f);
}

TEST(Extrema, OtherPixelTypeIsBadFrameAndChangesNothing) {
  std::vector<uint8_t> a = {10, 20};
  std::vector<uint16_t> b = {1000, 0};
  Extrema ex(2, 1);
  ASSERT_TRUE(ex.add(sdk::gray_view(a.data(), 2, 1), 1).ok());
  const sdk::Error e = ex.add(sdk::gray_view(b.data(), 2, 1, 12), 1);
  EXPECT_EQ(e.code, PROCAM_ERR_BAD_FRAME);
  EXPECT_NE(e.message.find("same camera mode"), std::string::npos) << e.message;
  EXPECT_EQ(ex.count(), 1u);
  float mx[2];
  ex.max_row(0, mx);
  EXPECT_EQ(mx[0], 10.f);
  EXPECT_EQ(mx[1], 20.f);
}

}  // namespace
}  // namespace procam::separation
