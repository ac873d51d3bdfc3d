// SPDX-License-Identifier: MIT
// Synthetic decode tests, independent of any renderer: camera pixel (x, y)
// sees projector column col(x, y) = floor(1.3 x + 0.25 y + 7) (a known map),
// with a shadow rectangle and a region beyond the projector's last column
// that receive no projector light. Frames are black + contrast * pattern + noise,
// quantized to 8, 12 and 16 bits (and F32). The truth is col(x, y) itself.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numeric>
#include <random>
#include <vector>

#include "binarize.hpp"
#include "codes.hpp"
#include "decode.hpp"
#include "gray_code.hpp"
#include "plan_layout.hpp"
#include "round_decoder.hpp"

namespace procam::sl {
namespace {

constexpr uint32_t kCamW = 640, kCamH = 96, kProjW = 800;

// True projector column per camera pixel; -1 = no projector light (shadow).
std::vector<int32_t> truth_columns() {
  std::vector<int32_t> col(size_t{kCamW} * kCamH);
  for (uint32_t y = 0; y < kCamH; ++y)
    for (uint32_t x = 0; x < kCamW; ++x) {
      auto c = static_cast<int32_t>(std::floor(1.3 * x + 0.25 * y + 7.0));
      if (c >= static_cast<int32_t>(kProjW)) c = -1;              // beyond the projector
      if (x >= 100 && x < 150 && y >= 20 && y < 40) c = -1;       // cast shadow
      col[size_t{y} * kCamW + x] = c;
    }
  return col;
}

struct Sensor {
  procam_pixel_type type;
  uint32_t bits;      // significant bits (32 for F32)
  double black;       // black level + ambient, in input units
  double contrast;    // white - black of a lit pixel, in input units
  double noise;       // uniform noise amplitude (+-), in input units
  double full_scale() const { return type == PROCAM_PIXEL_F32 ? 1.0 : std::ldexp(1.0, static_cast<int>(bits)) - 1; }
};

struct TestFrame {
  std::vector<uint8_t> u8;
  std::vector<uint16_t> u16;
  std::vector<float> f32;
  procam_image img{};
  // Writes value v (input units) at pixel i, quantized for integer types.
  void set(size_t i, double v, const Sensor& s) {
    if (s.type == PROCAM_PIXEL_F32) {
      f32[i] = static_cast<float>(v);
      return;
    }
    const double q = std::clamp(std::round(v), 0.0, s.full_scale());
    if (s.type == PROCAM_PIXEL_U8)
      u8[i] = static_cast<uint8_t>(q);
    else
      u16[i] = static_cast<uint16_t>(q);
  }
  double get(size_t i) const {
    if (!f32.empty()) return static_cast<double>(f32[i]);
    if (!u16.empty()) return u16[i];
    return u8[i];
  }
};

TestFrame blank_frame(const Sensor& s, uint32_t w = kCamW, uint32_t h = kCamH) {
  TestFrame f;
  const size_t n = size_t{w} * h;
  f.img.width = w;
  f.img.height = h;
  f.img.channels = 1;
  f.img.pixel_type = s.type;
  f.img.bit_depth = s.bits;
  switch (s.type) {
    case PROCAM_PIXEL_U8: f.u8.assign(n, 0); f.img.data = f.u8.data(); f.img.stride_bytes = w; break;
    case PROCAM_PIXEL_U16: f.u16.assign(n, 0); f.img.data = f.u16.data(); f.img.stride_bytes = size_t{w} * 2; break;
    default: f.f32.assign(n, 0.f); f.img.data = f.f32.data(); f.img.stride_bytes = size_t{w} * 4; break;
  }
  return f;
}

// One frame per layout entry: black + contrast * lit + noise.
std::vector<TestFrame> render(const Layout& layout, const StripeCode& cols,
                              const std::vector<int32_t>& col, const Sensor& s, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> noise(-s.noise, s.noise);
  std::vector<TestFrame> frames;
  for (const FrameRole& role : layout.frames) {
    TestFrame f = blank_frame(s);
    for (size_t i = 0; i < col.size(); ++i) {
      bool lit = false;
      if (col[i] >= 0) {
        const auto c = static_cast<uint32_t>(col[i]);
        switch (role.kind) {
          case FrameKind::white: lit = true; break;
          case FrameKind::black: lit = false; break;
          case FrameKind::plane: lit = cols.bit(role.plane, c); break;
          case FrameKind::inverse: lit = !cols.bit(role.plane, c); break;
        }
      }
      f.set(i, s.black + (lit ? s.contrast : 0.0) + noise(rng), s);
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

RoundResult decode(const Layout& layout, const StripeCode& cols, std::vector<TestFrame>& frames,
                   const std::vector<uint32_t>& order, uint32_t threads = 1,
                   double min_contrast = 0.03, double min_bit_margin = 0.1,
                   uint32_t max_weak_error_px = 0) {
  BinaryRoundDecoder dec(layout, cols, nullptr, kCamW, kCamH, threads, max_weak_error_px);
  for (uint32_t i : order) {
    sdk::Error e = dec.add_frame(i, frames[i].img);
    EXPECT_TRUE(e.ok()) << e.message;
  }
  EXPECT_TRUE(dec.complete());
  return dec.finish(min_contrast, min_bit_margin);
}

std::vector<uint32_t> in_order(size_t n) {
  std::vector<uint32_t> o(n);
  std::iota(o.begin(), o.end(), 0u);
  return o;
}

// Decoded columns exact on lit pixels, invalid (NaN) on shadow pixels.
void expect_exact(const RoundResult& r, const std::vector<int32_t>& col, const Sensor& s) {
  size_t checked_lit = 0, checked_shadow = 0;
  const double min_conf = 1.0 - 2.0 * 2.0 * s.noise / s.contrast;  // worst-case noise on both sides
  for (size_t i = 0; i < col.size(); ++i) {
    if (col[i] >= 0) {
      ASSERT_EQ(r.cols.valid[i], 255) << "pixel " << i << " col " << col[i];
      ASSERT_EQ(r.cols.coord[i], static_cast<float>(col[i])) << "pixel " << i;
      ASSERT_GE(static_cast<double>(r.cols.confidence[i]), min_conf - 1e-6);
      ASSERT_LE(r.cols.confidence[i], 1.0f);
      ++checked_lit;
    } else {
      ASSERT_EQ(r.cols.valid[i], 0) << "shadow pixel " << i;
      ASSERT_TRUE(std::isnan(r.cols.coord[i]));
      ++checked_shadow;
    }
  }
  EXPECT_GT(checked_lit, col.size() / 2);
  EXPECT_GT(checked_shadow, 1000u);
}

struct Case {
  const char* name;
  Sensor sensor;
};
const Case kCases[] = {
    {"u8_8bit", {PROCAM_PIXEL_U8, 8, 10, 200, 3}},
    {"u16_12bit", {PROCAM_PIXEL_U16, 12, 100, 3000, 40}},
    {"u16_16bit", {PROCAM_PIXEL_U16, 16, 1000, 50000, 500}},
    {"f32", {PROCAM_PIXEL_F32, 32, 0.02, 0.7, 0.01}},
};

TEST(SyntheticDecode, ExactColumnsInverseAndWhite) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  for (bool inverse : {true, false}) {
    const Layout layout = make_layout(cols, nullptr, inverse);
    for (const Case& c : kCases) {
      SCOPED_TRACE(std::string(c.name) + (inverse ? " inverse" : " white"));
      std::vector<TestFrame> frames = render(layout, cols, col, c.sensor, 7);
      const RoundResult r = decode(layout, cols, frames, in_order(frames.size()));
      EXPECT_DOUBLE_EQ(r.full_scale, c.sensor.full_scale());
      expect_exact(r, col, c.sensor);
    }
  }
}

TEST(SyntheticDecode, AnyFrameOrderAndThreadCountGiveTheSameMaps) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  for (bool inverse : {true, false}) {
    const Layout layout = make_layout(cols, nullptr, inverse);
    std::vector<TestFrame> frames = render(layout, cols, col, kCases[1].sensor, 11);
    const RoundResult ref = decode(layout, cols, frames, in_order(frames.size()));
    std::vector<uint32_t> reversed = in_order(frames.size());
    std::reverse(reversed.begin(), reversed.end());
    std::vector<uint32_t> shuffled = in_order(frames.size());
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(3));
    for (const auto& order : {reversed, shuffled}) {
      for (uint32_t threads : {1u, 3u}) {
        const RoundResult r = decode(layout, cols, frames, order, threads);
        ASSERT_EQ(r.cols.valid, ref.cols.valid);
        ASSERT_EQ(r.cols.confidence, ref.cols.confidence);
        for (size_t i = 0; i < col.size(); ++i)
          ASSERT_TRUE(r.cols.coord[i] == ref.cols.coord[i] ||
                      (std::isnan(r.cols.coord[i]) && std::isnan(ref.cols.coord[i])));
      }
    }
  }
}

// Overwrites pixel i of a plane frame and its inverse so that the bit keeps
// its true value but its margin |L - L̄| becomes `margin_frac` of the contrast.
void set_margin(std::vector<TestFrame>& frames, const Layout& layout, const StripeCode& cols,
                size_t plane_frame, size_t i, int32_t c, const Sensor& s, double margin_frac) {
  const FrameRole& role = layout.frames[plane_frame];
  const double sign = cols.bit(role.plane, static_cast<uint32_t>(c)) ? 1.0 : -1.0;
  const double mid = s.black + s.contrast / 2;
  frames[0].set(i, s.black + s.contrast, s);  // noise-free white and black here
  frames[1].set(i, s.black, s);
  frames[plane_frame].set(i, mid + sign * margin_frac * s.contrast / 2, s);
  frames[static_cast<size_t>(role.partner)].set(i, mid - sign * margin_frac * s.contrast / 2, s);
}

TEST(SyntheticDecode, NearTieIsInvalidNotGuessed) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  const Sensor s = kCases[1].sensor;  // 12 bit: fine steps
  std::vector<TestFrame> frames = render(layout, cols, col, s, 5);
  const size_t tie = 10 * kCamW + 300, thin = 10 * kCamW + 301, ok_px = 10 * kCamW + 302;
  set_margin(frames, layout, cols, 6, tie, col[tie], s, 0.0);      // L == L̄
  set_margin(frames, layout, cols, 8, thin, col[thin], s, 0.05);   // below 0.1
  set_margin(frames, layout, cols, 8, ok_px, col[ok_px], s, 0.2);  // above 0.1
  const RoundResult r = decode(layout, cols, frames, in_order(frames.size()));
  EXPECT_EQ(r.cols.valid[tie], 0);
  EXPECT_TRUE(std::isnan(r.cols.coord[tie]));
  EXPECT_NEAR(r.cols.confidence[tie], 0.0f, 1e-6f);
  EXPECT_EQ(r.cols.valid[thin], 0);
  EXPECT_NEAR(r.cols.confidence[thin], 0.05f, 0.002f);
  EXPECT_EQ(r.cols.valid[ok_px], 255);
  EXPECT_EQ(r.cols.coord[ok_px], static_cast<float>(col[ok_px]));
  EXPECT_NEAR(r.cols.confidence[ok_px], 0.2f, 0.002f);
  // With the threshold lowered below 0.05 the thin pixel decodes exactly.
  const RoundResult loose = decode(layout, cols, frames, in_order(frames.size()), 1, 0.03, 0.01);
  EXPECT_EQ(loose.cols.valid[thin], 255);
  EXPECT_EQ(loose.cols.coord[thin], static_cast<float>(col[thin]));
  EXPECT_EQ(loose.cols.valid[tie], 0) << "an exact tie is never valid";
}

TEST(SyntheticDecode, SaturatedPlaneIsInvalid) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  {  // 8 bit: plane and inverse both clipped at 255
    const Sensor s = kCases[0].sensor;
    std::vector<TestFrame> frames = render(layout, cols, col, s, 9);
    const size_t i = 50 * kCamW + 200;
    frames[0].set(i, 255, s);
    frames[4].set(i, 255, s);
    frames[5].set(i, 255, s);
    const RoundResult r = decode(layout, cols, frames, in_order(frames.size()), 1, 0.03, 0.0);
    EXPECT_EQ(r.cols.valid[i], 0);
    EXPECT_TRUE(std::isnan(r.cols.coord[i]));
  }
  {  // F32: both above full scale (1.0) but different: only the saturation rule catches it
    const Sensor s = kCases[3].sensor;
    std::vector<TestFrame> frames = render(layout, cols, col, s, 9);
    const size_t bad = 50 * kCamW + 200, good = 50 * kCamW + 201;
    for (size_t i : {bad, good}) {
      frames[0].set(i, 1.5, s);
      frames[1].set(i, 0.0, s);
      const bool b = cols.bit(layout.frames[4].plane, static_cast<uint32_t>(col[i]));
      frames[4].set(i, b ? 1.4 : (i == bad ? 1.1 : 0.1), s);
      frames[5].set(i, b ? (i == bad ? 1.1 : 0.1) : 1.4, s);
    }
    const RoundResult r = decode(layout, cols, frames, in_order(frames.size()));
    EXPECT_EQ(r.cols.valid[bad], 0);
    EXPECT_EQ(r.cols.valid[good], 255);
    EXPECT_EQ(r.cols.coord[good], static_cast<float>(col[good]));
  }
}

void expect_no_inf(const RoundResult& r) {
  for (size_t i = 0; i < r.cols.coord.size(); ++i) {
    ASSERT_FALSE(std::isinf(r.cols.coord[i]));
    ASSERT_TRUE(std::isfinite(r.cols.confidence[i]));
    ASSERT_GE(r.cols.confidence[i], 0.0f);
    ASSERT_LE(r.cols.confidence[i], 1.0f);
    ASSERT_TRUE(std::isfinite(r.intensity[i]));
    ASSERT_TRUE(r.cols.valid[i] == 0 || r.cols.valid[i] == 255);
  }
}

TEST(SyntheticDecode, AllBlackFramesAreAllInvalid) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> none(size_t{kCamW} * kCamH, -1);  // projector off / no light
  for (bool inverse : {true, false}) {
    const Layout layout = make_layout(cols, nullptr, inverse);
    for (const Case& c : kCases) {
      SCOPED_TRACE(c.name);
      std::vector<TestFrame> frames = render(layout, cols, none, c.sensor, 13);
      const RoundResult r = decode(layout, cols, frames, in_order(frames.size()));
      EXPECT_EQ(std::count(r.cols.valid.begin(), r.cols.valid.end(), 255), 0);
      for (float v : r.cols.coord) ASSERT_TRUE(std::isnan(v));
      expect_no_inf(r);
    }
  }
  {  // exactly zero everywhere: contrast 0, margin 0
    const Layout layout = make_layout(cols, nullptr, true);
    const Sensor zero{PROCAM_PIXEL_U8, 8, 0, 0, 0};
    std::vector<TestFrame> frames = render(layout, cols, none, zero, 1);
    const RoundResult r = decode(layout, cols, frames, in_order(frames.size()), 1, 0.0, 0.0);
    EXPECT_EQ(std::count(r.cols.valid.begin(), r.cols.valid.end(), 255), 0);
    expect_no_inf(r);
  }
}

TEST(SyntheticDecode, NonFiniteInputIsInvalid) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  const Sensor s = kCases[3].sensor;
  std::vector<TestFrame> frames = render(layout, cols, col, s, 21);
  const size_t a = 30 * kCamW + 210, b = 30 * kCamW + 211, c = 30 * kCamW + 212;
  frames[7].f32[a] = std::numeric_limits<float>::quiet_NaN();
  frames[0].f32[b] = std::numeric_limits<float>::infinity();
  frames[3].f32[c] = -std::numeric_limits<float>::infinity();
  const RoundResult r = decode(layout, cols, frames, in_order(frames.size()));
  for (size_t i : {a, b, c}) {
    EXPECT_EQ(r.cols.valid[i], 0) << i;
    EXPECT_TRUE(std::isnan(r.cols.coord[i]));
  }
  EXPECT_EQ(r.cols.valid[c + 1], 255);
  expect_no_inf(r);
}

TEST(SyntheticDecode, LowContrastIsShadow) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  const Sensor dim{PROCAM_PIXEL_U16, 12, 100, 0.02 * 4095, 0};  // contrast 2% of full scale
  std::vector<TestFrame> frames = render(layout, cols, col, dim, 1);
  const RoundResult strict = decode(layout, cols, frames, in_order(frames.size()));
  EXPECT_EQ(std::count(strict.cols.valid.begin(), strict.cols.valid.end(), 255), 0);
  const RoundResult loose = decode(layout, cols, frames, in_order(frames.size()), 1, 0.01);
  expect_exact(loose, col, Sensor{PROCAM_PIXEL_U16, 12, 100, 0.02 * 4095, 0.5});
}

TEST(SyntheticDecode, WhiteModeHandlesBlackLevelWhereFootnoteFormFails) {
  // Strong ambient: black 150 DN, contrast 80 DN (white 230) at 8 bit.
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, false);
  const Sensor s{PROCAM_PIXEL_U8, 8, 150, 80, 2};
  std::vector<TestFrame> frames = render(layout, cols, col, s, 17);
  expect_exact(decode(layout, cols, frames, in_order(frames.size())), col, s);
  // The footnote's L̄ = white - L ignores the black level: an unlit pixel
  // (L = 150) gets L̄ = 80 < L and binarizes as lit.
  const float L = 150, W = 230, B = 150;
  const float naive = W - L;
  float synth = 0;
  synthesize_inverse(&L, &W, &B, 1, &synth);
  EXPECT_GT(L, naive);        // footnote form: wrong bit (lit)
  EXPECT_FLOAT_EQ(synth, W);  // generalized: L̄ = W + B - L = W for an unlit pixel
  EXPECT_LT(L, synth);        // correct bit (unlit)
}

TEST(SyntheticDecode, RejectsWrongFramesWithoutChangingState) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  std::vector<TestFrame> frames = render(layout, cols, col, kCases[0].sensor, 2);
  BinaryRoundDecoder dec(layout, cols, nullptr, kCamW, kCamH, 1);
  TestFrame small = blank_frame(kCases[0].sensor, 100, 100);
  sdk::Error e = dec.add_frame(0, small.img);
  EXPECT_EQ(e.code, PROCAM_ERR_BAD_FRAME);
  EXPECT_NE(e.message.find("expected 640x96"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find("got 100x100"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find("frame 0 (white)"), std::string::npos) << e.message;
  TestFrame rgb = blank_frame(kCases[0].sensor);
  rgb.img.channels = 3;
  rgb.u8.assign(size_t{kCamW} * kCamH * 3, 0);
  rgb.img.data = rgb.u8.data();
  rgb.img.stride_bytes = size_t{kCamW} * 3;
  EXPECT_EQ(dec.add_frame(0, rgb.img).code, PROCAM_ERR_BAD_FRAME);
  ASSERT_TRUE(dec.add_frame(0, frames[0].img).ok());
  TestFrame other = blank_frame(kCases[1].sensor);  // U16/12 after U8/8
  e = dec.add_frame(1, other.img);
  EXPECT_EQ(e.code, PROCAM_ERR_BAD_FRAME);
  EXPECT_NE(e.message.find("U16/12-bit"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find("U8/8-bit"), std::string::npos) << e.message;
  for (uint32_t i = 1; i < frames.size(); ++i) ASSERT_TRUE(dec.add_frame(i, frames[i].img).ok());
  expect_exact(dec.finish(0.03, 0.1), col, kCases[0].sensor);
}

// ---- tolerated weak planes (decode.hpp, max_weak_error_px) ----------------

// Brute force, independent of plane_error_bounds: flip bit k of every
// column's Gray word and find the column with that word by search.
std::vector<uint32_t> brute_force_gray_bounds(uint32_t length, uint32_t bits) {
  std::vector<uint32_t> word(length);
  for (uint32_t x = 0; x < length; ++x) word[x] = x ^ (x >> 1);
  std::vector<uint32_t> bound(bits, 0);
  for (uint32_t k = 0; k < bits; ++k)
    for (uint32_t x = 0; x < length; ++x)
      for (uint32_t y = 0; y < length; ++y)
        if (word[y] == (word[x] ^ (1u << k)))
          bound[k] = std::max(bound[k], x > y ? x - y : y - x);
  return bound;
}

TEST(WeakPlanes, GrayErrorBoundsMatchBruteForce) {
  for (uint32_t length : {2u, 5u, 40u, 100u, 256u}) {
    const StripeCode code = make_gray_code(length);
    EXPECT_EQ(plane_error_bounds(code), brute_force_gray_bounds(length, code.bits)) << length;
  }
  // Full width 1024: bit k flips binary bits k..0, an error of 2^(k+1) - 1.
  const std::vector<uint32_t> b = plane_error_bounds(make_gray_code(1024));
  ASSERT_EQ(b.size(), 10u);
  for (uint32_t k = 0; k < 10; ++k) EXPECT_EQ(b[k], (2u << k) - 1u) << k;
  // Only the finest plane (the last projected) is tolerable at 1 px.
  const std::vector<uint8_t> t = tolerable_planes(b, 1);
  for (uint32_t p = 0; p < 10; ++p) EXPECT_EQ(t[p], p == 9 ? 1 : 0) << p;
  for (uint8_t v : tolerable_planes(b, 0)) EXPECT_EQ(v, 0);  // 0 = every plane strict
}

TEST(WeakPlanes, XorBasePlaneBoundIsLarge) {
  // Projected words of XOR-02 / XOR-04 (thesis Eq. 3.6-3.8) built here, then
  // bounds by brute force over projected columns.
  for (const auto& [id, base] : {std::pair{"xor02", 0u}, std::pair{"xor04", 1u}}) {
    const uint32_t length = 64, bits = 6, high = 0x3Fu & ~((2u << base) - 1u);
    std::vector<uint32_t> word(length);
    for (uint32_t x = 0; x < length; ++x) {
      const uint32_t g = x ^ (x >> 1);
      word[x] = ((g >> base) & 1u) != 0 ? g ^ high : g;
    }
    std::vector<uint32_t> expect(bits, 0);
    for (uint32_t k = 0; k < bits; ++k)
      for (uint32_t x = 0; x < length; ++x)
        for (uint32_t y = 0; y < length; ++y)
          if (word[y] == (word[x] ^ (1u << k))) expect[k] = std::max(expect[k], x > y ? x - y : y - x);
    const ProjectedCode code = make_projected_code(id, length);
    EXPECT_EQ(plane_error_bounds(code), expect) << id;
    EXPECT_GE(expect[base], length / 2) << id << ": the base plane flips every decoded bit above it";
  }
  const std::vector<uint32_t> x2 = plane_error_bounds(make_projected_code("xor02", 1024));
  EXPECT_GE(x2[0], 512u);
  EXPECT_EQ(x2[1], 3u);  // like Gray bit 1
  const std::vector<uint32_t> x4 = plane_error_bounds(make_projected_code("xor04", 1024));
  EXPECT_EQ(x4[0], 1u);  // projected unchanged: Gray bit 0
  EXPECT_GE(x4[1], 512u);
}

TEST(WeakPlanes, FinestGrayPlaneNearTieIsToleratedOnlyWithMaxWeak) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  for (bool inverse : {true, false}) {
    SCOPED_TRACE(inverse ? "inverse" : "white");
    const Layout layout = make_layout(cols, nullptr, inverse);
    const Sensor s = kCases[1].sensor;  // 12 bit
    std::vector<TestFrame> frames = render(layout, cols, col, s, 23);
    const size_t step = inverse ? 2 : 1;
    const size_t finest = 2 + (cols.bits - 1) * step;  // frame of bit 0 (stripe width 2)
    const size_t mid = 2 + 3 * step;                     // a coarser plane
    ASSERT_EQ(layout.frames[finest].label, "col bit 0");
    const size_t weak = 12 * kCamW + 300, tie = 12 * kCamW + 301, coarse = 12 * kCamW + 302;
    auto set = [&](size_t f, size_t i, double frac) {
      const int32_t c = col[i];
      const double sign = cols.bit(layout.frames[f].plane, static_cast<uint32_t>(c)) ? 1.0 : -1.0;
      const double midv = s.black + s.contrast / 2;
      frames[0].set(i, s.black + s.contrast, s);
      frames[1].set(i, s.black, s);
      frames[f].set(i, midv + sign * frac * s.contrast / 2, s);
      if (inverse) frames[f + 1].set(i, midv - sign * frac * s.contrast / 2, s);
    };
    set(finest, weak, 0.05);   // near tie, right sign
    set(finest, tie, 0.0);     // exact tie: no sign at all
    set(mid, coarse, 0.05);    // near tie on a strict plane
    const RoundResult strict = decode(layout, cols, frames, in_order(frames.size()), 1, 0.03, 0.1, 0);
    const RoundResult tolerant = decode(layout, cols, frames, in_order(frames.size()), 1, 0.03, 0.1, 1);
    EXPECT_EQ(strict.cols.valid[weak], 0) << "max_weak_error_px = 0: today's rule";
    EXPECT_EQ(tolerant.cols.valid[weak], 255);
    EXPECT_EQ(tolerant.cols.coord[weak], static_cast<float>(col[weak]));
    EXPECT_NEAR(tolerant.cols.confidence[weak], 0.05f, 0.002f) << "confidence shows the weak plane";
    EXPECT_EQ(tolerant.cols.valid[tie], 0) << "an exact tie is never valid";
    EXPECT_EQ(tolerant.cols.valid[coarse], 0) << "coarser planes stay strict";
    EXPECT_EQ(strict.cols_weak, 0u);
    EXPECT_GE(tolerant.cols_weak, 1u);
    // Every other pixel decodes the same under both rules.
    size_t differ = 0;
    for (size_t i = 0; i < col.size(); ++i) differ += strict.cols.valid[i] != tolerant.cols.valid[i];
    EXPECT_EQ(differ, tolerant.cols_weak);
  }
}

// The fit of sigma_d^2 = a + b S from per-pixel sample variances of n pair
// sums: samples drawn here from Gaussians of known variance.
TEST(NoiseRule, FitRecoversReadAndShotNoise) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> level(10.0, 500.0);
  const double a = 9.0, b = 0.4;  // sigma_d^2 in DN^2: read 9, shot 0.4 per DN of S
  const uint32_t pairs = 20;
  std::vector<double> mean, var;
  for (int p = 0; p < 40000; ++p) {
    const double S = level(rng);
    std::normal_distribution<double> g(S, std::sqrt(a + b * S));
    double sum = 0, sq = 0;
    for (uint32_t k = 0; k < pairs; ++k) {
      const double v = g(rng);
      sum += v;
      sq += v * v;
    }
    const double m = sum / pairs;
    mean.push_back(m);
    var.push_back((sq - pairs * m * m) / (pairs - 1));
  }
  const NoiseFit f = fit_noise_samples(mean, var, pairs, 255.0);
  ASSERT_TRUE(f.measured);
  EXPECT_NEAR(f.b, b, 0.04 * b);
  EXPECT_NEAR(f.a, a, 0.25 * a) << "a is the intercept: a few % of the variance at S ~ 250";
  for (double S : {20.0, 250.0, 480.0}) EXPECT_NEAR(f.a + f.b * S, a + b * S, 0.04 * (a + b * S));
  EXPECT_FALSE(fit_noise_samples(mean, var, 2, 255.0).measured) << "2 pairs: too few to measure";
  EXPECT_FALSE(fit_noise_samples({}, {}, pairs, 255.0).measured);
}

// End to end: frames with Gaussian noise sigma^2(I) = r + q I per frame give
// sigma_d^2 = 2 r + q (W + B) (decode.hpp), measured from the pairs alone.
TEST(NoiseRule, StreamMeasuresTheMarginNoiseOfTheCapture) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  const Sensor s{PROCAM_PIXEL_F32, 32, 0, 0, 0};
  const double r = 4e-5, q = 2e-4;  // per-frame variance, F32 units
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> albedo(0.2, 1.0);
  std::vector<double> pix_albedo(col.size());
  for (double& v : pix_albedo) v = albedo(rng);
  std::vector<TestFrame> frames;
  for (const FrameRole& role : layout.frames) {
    TestFrame f = blank_frame(s);
    for (size_t i = 0; i < col.size(); ++i) {
      bool lit = false;
      if (col[i] >= 0) {
        const auto c = static_cast<uint32_t>(col[i]);
        lit = role.kind == FrameKind::white || (role.kind == FrameKind::plane && cols.bit(role.plane, c)) ||
              (role.kind == FrameKind::inverse && !cols.bit(role.plane, c));
      }
      const double I = 0.05 + (lit ? 0.6 * pix_albedo[i] : 0.0);
      std::normal_distribution<double> g(I, std::sqrt(r + q * I));
      f.set(i, g(rng), s);
    }
    frames.push_back(std::move(f));
  }
  BinaryRoundDecoder dec(layout, cols, nullptr, kCamW, kCamH, 2, 1);
  for (uint32_t i = 0; i < frames.size(); ++i) ASSERT_TRUE(dec.add_frame(i, frames[i].img).ok());
  const RoundResult res = dec.finish(0.03, 0.0, 3.0);
  ASSERT_TRUE(res.noise.measured);
  EXPECT_EQ(res.noise.pairs, cols.bits);
  EXPECT_NEAR(res.noise.b, q, 0.1 * q);
  EXPECT_NEAR(res.noise.a, 2 * r, 0.3 * 2 * r);
  // A clean capture: the noise rule keeps every lit pixel exact (margins ~ 0.12..0.6 >> 3 sigma_d ~ 0.04).
  size_t lit = 0, exact = 0;
  for (size_t i = 0; i < col.size(); ++i) {
    if (col[i] < 0) continue;
    ++lit;
    exact += res.cols.coord[i] == static_cast<float>(col[i]) ? 1u : 0u;
  }
  EXPECT_EQ(exact, lit);
}

// A margin of 2 sigma_d is rejected at k = 3 and kept at k = 1; the threshold
// grows with W + B (shot noise), on 8-bit (integer kernels) and F32 input.
TEST(NoiseRule, MarginWithinKSigmaIsRejected) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  for (const Case& cs : {kCases[0], kCases[3]}) {
    SCOPED_TRACE(cs.name);
    const Sensor s = cs.sensor;
    std::vector<TestFrame> frames = render(layout, cols, col, s, 29);
    const size_t mid = 2 + 2 * 3;  // plane 3, a strict plane
    ASSERT_EQ(layout.frames[mid].label, "col bit " + std::to_string(cols.bits - 4));
    // Uniform noise +-u per frame: sigma_d^2 = 2 u^2 / 3 (+ quantization 2/12 at 8 bit).
    const double var = 2 * s.noise * s.noise / 3 + (s.type == PROCAM_PIXEL_U8 ? 2.0 / 12 : 0.0);
    const double sd = std::sqrt(var);
    const size_t px = 50 * kCamW + 400;
    const double sign = cols.bit(layout.frames[mid].plane, static_cast<uint32_t>(col[px])) ? 1.0 : -1.0;
    const double midv = s.black + s.contrast / 2;
    frames[mid].set(px, midv + sign * sd, s);   // margin 2 sigma_d
    frames[mid + 1].set(px, midv - sign * sd, s);
    auto run = [&](double k) {
      BinaryRoundDecoder dec(layout, cols, nullptr, kCamW, kCamH, 1, 0);
      for (uint32_t i = 0; i < frames.size(); ++i) EXPECT_TRUE(dec.add_frame(i, frames[i].img).ok());
      return dec.finish(0.03, 0.0, k);
    };
    const RoundResult k3 = run(3.0), k1 = run(1.0), off = run(0.0);
    ASSERT_TRUE(k3.noise.measured);
    // The fit sees a constant-variance capture (uniform noise): sigma_d within 25 %.
    EXPECT_NEAR(std::sqrt(k3.noise.a + k3.noise.b * (2 * s.black + s.contrast)), sd, 0.25 * sd);
    EXPECT_EQ(k3.cols.valid[px], 0) << "2 sigma_d < 3 sigma_d";
    EXPECT_EQ(k1.cols.valid[px], 255) << "2 sigma_d > 1 sigma_d";
    EXPECT_EQ(off.cols.valid[px], 255);
    EXPECT_EQ(k1.cols.coord[px], static_cast<float>(col[px]));
  }
}

// With uncertain output, a pixel whose finest plane is a near tie gets the
// two-column interval (centre col +- 0.5 around the truth's pair), and so
// does an exact tie under an unclipped white (with ties enumerated; invalid
// without); an exact tie under a clipped
// white (what a clipped pair looks like at 8 bit) and a near tie on a
// coarser plane away from its edge stay invalid; other pixels are exact with
// uncertainty 0.
TEST(UncertainPlanes, FinestPlaneTieGivesTheIntervalNotNothing) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  const Sensor s = kCases[0].sensor;  // 8 bit
  std::vector<TestFrame> frames = render(layout, cols, col, s, 31);
  const size_t finest = 2 + (cols.bits - 1) * 2, mid = 2 + 3 * 2;
  const size_t weak = 12 * kCamW + 300, tie = 12 * kCamW + 301, coarse = 12 * kCamW + 302;
  auto set = [&](size_t f, size_t i, double frac) {
    const double sign = cols.bit(layout.frames[f].plane, static_cast<uint32_t>(col[i])) ? 1.0 : -1.0;
    const double midv = s.black + s.contrast / 2;
    frames[f].set(i, midv + sign * frac * s.contrast / 2, s);
    frames[f + 1].set(i, midv - sign * frac * s.contrast / 2, s);
  };
  const size_t clipped = 12 * kCamW + 303;
  set(finest, weak, 0.05);
  set(finest, tie, 0.0);
  set(mid, coarse, 0.05);
  frames[static_cast<size_t>(layout.white_index())].set(clipped, 255, s);
  frames[finest].set(clipped, 255, s);
  frames[finest + 1].set(clipped, 255, s);
  BinaryRoundDecoder plain_dec(layout, cols, nullptr, kCamW, kCamH, 1, 1);
  plain_dec.set_uncertain_output(true);  // ties off (the default)
  for (uint32_t i = 0; i < frames.size(); ++i) ASSERT_TRUE(plain_dec.add_frame(i, frames[i].img).ok());
  const RoundResult no_ties = plain_dec.finish(0.03, 0.1, 3.0);
  EXPECT_EQ(no_ties.cols.valid[tie], 0) << "without tie_intervals a tie is invalid";
  EXPECT_EQ(no_ties.cols.valid[weak], 255);
  BinaryRoundDecoder dec(layout, cols, nullptr, kCamW, kCamH, 1, 1);
  dec.set_uncertain_output(true, 1.5f, true);
  for (uint32_t i = 0; i < frames.size(); ++i) ASSERT_TRUE(dec.add_frame(i, frames[i].img).ok());
  const RoundResult r = dec.finish(0.03, 0.1, 3.0);
  const auto c = static_cast<uint32_t>(col[weak]);
  EXPECT_EQ(r.cols.valid[weak], 255);
  EXPECT_EQ(r.cols.coord[weak], static_cast<float>(c / 2 * 2) + 0.5f);
  EXPECT_EQ(r.cols.uncertainty[weak], 0.5f);
  EXPECT_LE(r.cols.confidence[weak], 0.1f) << "lower than a certain pixel's";
  const auto ct = static_cast<uint32_t>(col[tie]);
  EXPECT_EQ(r.cols.valid[tie], 255) << "a tie under an unclipped white: either sign";
  EXPECT_EQ(r.cols.coord[tie], static_cast<float>(ct / 2 * 2) + 0.5f);
  EXPECT_EQ(r.cols.uncertainty[tie], 0.5f);
  EXPECT_EQ(r.cols.valid[clipped], 0) << "a tie under a clipped white carries no information";
  EXPECT_TRUE(std::isnan(r.cols.uncertainty[clipped]));
  EXPECT_EQ(r.cols.valid[coarse], 0);
  EXPECT_TRUE(std::isnan(r.cols.uncertainty[coarse]));
  size_t exact = 0, lit = 0;
  for (size_t i = 0; i < col.size(); ++i) {
    if (col[i] < 0 || i == weak || i == tie || i == coarse || i == clipped) continue;
    ++lit;
    exact += r.cols.coord[i] == static_cast<float>(col[i]) && r.cols.uncertainty[i] == 0.0f ? 1u : 0u;
  }
  EXPECT_EQ(exact, lit);
  EXPECT_EQ(r.cols_weak, 2u);
}

// One strict plane nearly tied (margin 2 DN, below 3 sigma_d and 0.1 C): at
// that plane's stripe edge the pixel sees both columns, so it gets the
// two-column interval; away from the edge the flip would jump by 2^k columns
// and the pixel stays invalid.
TEST(UncertainPlanes, SingleStrictPlaneTieOnlyAtItsStripeEdge) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  const Sensor s = kCases[0].sensor;
  std::vector<TestFrame> frames = render(layout, cols, col, s, 37);
  const uint32_t plane = 4;  // bit position bits - 5: stripes of 32 columns
  const size_t f = 2 + 2 * plane;
  ASSERT_EQ(layout.frames[f].label, "col bit " + std::to_string(cols.bits - 1 - plane));
  // Find, on row 60, a pixel whose column c and c + 1 differ exactly in this
  // plane (its stripe edge), and one whose neighbours do not.
  size_t edge = 0, inner = 0;
  for (uint32_t x = 200; x < 600 && (edge == 0 || inner == 0); ++x) {
    const size_t i = 60 * kCamW + x;
    const auto c = static_cast<uint32_t>(col[i]);
    const bool at_edge = cols.bit(plane, c) != cols.bit(plane, c + 1);
    const bool near_edge = at_edge || cols.bit(plane, c) != cols.bit(plane, c - 1);
    if (at_edge && edge == 0) edge = i;
    if (!near_edge && inner == 0) inner = i;
  }
  ASSERT_NE(edge, 0u);
  ASSERT_NE(inner, 0u);
  for (size_t i : {edge, inner}) {  // near tie, either sign
    frames[f].set(i, s.black + s.contrast / 2 + 1, s);
    frames[f + 1].set(i, s.black + s.contrast / 2 - 1, s);
  }
  BinaryRoundDecoder dec(layout, cols, nullptr, kCamW, kCamH, 1, 1);
  dec.set_uncertain_output(true);
  for (uint32_t i = 0; i < frames.size(); ++i) ASSERT_TRUE(dec.add_frame(i, frames[i].img).ok());
  const RoundResult r = dec.finish(0.03, 0.1, 3.0);
  EXPECT_EQ(r.cols.valid[edge], 255);
  EXPECT_EQ(r.cols.coord[edge], static_cast<float>(col[edge]) + 0.5f);
  EXPECT_EQ(r.cols.uncertainty[edge], 0.5f);
  EXPECT_NEAR(r.cols.confidence[edge], 0.01f, 0.0005f) << "the tied plane's margin 2 / C, C = 200 +- 6";
  EXPECT_EQ(r.cols.valid[inner], 0) << "a flip away from the edge is a 2^k jump: not an interval";
  EXPECT_TRUE(std::isnan(r.cols.coord[inner]));
}


// Several strict planes nearly tied at once (margin 2 DN each): the decoder
// reports the interval of every column whose word differs from the pixel's
// only in those planes, when every such word is a column, they leave no gap
// and the half-width is <= 1.5, and nothing otherwise;
// with 4 uncertain strict planes (more than tracked) the pixel is invalid.
// The expected sets are enumerated here from StripeCode::bit over all
// projector columns (not from the decoder's lookup table).
TEST(UncertainPlanes, SeveralStrictPlanesGiveTheirIntervalWhenNarrow) {
  const StripeCode cols = make_gray_code(kProjW);
  const std::vector<int32_t> col = truth_columns();
  const Layout layout = make_layout(cols, nullptr, true);
  const Sensor s = kCases[0].sensor;
  std::vector<TestFrame> frames = render(layout, cols, col, s, 41);
  const uint32_t strict = cols.bits - 1;  // planes 0 .. bits-2 are strict, bits-1 tolerable
  auto tie = [&](size_t i, uint32_t plane) {  // margin +-2 with the true sign
    const size_t f = 2 + 2 * size_t{plane};
    const double sign = cols.bit(plane, static_cast<uint32_t>(col[i])) ? 1.0 : -1.0;
    frames[f].set(i, s.black + s.contrast / 2 + sign, s);
    frames[f + 1].set(i, s.black + s.contrast / 2 - sign, s);
  };
  struct Probe {
    size_t i;
    std::vector<uint32_t> planes;
  };
  std::vector<Probe> probes;
  // Rows 50..90, every 7th pixel (all lit): the one or three strict planes
  // whose stripe edges lie nearest the pixel's column (narrow intervals
  // where a single edge runs through it) or a fixed coarse pair (wide
  // ones); one pixel with four.
  for (uint32_t y = 50; y < 90; y += 2)
    for (uint32_t x = 200; x < 580; x += 7) {
      const size_t i = size_t{y} * kCamW + x;
      const auto c = static_cast<uint32_t>(col[i]);
      std::vector<uint32_t> near;
      for (uint32_t d = 1; d < 8 && near.size() < 3; ++d)  // planes flipping at c-d|c-d+1, c+d-1|c+d
        for (uint32_t cc : {c - d, c + d - 1})
          for (uint32_t p = 0; p < strict; ++p)
            if (cc + 1 < kProjW && cols.bit(p, cc) != cols.bit(p, cc + 1) &&
                std::find(near.begin(), near.end(), p) == near.end() && near.size() < 3)
              near.push_back(p);
      if ((x / 7 + y) % 3 == 0) near = {strict - 3, strict - 5};
      if ((x / 7 + y) % 3 == 1) near.resize(std::min<size_t>(near.size(), 1));
      probes.push_back({i, near});
    }
  const size_t four = 92 * kCamW + 400;
  probes.push_back({four, {strict - 1, strict - 2, strict - 3, strict - 4}});
  for (const Probe& p : probes)
    for (uint32_t plane : p.planes) tie(p.i, plane);
  BinaryRoundDecoder dec(layout, cols, nullptr, kCamW, kCamH, 1, 1);
  dec.set_uncertain_output(true, 1.5f);
  for (uint32_t i = 0; i < frames.size(); ++i) ASSERT_TRUE(dec.add_frame(i, frames[i].img).ok());
  const RoundResult r = dec.finish(0.03, 0.1, 3.0);
  size_t narrow = 0, wide = 0;
  for (const Probe& p : probes) {
    const auto c = static_cast<uint32_t>(col[p.i]);
    uint32_t lo = kProjW, hi = 0, count = 0;
    for (uint32_t x = 0; x < kProjW; ++x) {
      bool same = true;  // x's word equals c's outside the tied planes
      for (uint32_t q = 0; q < cols.bits && same; ++q)
        same = std::find(p.planes.begin(), p.planes.end(), q) != p.planes.end() ||
               cols.bit(q, x) == cols.bit(q, c);
      if (same) {
        lo = std::min(lo, x);
        hi = std::max(hi, x);
        ++count;
      }
    }
    const float half = 0.5f * static_cast<float>(hi - lo);
    // Every flip a column of the projector, and no gap between them.
    const bool full = count == (1u << p.planes.size()) && hi - lo + 1 == count;
    SCOPED_TRACE(::testing::Message() << "pixel " << p.i << " column " << c << " planes " << p.planes.size());
    if (p.planes.size() <= 3 && full && half <= 1.5f) {
      ++narrow;
      ASSERT_EQ(r.cols.valid[p.i], 255);
      EXPECT_EQ(r.cols.coord[p.i], 0.5f * static_cast<float>(lo + hi));
      EXPECT_EQ(r.cols.uncertainty[p.i], half);
      EXPECT_LE(std::fabs(r.cols.coord[p.i] - static_cast<float>(c)), r.cols.uncertainty[p.i]) << "holds the truth";
    } else {
      ++wide;
      EXPECT_EQ(r.cols.valid[p.i], 0);
      EXPECT_TRUE(std::isnan(r.cols.coord[p.i]));
      EXPECT_TRUE(std::isnan(r.cols.uncertainty[p.i]));
    }
  }
  EXPECT_GT(narrow, 20u) << "the probes must exercise narrow intervals";
  EXPECT_GT(wide, 20u) << "and wide ones";
}


// Neighbour fill (neighbour_fill.hpp) on synthetic frames. Rows 30..79 hold
// a depth edge: from x = 480 the surface sees columns 300 lower (a jump no
// blur explains). Two bands are blurred: each pixel there sees the mean of
// the columns of the pixels x-1, x, x+1, x+2 (a 4-pixel box blur along the
// row, 5-6 projector columns at 1.3 columns per pixel), so fine planes tie
// or nearly tie and most band pixels have too many uncertain planes for an
// interval. Band A (x 300..307) lies on one smooth surface: the fill must
// recover most of it. Band B (x 474..489) straddles the edge. Everywhere a
// filled pixel's column must lie within 1 of the span of the columns it sees
// on ONE surface — never an in-between column across the edge, and a pixel
// that sees only the far surface never takes the near one's columns.
TEST(NeighbourFill, FillsABlurredBandButDoesNotBridgeADepthEdge) {
  const StripeCode cols = make_gray_code(kProjW);
  std::vector<int32_t> col = truth_columns();
  constexpr uint32_t kY0 = 30, kY1 = 80, kEdge = 480;
  for (uint32_t y = kY0; y < kY1; ++y)
    for (uint32_t x = kEdge; x < kCamW; ++x)
      if (col[size_t{y} * kCamW + x] >= 0) col[size_t{y} * kCamW + x] -= 300;
  const Layout layout = make_layout(cols, nullptr, true);
  const Sensor s = kCases[0].sensor;  // 8 bit, +-3 DN noise
  std::vector<TestFrame> frames = render(layout, cols, col, s, 53);
  auto in_band = [](uint32_t x) { return (x >= 300 && x < 308) || (x >= 474 && x < 490); };
  for (uint32_t y = kY0; y < kY1; ++y)
    for (uint32_t x = 0; x < kCamW; ++x) {
      if (!in_band(x)) continue;
      const size_t i = size_t{y} * kCamW + x;
      for (size_t f = 0; f < layout.frames.size(); ++f) {
        const FrameRole& role = layout.frames[f];
        if (role.kind != FrameKind::plane && role.kind != FrameKind::inverse) continue;
        double lit = 0;
        for (int d = -1; d <= 2; ++d) {
          const bool b = cols.bit(role.plane, static_cast<uint32_t>(col[static_cast<size_t>(static_cast<int64_t>(i) + d)]));
          lit += (role.kind == FrameKind::plane ? b : !b) ? 0.25 : 0.0;
        }
        frames[f].set(i, s.black + s.contrast * lit, s);
      }
    }
  auto run = [&](uint32_t passes, uint32_t threads) {
    BinaryRoundDecoder dec(layout, cols, nullptr, kCamW, kCamH, threads, 1);
    dec.set_uncertain_output(true, 1.5f);
    NeighbourFillRule rule;
    rule.passes = passes;
    dec.set_neighbour_fill(rule);
    for (uint32_t i = 0; i < frames.size(); ++i) EXPECT_TRUE(dec.add_frame(i, frames[i].img).ok());
    return dec.finish(0.03, 0.1, 3.0);
  };
  const RoundResult off = run(0, 1), on = run(4, 1), on3 = run(4, 3);
  EXPECT_EQ(off.cols_filled, 0u);
  // Within 1 column of the span of the columns pixel i sees on one surface.
  auto plausible = [&](size_t i, uint32_t x, float c) {
    for (int side = 0; side < 2; ++side) {
      float lo = 1e9f, hi = -1e9f;
      for (int d = -1; d <= 2; ++d) {
        if ((int64_t{x} + d >= int64_t{kEdge}) != (side == 1)) continue;
        const auto v = static_cast<float>(col[static_cast<size_t>(static_cast<int64_t>(i) + d)]);
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
      if (c >= lo - 1 && c <= hi + 1) return true;
    }
    return false;
  };
  size_t a_total = 0, a_off = 0, a_on = 0;
  for (uint32_t y = kY0; y < kY1; ++y)
    for (uint32_t x = 300; x < 308; ++x) {
      const size_t i = size_t{y} * kCamW + x;
      ++a_total;
      a_off += off.cols.valid[i] != 0 ? 1u : 0u;
      if (on.cols.valid[i] == 0) continue;
      ++a_on;
      if (off.cols.valid[i] != 0) continue;  // decoded from its own bits, unchanged
      EXPECT_TRUE(plausible(i, x, on.cols.coord[i])) << "band A pixel " << x << "," << y << ": " << on.cols.coord[i];
      EXPECT_GE(on.cols.uncertainty[i], 0.5f) << "a filled pixel reports an interval";
    }
  std::printf("band A: %zu px, valid without fill %zu, with fill %zu (filled in all: %zu)\n", a_total, a_off,
              a_on, on.cols_filled);
  EXPECT_LT(a_off * 2, a_total) << "the blur must defeat the interval rule on most band pixels";
  EXPECT_GE(a_on * 100, a_total * 80) << "4 passes from both sides reach across the 8-pixel band";
  size_t b_valid = 0, b_off = 0;
  for (uint32_t y = kY0; y < kY1; ++y)
    for (uint32_t x = 474; x < 490; ++x) {
      const size_t i = size_t{y} * kCamW + x;
      b_off += off.cols.valid[i] != 0 ? 1u : 0u;
      if (on.cols.valid[i] == 0 || off.cols.valid[i] != 0) continue;
      ++b_valid;
      EXPECT_TRUE(plausible(i, x, on.cols.coord[i])) << "band B pixel " << x << "," << y << ": " << on.cols.coord[i];
    }
  std::printf("band B: valid without fill %zu, filled %zu of %u\n", b_off, b_valid, (kY1 - kY0) * 16);
  EXPECT_GT(b_valid, 0u) << "the fill must act on band B for the edge check to mean something";
  // Outside the bands the fill changes nothing; the result does not depend
  // on the thread count (Jacobi passes).
  for (size_t i = 0; i < col.size(); ++i) {
    const uint32_t x = static_cast<uint32_t>(i % kCamW), y = static_cast<uint32_t>(i / kCamW);
    if (!(y >= kY0 && y < kY1 && in_band(x))) {
      EXPECT_EQ(on.cols.valid[i], off.cols.valid[i]) << i;
    }
    ASSERT_EQ(on.cols.valid[i], on3.cols.valid[i]) << i;
    if (on.cols.valid[i] != 0) {
      ASSERT_EQ(on.cols.coord[i], on3.cols.coord[i]) << i;
    }
  }
  EXPECT_EQ(on.cols_filled, on3.cols_filled);
}

}  // namespace
}  // namespace procam::sl
