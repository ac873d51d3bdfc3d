// SPDX-License-Identifier: MIT
// The SIMD kernels (AVX2 / AVX-512, chosen at run time) against the portable
// scalar kernels: bit-identical state and maps on random data with ties,
// saturation, black pixels, 8/12/16-bit and F32 input (NaN / inf), and the
// fused decode + vote against per-code decode + vote_pixels. On a CPU without
// AVX2 both sides run the scalar kernels and the tests still check the
// fused-vs-separate and integer-vs-float vote equivalences.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "binarize.hpp"
#include "codes.hpp"
#include "gray_code.hpp"
#include "multi_round.hpp"
#include "plan_layout.hpp"
#include "round_decoder.hpp"
#include "vote.hpp"

namespace procam::sl {
namespace {

struct ScalarOnly {  // RAII: scalar kernels within a scope
  ScalarOnly() { set_simd_enabled(false); }
  ~ScalarOnly() { set_simd_enabled(true); }
};

// The SIMD levels to compare with scalar: the widest (AVX-512 where present)
// and AVX2 with AVX-512 switched off. Where neither exists both are scalar.
struct SimdLevel {
  bool avx512;
  const char* name;
};
constexpr SimdLevel kLevels[] = {{true, "widest"}, {false, "avx2"}};
struct Level {  // RAII: AVX-512 on / off within a scope
  explicit Level(const SimdLevel& l) { set_avx512_enabled(l.avx512); }
  ~Level() { set_avx512_enabled(true); }
};

bool same_float(float a, float b) {
  return (std::isnan(a) && std::isnan(b)) || std::memcmp(&a, &b, sizeof a) == 0;
}

TEST(Kernels, Fold8BitSimdEqualsScalar) {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> byte(0, 255), small(0, 3);
  for (size_t n : {size_t{1}, size_t{31}, size_t{32}, size_t{33}, size_t{65}, size_t{1000}}) {
    std::vector<uint8_t> L(n), Lb(n), W(n), B(n);
    for (size_t i = 0; i < n; ++i) {
      W[i] = static_cast<uint8_t>(byte(rng));
      B[i] = static_cast<uint8_t>(small(rng) == 0 ? 255 : byte(rng) / 4);
      switch (small(rng)) {  // ties (2L = W + B, L = L̄), saturation, random
        case 0: L[i] = static_cast<uint8_t>((W[i] + B[i]) / 2); Lb[i] = L[i]; break;
        case 1: L[i] = 255; Lb[i] = 255; break;
        default: L[i] = static_cast<uint8_t>(byte(rng)); Lb[i] = static_cast<uint8_t>(byte(rng));
      }
    }
    for (const SimdLevel& level : kLevels)
    for (bool black : {false, true})
      for (uint32_t pos : {0u, 7u}) {
        const Level guard(level);
        SCOPED_TRACE(level.name);
        std::vector<uint8_t> w1(n, 0x5A), m1(n, 200), w2 = w1, m2 = m1;
        for (int pass = 0; pass < 2; ++pass) {  // first (store) then min / OR
          const bool first = pass == 0;
          fold_u8_synthetic(L.data(), W.data(), black ? B.data() : nullptr, n, pos, first, first,
                            w1.data(), m1.data());
          fold_u8_synthetic_scalar(L.data(), W.data(), black ? B.data() : nullptr, n, pos, first,
                                   first, w2.data(), m2.data());
          ASSERT_EQ(w1, w2);
          ASSERT_EQ(m1, m2);
          fold_u8_inverse(L.data(), Lb.data(), n, pos + 0, first, false, w1.data(), m1.data());
          fold_u8_inverse_scalar(L.data(), Lb.data(), n, pos + 0, first, false, w2.data(),
                                 m2.data());
          ASSERT_EQ(w1, w2);
          ASSERT_EQ(m1, m2);
        }
      }
    // The scalar rule itself: tie -> bit 0, margin 0; saturated |d| -> 255.
    std::vector<uint8_t> w(1), m(1);
    const uint8_t l = 200, wt = 100, b0 = 0;  // d = 400 - 100 = 300 -> 255
    fold_u8_synthetic_scalar(&l, &wt, &b0, 1, 3, true, true, w.data(), m.data());
    EXPECT_EQ(w[0], 8);
    EXPECT_EQ(m[0], 255);
    const uint8_t tie = 50;  // 2 * 50 = 100 = W + B
    fold_u8_synthetic_scalar(&tie, &wt, &b0, 1, 3, true, true, w.data(), m.data());
    EXPECT_EQ(w[0], 0);
    EXPECT_EQ(m[0], 0);
  }
}

TEST(Kernels, IntensitySimdEqualsScalar) {
  std::vector<uint8_t> src(300);
  for (size_t i = 0; i < src.size(); ++i) src[i] = static_cast<uint8_t>(i * 7);
  for (float inv_scale : {1.0f / 255.0f, 1.0f / 63.0f, 1.0f / 300.0f}) {
    std::vector<float> a(src.size()), b(src.size());
    intensity_u8(src.data(), src.size(), inv_scale, a.data());
    {
      ScalarOnly guard;
      intensity_u8(src.data(), src.size(), inv_scale, b.data());
    }
    for (size_t i = 0; i < src.size(); ++i) {
      ASSERT_EQ(std::memcmp(&a[i], &b[i], sizeof(float)), 0) << i;
      ASSERT_EQ(b[i], std::clamp(static_cast<float>(src[i]) * inv_scale, 0.0f, 1.0f));
    }
  }
}

// Frames of a layout: random patterns per pixel, with hard pixels mixed in.
struct Frames {
  std::vector<std::vector<uint8_t>> u8;
  std::vector<std::vector<uint16_t>> u16;
  std::vector<std::vector<float>> f32;
  std::vector<procam_image> views;
};

Frames random_frames(size_t count, uint32_t w, uint32_t h, procam_pixel_type type, uint32_t bits,
                     uint32_t seed) {
  Frames f;
  std::mt19937 rng(seed);
  const double top = type == PROCAM_PIXEL_F32 ? 1.0 : std::ldexp(1.0, static_cast<int>(bits)) - 1;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const size_t n = size_t{w} * h;
  std::vector<double> white(n), black(n);
  for (size_t i = 0; i < n; ++i) {
    black[i] = u(rng) * 0.2;
    white[i] = i % 17 == 0 ? 1.0 : black[i] + u(rng) * 0.8;  // some clipped whites
    if (i % 23 == 0) white[i] = black[i];                    // no contrast
  }
  for (size_t k = 0; k < count; ++k) {
    std::vector<double> v(n);
    for (size_t i = 0; i < n; ++i) {
      const double r = u(rng);
      v[i] = k == 0 ? white[i] : k == 1 ? black[i]
             : r < 0.1 ? 0.5 * (white[i] + black[i])  // near tie
             : r < 0.55 ? white[i] - u(rng) * 0.05 : black[i] + u(rng) * 0.05;
    }
    // Inner buffers keep their address when the outer vectors grow.
    if (type == PROCAM_PIXEL_U8) {
      auto& b = f.u8.emplace_back(n);
      for (size_t i = 0; i < n; ++i) b[i] = static_cast<uint8_t>(std::lround(v[i] * top));
      f.views.push_back(sdk::gray_view(b.data(), w, h, bits));
    } else if (type == PROCAM_PIXEL_U16) {
      auto& b = f.u16.emplace_back(n);
      for (size_t i = 0; i < n; ++i) b[i] = static_cast<uint16_t>(std::lround(v[i] * top));
      f.views.push_back(sdk::gray_view(b.data(), w, h, bits));
    } else {
      auto& b = f.f32.emplace_back(n);
      for (size_t i = 0; i < n; ++i) b[i] = static_cast<float>(v[i]);
      if (k == 3) b[5] = std::numeric_limits<float>::quiet_NaN();
      if (k == 4) b[6] = std::numeric_limits<float>::infinity();
      f.views.push_back(sdk::gray_view(b.data(), w, h));
    }
  }
  return f;
}

struct Decoded {
  MultiResult per_code, fused;
};

Decoded decode_ensemble(const std::vector<ProjectedCode>& codes, const MultiLayout& l, const Frames& f,
                    uint32_t w, uint32_t h, uint32_t max_weak) {
  Decoded r;
  MultiCodeDecoder a(l, codes, w, h, 2, max_weak);
  MultiCodeDecoder b(l, codes, w, h, 2, max_weak, MultiCodeDecoder::Output::vote);
  for (uint32_t i = 0; i < f.views.size(); ++i) {
    EXPECT_TRUE(a.add_frame(i, f.views[i]).ok());
    EXPECT_TRUE(b.add_frame(i, f.views[i]).ok());
  }
  r.per_code = a.finish(0.03, 0.1);
  VoteSpec spec;
  for (uint32_t k = 0; k < kEnsembleCodes; ++k) spec.round_code[k] = static_cast<int32_t>(k);
  r.fused = b.finish_vote(0.03, 0.1, spec);
  return r;
}

void expect_same_maps(const std::vector<float>& a, const std::vector<float>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) ASSERT_TRUE(same_float(a[i], b[i])) << i << " " << a[i] << " " << b[i];
}

// count_classes (the vote pass's pixel counts) at every level against a
// plain count written here: random maps with zeros and nonzeros, classes
// 0..9 (values past kConflict land in the last bin and are not flagged),
// lengths around the 64-pixel step and offsets off any alignment.
TEST(Kernels, CountClassesEqualsPlainCount) {
  std::mt19937 rng(29);
  std::uniform_int_distribution<int> byte(0, 255), cls_of(0, 9);
  for (const size_t n : {size_t{0}, size_t{1}, size_t{63}, size_t{64}, size_t{65}, size_t{1920}, size_t{4099}}) {
    std::vector<uint8_t> lit(n + 3), valid(n + 3), cls(n + 3);
    for (size_t i = 0; i < n + 3; ++i) {
      lit[i] = byte(rng) < 128 ? 0 : static_cast<uint8_t>(byte(rng) | 1);
      valid[i] = byte(rng) < 100 ? 0 : 255;
      cls[i] = static_cast<uint8_t>(cls_of(rng));
    }
    const size_t off = 3;  // unaligned start
    PixelCounts want;
    for (size_t i = off; i < off + n; ++i) {
      want.lit += lit[i] ? 1u : 0u;
      want.valid += valid[i] ? 1u : 0u;
      want.flagged += (cls[i] == kError || cls[i] == kConflict) ? 1u : 0u;
      want.cls[cls[i] < kTransportClassCount ? cls[i] : kTransportClassCount - 1] += 1u;
    }
    const auto check = [&](const char* level) {
      SCOPED_TRACE(std::string(level) + " n " + std::to_string(n));
      PixelCounts got;
      got.lit = 5;  // adds to what is there
      count_classes(lit.data() + off, valid.data() + off, cls.data() + off, n, got);
      EXPECT_EQ(got.lit, want.lit + 5);
      EXPECT_EQ(got.valid, want.valid);
      EXPECT_EQ(got.flagged, want.flagged);
      for (uint32_t k = 0; k < kTransportClassCount; ++k) EXPECT_EQ(got.cls[k], want.cls[k]) << "class " << k;
    };
    {
      ScalarOnly guard;
      check("scalar");
    }
    for (const SimdLevel& level : kLevels) {
      const Level guard(level);
      check(level.name);
    }
  }
}

// report_columns (the ensemble's reported column) at every level against
// its definition written here: valid bytes 0 / 1 / 255, confidences below,
// at and above 1 and NaN, refined columns on and off the quarter grid
// (ties 2x = k + 0.5 round to even), negative, huge (2x overflows), NaN and
// infinite; lengths around the 16-pixel step, an unaligned start.
TEST(Kernels, ReportColumnsEqualsDefinition) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const float specials[] = {nan, inf, -inf, std::numeric_limits<float>::max(), -0.0f, 0.25f, 0.75f, 1.25f, -2.75f};
  const float confs[] = {0.0f, 0.25f, 0.5f, 0.75f, 1.0f, 1.5f, nan};
  for (const size_t n : {size_t{0}, size_t{1}, size_t{15}, size_t{16}, size_t{17}, size_t{1920}, size_t{4099}}) {
    const size_t off = 1;
    std::vector<uint8_t> valid(n + off);
    std::vector<float> conf(n + off), refined(n + off), coord(n + off);
    for (size_t i = 0; i < n + off; ++i) {
      const float p = u(rng);
      valid[i] = p < 0.2f ? 0 : p < 0.3f ? 1 : 255;
      conf[i] = confs[static_cast<size_t>(u(rng) * 7.0f) % 7];
      const float q = u(rng);
      refined[i] = q < 0.1f ? specials[static_cast<size_t>(u(rng) * 9.0f) % 9]
                   : q < 0.6f ? std::round(4.0f * 1024.0f * u(rng)) / 4.0f
                              : 1024.0f * u(rng) - 10.0f;
      // the vote's value: near the refined column (within 0, 0.5, 1 or 1.5
      // columns, so the half-column clamp both holds and fires) or anywhere
      const float shifts[] = {-1.5f, -1.0f, -0.5f, 0.0f, 0.5f, 1.0f, 1.5f};
      coord[i] = u(rng) < 0.6f && std::isfinite(refined[i]) && std::abs(refined[i]) < 4096.0f
                     ? std::round(2.0f * refined[i]) / 2.0f + shifts[static_cast<size_t>(u(rng) * 7.0f) % 7]
                     : std::round(2.0f * 1024.0f * u(rng)) / 2.0f;
    }
    std::vector<float> want = coord;
    for (size_t i = off; i < off + n; ++i)
      if (valid[i] != 0 && conf[i] < 1.0f && std::isfinite(refined[i]))
        want[i] = std::clamp(0.5f * std::nearbyint(2.0f * refined[i]), coord[i] - 0.5f, coord[i] + 0.5f);
    const auto check = [&](const char* level) {
      SCOPED_TRACE(std::string(level) + " n " + std::to_string(n));
      std::vector<float> got = coord;
      report_columns(got.data() + off, valid.data() + off, conf.data() + off, refined.data() + off, n);
      for (size_t i = 0; i < got.size(); ++i)
        ASSERT_EQ(0, std::memcmp(&got[i], &want[i], sizeof(float))) << i << ": " << got[i] << " vs " << want[i];
    };
    {
      ScalarOnly guard;
      check("scalar");
    }
    for (const SimdLevel& level : kLevels) {
      const Level guard(level);
      check(level.name);
    }
  }
}

TEST(Kernels, EnsembleSimdEqualsScalarAndFusedVoteEqualsSeparate) {
  constexpr uint32_t kW = 83, kH = 9, kProj = 1024;  // odd width: SIMD tails
  std::vector<ProjectedCode> codes;
  for (const char* id : kCodeIds) codes.push_back(make_projected_code(id, kProj));
  for (const auto& [type, bits] : {std::pair{PROCAM_PIXEL_U8, 8u}, std::pair{PROCAM_PIXEL_U16, 12u},
                                   std::pair{PROCAM_PIXEL_U16, 16u}, std::pair{PROCAM_PIXEL_F32, 32u},
                                   std::pair{PROCAM_PIXEL_U8, 6u}})
    for (bool inverse : {false, true})
      for (uint32_t max_weak : {0u, 1u}) {
        SCOPED_TRACE(std::to_string(bits) + (inverse ? " inverse" : " white") + " weak " +
                     std::to_string(max_weak));
        const MultiLayout l = make_multi_layout(codes, inverse, true);
        const Frames f = random_frames(l.frames.size(), kW, kH, type, bits, 3);
        Decoded scalar;
        {
          ScalarOnly guard;
          scalar = decode_ensemble(codes, l, f, kW, kH, max_weak);
        }
        for (const SimdLevel& level : kLevels) {
        SCOPED_TRACE(level.name);
        Decoded simd;
        {
          const Level guard(level);
          simd = decode_ensemble(codes, l, f, kW, kH, max_weak);
        }
        for (size_t c = 0; c < codes.size(); ++c) {
          expect_same_maps(simd.per_code.codes[c].coord, scalar.per_code.codes[c].coord);
          expect_same_maps(simd.per_code.codes[c].confidence, scalar.per_code.codes[c].confidence);
          ASSERT_EQ(simd.per_code.codes[c].valid, scalar.per_code.codes[c].valid);
          ASSERT_EQ(simd.per_code.weak[c], scalar.per_code.weak[c]);
          ASSERT_EQ(simd.fused.weak[c], simd.per_code.weak[c]);
        }
        ASSERT_EQ(simd.per_code.lit, scalar.per_code.lit);
        expect_same_maps(simd.per_code.intensity, scalar.per_code.intensity);
        // Fused decode + vote == per-code maps + vote_pixels (float vote).
        const size_t n = size_t{kW} * kH;
        std::vector<float> coord(n), conf(n);
        std::vector<uint8_t> valid(n), cls(n);
        const float* maps[kEnsembleCodes];
        for (uint32_t k = 0; k < kEnsembleCodes; ++k) maps[k] = simd.per_code.codes[k].coord.data();
        vote_pixels(maps, simd.per_code.lit.data(), 0, n, 1.0f, coord.data(), valid.data(),
                    conf.data(), cls.data());
        for (const Decoded* r : {static_cast<const Decoded*>(&simd), static_cast<const Decoded*>(&scalar)}) {
          expect_same_maps(r->fused.vote.coord, coord);
          expect_same_maps(r->fused.vote.confidence, conf);
          ASSERT_EQ(r->fused.vote.valid, valid);
          ASSERT_EQ(r->fused.vote.cls, cls);
          ASSERT_EQ(r->fused.lit, simd.per_code.lit);
        }
        }
      }
}

TEST(Kernels, GrayRoundSimdEqualsScalar) {
  constexpr uint32_t kW = 141, kH = 7;  // 4 x 32 + 13: SIMD steps and tails
  const StripeCode cols = make_gray_code(1000), rows = make_gray_code(600);
  for (bool inverse : {true, false}) {
    const Layout layout = make_layout(cols, &rows, inverse);
    const Frames f = random_frames(layout.frames.size(), kW, kH, PROCAM_PIXEL_U8, 8, 9);
    auto run = [&] {
      BinaryRoundDecoder dec(layout, cols, &rows, kW, kH, 2, 1);
      for (uint32_t i = 0; i < f.views.size(); ++i) EXPECT_TRUE(dec.add_frame(i, f.views[i]).ok());
      return dec.finish(0.03, 0.1);
    };
    RoundResult b;
    {
      ScalarOnly guard;
      b = run();
    }
    for (const SimdLevel& level : kLevels) {
    SCOPED_TRACE(level.name);
    RoundResult a;
    {
      const Level guard(level);
      a = run();
    }
    expect_same_maps(a.cols.coord, b.cols.coord);
    expect_same_maps(a.cols.confidence, b.cols.confidence);
    expect_same_maps(a.rows.coord, b.rows.coord);
    ASSERT_EQ(a.cols.valid, b.cols.valid);
    ASSERT_TRUE(a.rows.valid.empty());
    ASSERT_EQ(a.cols_weak, b.cols_weak);
    expect_same_maps(a.intensity, b.intensity);
    }
  }
}

// The noise rule (per-pixel threshold from W + B, gathered from a table in
// the SIMD decode_base) and the uncertain-plane intervals: SIMD == scalar.
TEST(Kernels, GrayRoundNoiseRuleSimdEqualsScalar) {
  constexpr uint32_t kW = 141, kH = 17;  // 4 x 32 + 13: SIMD steps and tails; 3 noise sample rows
  const StripeCode cols = make_gray_code(1000), rows = make_gray_code(600);
  const Layout layout = make_layout(cols, &rows, true);
  const Frames f = random_frames(layout.frames.size(), kW, kH, PROCAM_PIXEL_U8, 8, 11);
  auto run = [&](double noise_k) {
    BinaryRoundDecoder dec(layout, cols, &rows, kW, kH, 2, 3);
    dec.set_uncertain_output(true);
    for (uint32_t i = 0; i < f.views.size(); ++i) EXPECT_TRUE(dec.add_frame(i, f.views[i]).ok());
    return dec.finish(0.03, 0.0, noise_k);
  };
  RoundResult b, off;
  {
    ScalarOnly guard;
    b = run(3.0);
    off = run(0.0);
  }
  ASSERT_TRUE(b.noise.measured);
  ASSERT_GT(b.noise.a + b.noise.b, 0.0);
  // The rule is active: it invalidates or degrades some pixels the margin > 0 rule keeps exact.
  size_t changed = 0;
  for (size_t i = 0; i < b.cols.uncertainty.size(); ++i)
    changed += !same_float(b.cols.uncertainty[i], off.cols.uncertainty[i]) ? 1u : 0u;
  ASSERT_GT(changed, 0u);
  for (const SimdLevel& level : kLevels) {
    SCOPED_TRACE(level.name);
    RoundResult a;
    {
      const Level guard(level);
      a = run(3.0);
    }
    expect_same_maps(a.cols.coord, b.cols.coord);
    expect_same_maps(a.cols.confidence, b.cols.confidence);
    expect_same_maps(a.cols.uncertainty, b.cols.uncertainty);
    expect_same_maps(a.rows.coord, b.rows.coord);
    ASSERT_EQ(a.cols.valid, b.cols.valid);
    ASSERT_EQ(a.cols_weak, b.cols_weak);
  }
}

TEST(Kernels, IntegerVoteEqualsFloatVote) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> col(0, 40), pick(0, 5);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const size_t n = 5000;
  std::vector<int32_t> keys[kEnsembleCodes];
  std::vector<float> cols[kEnsembleCodes];
  std::vector<uint8_t> lit(n);
  for (uint32_t k = 0; k < kEnsembleCodes; ++k) {
    keys[k].resize(n);
    cols[k].resize(n);
  }
  for (size_t i = 0; i < n; ++i) {
    lit[i] = pick(rng) == 0 ? 0 : 255;
    const int base = col(rng);
    for (uint32_t k = 0; k < kEnsembleCodes; ++k) {
      const int r = pick(rng);
      const int key = r == 0 ? -1 : r < 3 ? 2 * base + pick(rng) - 2 : 2 * col(rng) + (r == 5);
      keys[k][i] = key;
      cols[k][i] = key < 0 ? nan : 0.5f * static_cast<float>(key);
    }
  }
  for (float agree : {0.0f, 0.5f, 1.0f, 1.7f, 3.0f}) {
    std::vector<float> c1(n), c2(n), f1(n), f2(n);
    std::vector<uint8_t> v1(n), v2(n), k1(n), k2(n);
    const float* maps[kEnsembleCodes] = {cols[0].data(), cols[1].data(), cols[2].data(), cols[3].data()};
    const int32_t* kk[kEnsembleCodes] = {keys[0].data(), keys[1].data(), keys[2].data(), keys[3].data()};
    vote_pixels(maps, lit.data(), 0, n, agree, c1.data(), v1.data(), f1.data(), k1.data());
    for (int mode : {0, 1, 2}) {  // widest SIMD, AVX2, scalar
      set_avx512_enabled(mode == 0);
      set_simd_enabled(mode != 2);
      vote_keys(kk, lit.data(), n, agree_key_threshold(agree), c2.data(), v2.data(), f2.data(),
                k2.data());
      set_simd_enabled(true);
      set_avx512_enabled(true);
      expect_same_maps(c1, c2);
      expect_same_maps(f1, f2);
      ASSERT_EQ(v1, v2);
      ASSERT_EQ(k1, k2);
    }
  }
}

}  // namespace
}  // namespace procam::sl
