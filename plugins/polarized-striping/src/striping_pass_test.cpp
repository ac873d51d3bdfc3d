// SPDX-License-Identifier: MIT
// The one-pass kernels of striping_pass.hpp against the general
// double-precision pass (StripingPass::reference, the code they replace), on
// random and adversarial U8 scans: zeros, 255s (clipped), exact ties of
// far-apart stripes, adjacent-stripe edges, margins hit exactly, frames that
// are all equal. Image widths not a multiple of 8 and two threads exercise
// the kernels' heads, tails and band starts. Claims (striping_pass.hpp):
//  - the decisions are the same: valid count, and NaN exactly where the
//    reference has NaN, in every map;
//  - DOP p, image, background-derived B^ (unpolarised) and the stripe index of
//    non-edge pixels are identical; every value within 1e-5 relative (or 1e-5
//    absolute below 1) of the reference; report means within 1e-5;
//  - the AVX2 kernel and the scalar twin give bit-identical maps;
//  - the packed passes' composite is U8 with the reference's values, and the
//    default "core" maps are the "all" maps' bits (the output contract).
#include "striping_pass.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "estimate.hpp"
#include "media_model.hpp"
#include "params.hpp"
#include "procam/plugin_sdk.hpp"

namespace procam::polarized_striping {
namespace {

constexpr uint32_t kW = 203, kH = 9, kPW = 160;

enum class Scene { uniform_random, stripes, low_ties, constant };

// Frames of stripe k (best or worst analyser) for a scene; deterministic.
std::vector<uint8_t> frame(Scene scene, uint32_t stripes, uint32_t k, bool worst, uint32_t seed) {
  std::mt19937 rng(seed * 7919u + k * 2u + (worst ? 1u : 0u));
  std::vector<uint8_t> f(size_t{kW} * kH);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      int v = 0;
      switch (scene) {
        case Scene::uniform_random: v = int(rng() % 256); break;
        case Scene::constant: v = y == 0 ? 0 : (y == 1 ? 255 : 40); break;
        case Scene::low_ties: v = int(rng() % 4) * 3; break;  // few levels: exact ties everywhere
        case Scene::stripes: {
          // Stripe k lights columns [k w, (k + 1) w) with w = kW / stripes;
          // rows: 0 black, 1 clipped, 2 far-apart tie (stripes k and k + K/2
          // equally bright), 3 edge (two adjacent stripes), others textured.
          const uint32_t sw = kW / stripes, own = std::min(x / sw, stripes - 1);
          const int haze = worst ? 40 : 12;
          const int noise = int(rng() % 7) - 3;
          if (y == 0) v = 0;
          else if (y == 1) v = k == own ? 255 : 250 + int(rng() % 6);
          else if (y == 2) v = haze + ((k == own || k == (own + stripes / 2) % stripes) ? 90 : 0);
          else if (y == 3) v = haze + (k == own ? 80 : (k == own + 1 ? 60 + int(x % 30) : 0)) + noise;
          else v = haze + (k == own ? 30 + int((x * 13 + y * 7) % 150) : 0) + noise;
          break;
        }
      }
      f[size_t{y} * kW + x] = static_cast<uint8_t>(std::clamp(v, 0, 255));
    }
  return f;
}

struct Case {
  Scene scene;
  bool polarised;
  double p;  // < 0: estimated
  double noise;
  uint32_t stripes;
};

// maps: the `maps` param ("all": every per-pixel map, as the reference
// pass is compared on; "core": the default contract).
Maps run(const Case& c, StripingPass pass, uint32_t seed, const char* maps = "all", bool want_col = false) {
  Config cfg;
  nlohmann::json params = {{"stripes", c.stripes}, {"noise", c.noise}, {"maps", maps}};
  if (c.p >= 0) params["p"] = c.p;
  const sdk::Error e = parse_config(c.polarised ? "polarized-striping" : "striping", params, kPW, cfg);
  EXPECT_TRUE(e.ok()) << e.message;
  cfg.threads = 2;
  const Levels lv = levels_for(cfg, 255);
  // Even seeds: the stacks keep the compact DOP sample at the last frame
  // (the session's way); odd seeds: the DOP reads the full stacks.
  const uint32_t expected = seed % 2 == 0 ? c.stripes : 0;
  StripeStack best(kW, kH, true, expected), worst(kW, kH, true, expected);
  for (uint32_t k = 0; k < c.stripes; ++k) {
    const auto fb = frame(c.scene, c.stripes, k, false, seed), fw = frame(c.scene, c.stripes, k, true, seed);
    best.add(sdk::gray_view(fb.data(), kW, kH), static_cast<uint16_t>(k), 2);
    if (c.polarised) worst.add(sdk::gray_view(fw.data(), kW, kH), static_cast<uint16_t>(k), 2);
  }
  EXPECT_EQ(best.sample_current(), expected > 0);
  return estimate_striping(best, c.polarised ? &worst : nullptr, cfg, lv, kPW, pass, want_col);
}

// The packed passes' U8 composite holds the same values as the reference's F32 one.
void expect_same_image(const std::vector<uint8_t>& u8, const std::vector<float>& ref, const std::string& label) {
  ASSERT_EQ(u8.size(), ref.size()) << label;
  size_t bad = 0;
  for (size_t i = 0; i < ref.size(); ++i) bad += float(u8[i]) != ref[i];
  EXPECT_EQ(bad, 0u) << label << ": composite pixels that differ from the reference";
}

void expect_same_nan_and_close(const std::vector<float>& got, const std::vector<float>& ref, const char* what,
                               const std::string& label) {
  ASSERT_EQ(got.size(), ref.size()) << what;
  size_t bad = 0;
  for (size_t i = 0; i < ref.size() && bad < 5; ++i) {
    const bool ok = std::isnan(ref[i]) ? std::isnan(got[i])
                                       : std::abs(double(got[i]) - double(ref[i])) <= 1e-5 * std::max(1.0, std::abs(double(ref[i])));
    if (!ok) {
      ++bad;
      ADD_FAILURE() << label << " " << what << " pixel " << i << ": got " << got[i] << ", reference " << ref[i];
    }
  }
}

void expect_bit_identical(const std::vector<float>& a, const std::vector<float>& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  if (a.empty()) return;
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0) << what;
}

TEST(StripingPass, AgreesWithTheReferencePass) {
  const Case cases[] = {
      {Scene::stripes, true, -1, 0.004, 16},         {Scene::stripes, true, 0.6, 0.004, 16},
      {Scene::stripes, true, 0.01, 0.004, 16},       // below p_min: not separated
      {Scene::stripes, false, -1, 0.004, 16},        {Scene::stripes, true, -1, 0.0, 16},  // margin 0
      {Scene::uniform_random, true, -1, 0.004, 16},  {Scene::uniform_random, false, -1, 0.01, 64},
      {Scene::low_ties, true, 0.5, 0.001, 16},       {Scene::low_ties, false, -1, 0.0, 8},
      {Scene::constant, true, -1, 0.004, 16},        {Scene::stripes, true, -1, 0.004, 3},
      // margin 0 on all-equal frames: t1 - bg == margin exactly, top two adjacent (0, 1)
      {Scene::constant, false, -1, 0.0, 16},         {Scene::constant, true, 0.5, 0.0, 16},
  };
  for (const Case& c : cases) {
    for (uint32_t seed = 1; seed <= 2; ++seed) {
      const std::string label = "scene " + std::to_string(int(c.scene)) + (c.polarised ? " polarised" : "") +
                                " p " + std::to_string(c.p) + " noise " + std::to_string(c.noise) + " K " +
                                std::to_string(c.stripes) + " seed " + std::to_string(seed);
      const Maps ref = run(c, StripingPass::reference, seed);
      const Maps fast = run(c, StripingPass::scalar, seed);
      EXPECT_EQ(fast.valid, ref.valid) << label;
      EXPECT_EQ(fast.p, ref.p) << label;  // identical DOP
      EXPECT_TRUE(fast.image.empty()) << label << ": a packed scan's composite is U8";
      expect_same_image(fast.image_u8, ref.image, label);
      expect_same_nan_and_close(fast.enhanced, ref.enhanced, "enhanced", label);
      expect_same_nan_and_close(fast.backscatter, ref.backscatter, "backscatter", label);
      expect_same_nan_and_close(fast.stripe, ref.stripe, "stripe", label);
      expect_same_nan_and_close(fast.col, ref.col, "col", label);
      expect_same_nan_and_close(fast.cqm, ref.cqm, "cqm", label);
      expect_same_nan_and_close(fast.weight, ref.weight, "weight", label);
      if (c.polarised) expect_same_nan_and_close(fast.gqm, ref.gqm, "gqm", label);
      if (!c.polarised) expect_bit_identical(fast.backscatter, ref.backscatter, "backscatter (= background)");
      for (const char* k : {"cqm_mean", "gqm_mean", "snr_weight_mean", "cqm_w_mean", "gqm_w_mean"}) {
        const auto& a = fast.quality[k];
        const auto& b = ref.quality[k];
        ASSERT_EQ(a.is_null(), b.is_null()) << label << " " << k;
        if (!a.is_null()) {
          EXPECT_NEAR(a.get<double>(), b.get<double>(), 1e-5) << label << " " << k;
        }
      }
      EXPECT_EQ(fast.quality["image"], ref.quality["image"]) << label;  // integer sums: exact
      EXPECT_NEAR(fast.quality["enhanced"]["mean"].get<double>(), ref.quality["enhanced"]["mean"].get<double>(),
                  1e-5 * std::max(1.0, ref.quality["enhanced"]["mean"].get<double>()))
          << label;
      if (!pass_kernel_available(PassKernel::avx2)) continue;
      const Maps vec = run(c, StripingPass::avx2, seed);
      EXPECT_EQ(vec.valid, fast.valid) << label;
      EXPECT_EQ(vec.image_u8, fast.image_u8) << label;
      for (auto mp : {&Maps::image, &Maps::enhanced, &Maps::backscatter, &Maps::stripe, &Maps::col, &Maps::cqm,
                      &Maps::weight, &Maps::gqm})
        expect_bit_identical(vec.*mp, fast.*mp, label.c_str());
    }
  }
}

// The output contract (param maps): "core" leaves out the quality maps and
// the column map, and every map it keeps is the same bit for bit as with
// "all", on both kernels; the report (quality sums, valid count, p) does not
// change. With want_col (a calibrated rig triangulates) the column map is
// made under "core" too, again the same bits.
TEST(StripingPass, CoreMapsAreTheAllMapsBitForBit) {
  const Case cases[] = {
      {Scene::stripes, true, -1, 0.004, 16},  {Scene::stripes, false, -1, 0.004, 16},
      {Scene::stripes, true, 0.01, 0.004, 16}, {Scene::uniform_random, true, -1, 0.004, 16},
      {Scene::low_ties, false, -1, 0.0, 8},   {Scene::stripes, true, -1, 0.004, 3},
  };
  for (const Case& c : cases)
    for (StripingPass pass : {StripingPass::scalar, StripingPass::avx2, StripingPass::reference}) {
      if (pass == StripingPass::avx2 && !pass_kernel_available(PassKernel::avx2)) continue;
      const std::string label = "scene " + std::to_string(int(c.scene)) + (c.polarised ? " polarised" : "") +
                                " K " + std::to_string(c.stripes) + " pass " + std::to_string(int(pass));
      const Maps all = run(c, pass, 2, "all");
      const Maps core = run(c, pass, 2, "core");
      const Maps core_col = run(c, pass, 2, "core", true);
      EXPECT_EQ(core.valid, all.valid) << label;
      EXPECT_EQ(core.p, all.p) << label;
      EXPECT_EQ(core.quality, all.quality) << label << ": the report's means do not depend on the maps";
      EXPECT_EQ(core.image_u8, all.image_u8) << label;
      for (auto mp : {&Maps::image, &Maps::enhanced, &Maps::backscatter, &Maps::stripe})
        expect_bit_identical(core.*mp, all.*mp, label.c_str());
      for (auto mp : {&Maps::cqm, &Maps::weight, &Maps::gqm, &Maps::col})
        EXPECT_TRUE((core.*mp).empty()) << label << ": a map \"core\" leaves out";
      EXPECT_EQ(all.cqm.empty(), false) << label;
      EXPECT_EQ(all.gqm.empty(), !c.polarised) << label;
      ASSERT_FALSE(core_col.col.empty()) << label;
      expect_bit_identical(core_col.col, all.col, label.c_str());
      EXPECT_EQ(core_col.quality, all.quality) << label;
    }
}

// The scenes above must actually reach the hard cases they claim to.
TEST(StripingPass, ScenesCoverEdgesTiesAndClipping) {
  const Maps m = run({Scene::stripes, true, -1, 0.004, 16}, StripingPass::scalar, 1);
  size_t edges = 0;
  for (uint32_t x = 0; x < kW; ++x) {
    EXPECT_TRUE(std::isnan(m.stripe[x])) << "row 0 (black) has no stripe, x " << x;
    EXPECT_TRUE(std::isnan(m.backscatter[kW + x])) << "row 1 (clipped) is invalid, x " << x;
    EXPECT_TRUE(std::isnan(m.stripe[2 * kW + x])) << "row 2 (far-apart tie) is ambiguous, x " << x;
    const float s = m.stripe[3 * kW + x];
    if (std::isfinite(s) && s != std::floor(s)) ++edges;
  }
  EXPECT_GT(edges, kW / 2) << "row 3 straddles adjacent stripes: fractional indices";
}

// packed_dop (parallel sample, histogram selection) against estimate_dop on
// the float backgrounds of the same strided pixels, as the reference pass
// computes them: the same value bit for bit, whatever the thread count. Large
// enough for a pixel stride of 2; integer backgrounds give many exact ties;
// some pixels are clipped (top2 = 255) and some too dark for min_sum.
TEST(StripingPass, PackedDopEqualsEstimateDopOnTheSameSample) {
  constexpr size_t n = 700 * 800;  // stride n / 262144 = 2
  constexpr uint32_t kFrames = 16;
  std::mt19937 rng(11);
  std::vector<uint16_t> k1[2], k2[2], sum[2];
  for (int s = 0; s < 2; ++s) k1[s].resize(n), k2[s].resize(n), sum[s].resize(n);
  for (size_t i = 0; i < n; ++i)
    for (int s = 0; s < 2; ++s) {
      const auto t1 = uint32_t(rng() % 256), t2 = rng() % 50 == 0 ? t1 : uint32_t(rng() % (t1 + 1));
      const auto others = uint32_t(s == 0 ? rng() % (t2 * (kFrames - 2) + 1) : (rng() % 4 == 0 ? 0 : t2 * (kFrames - 2)));
      k1[s][i] = static_cast<uint16_t>((t1 << 8) | (rng() % 256));
      k2[s][i] = static_cast<uint16_t>((t2 << 8) | (rng() % 256));
      sum[s][i] = static_cast<uint16_t>(t1 + t2 + others);
    }
  const PackedView best{k1[0].data(), k2[0].data(), sum[0].data(), kFrames};
  const PackedView worst{k1[1].data(), k2[1].data(), sum[1].data(), kFrames};
  const double saturation = 250;
  // Stride 2 (the full stacks' sample) and stride 1 (a compact sample: the
  // AVX2 key kernel where the CPU has it, its scalar tail) over the first
  // 200003 entries (estimate_dop itself subsamples above 262144 values).
  for (size_t stride : {size_t{2}, size_t{1}}) {
  const size_t count = stride == 2 ? n / 2 : 200003;
  std::vector<float> sb, sw;
  for (size_t i = 0; i < count * stride; i += stride) {
    const int t2b = k2[0][i] >> 8, t2w = k2[1][i] >> 8;
    if (!(t2b < saturation && t2w < saturation)) continue;
    sb.push_back(float(int(sum[0][i]) - (k1[0][i] >> 8) - t2b) / float(kFrames - 2));
    sw.push_back(float(int(sum[1][i]) - (k1[1][i] >> 8) - t2w) / float(kFrames - 2));
  }
  for (double min_sum : {0.0, 20.0, 1e9})
    for (double pct : {0.0, 0.37, 0.9, 1.0}) {
      const double ref = estimate_dop(sb, sw, min_sum, pct);
      if (min_sum > 1e6) {
        EXPECT_TRUE(std::isnan(ref)) << "no pixel that bright: too few samples";
      }
      for (uint32_t threads : {1u, 2u, 3u}) {
        const double got = packed_dop(best, worst, count, stride, saturation, min_sum, pct, threads);
        if (std::isnan(ref)) {
          EXPECT_TRUE(std::isnan(got)) << min_sum << " " << pct << " " << threads;
        } else {
          EXPECT_EQ(got, ref) << "stride " << stride << " min_sum " << min_sum << " percentile " << pct << " threads "
                              << threads;
        }
      }
    }
  }
}

// The DOP quantile by pivots (DopSelect::best) against the radix selection
// and estimate_dop on samples shaped like real scans, stride 1 (the AVX2
// pivot pass where the CPU has it) and 2 (scalar): a hazy scene (every ratio
// within ~0.01: one radix bucket holds nearly all keys), haze with objects
// (a fifth of the pixels at lower ratios), every ratio equal (the pivots
// coincide), and a trap whose subsample entries (every 97th: 200003 / 2048)
// alone are off the distribution, so the pivots miss the ranks and the radix
// selection must answer (by_pivots false). Some pixels are clipped. The
// value must be the same bit for bit on both paths, for 1-3 threads.
TEST(StripingPass, PackedDopByPivotsOnClusteredAndAdversarialSamples) {
  constexpr uint32_t kFrames = 64;
  enum Shape : int { haze, haze_objects, equal, trap };
  for (size_t stride : {size_t{1}, size_t{2}})
    for (int c = haze; c <= trap; ++c) {
      const size_t count = 200003, n = count * stride;
      std::mt19937 gen(static_cast<uint32_t>(7 + c));
      const auto rng = [&gen] { return static_cast<uint32_t>(gen()); };
      std::vector<uint16_t> k1[2], k2[2], sum[2];
      for (int a = 0; a < 2; ++a) k1[a].assign(n, 0), k2[a].assign(n, 0), sum[a].assign(n, 0);
      for (size_t i = 0; i < n; ++i) {
        uint32_t nb = 900 + rng() % 26, nw = 3875 + rng() % 26;  // sums of the K - 2 background frames
        if (c == haze_objects && rng() % 5 == 0) nb = 2000 + rng() % 500, nw = nb + rng() % 300;
        if (c == equal) nb = 900, nw = 3875;
        if (c == trap && (i / stride) % 97 == 0) nb = 100, nw = 3900;
        const uint32_t top = rng() % 100 == 0 ? 255 : 20 + rng() % 60;  // 255: clipped, not in the sample
        for (int a = 0; a < 2; ++a) {
          k1[a][i] = static_cast<uint16_t>((top << 8) | (rng() % 256));
          k2[a][i] = static_cast<uint16_t>((top << 8) | (rng() % 256));
          sum[a][i] = static_cast<uint16_t>(2 * top + (a == 0 ? nb : nw));
        }
      }
      const PackedView best{k1[0].data(), k2[0].data(), sum[0].data(), kFrames};
      const PackedView worst{k1[1].data(), k2[1].data(), sum[1].data(), kFrames};
      std::vector<float> sb, sw;
      for (size_t i = 0; i < n; i += stride) {
        if ((k2[0][i] >> 8) >= 250 || (k2[1][i] >> 8) >= 250) continue;
        sb.push_back(float(int(sum[0][i]) - 2 * (k1[0][i] >> 8)) / float(kFrames - 2));
        sw.push_back(float(int(sum[1][i]) - 2 * (k1[1][i] >> 8)) / float(kFrames - 2));
      }
      for (double pct : {0.0, 0.5, 0.9, 0.99, 1.0}) {
        const double ref = estimate_dop(sb, sw, 20.0, pct);
        ASSERT_FALSE(std::isnan(ref));
        const double radix = packed_dop(best, worst, count, stride, 250, 20.0, pct, 2, 16, DopSelect::radix);
        EXPECT_EQ(radix, ref) << c << " " << pct;
        for (uint32_t threads : {1u, 2u, 3u}) {
          bool by_pivots = false;
          const double got = packed_dop(best, worst, count, stride, 250, 20.0, pct, threads, 16, DopSelect::best, &by_pivots);
          EXPECT_EQ(got, ref) << "case " << c << " stride " << stride << " percentile " << pct << " threads " << threads;
          // The trap's subsample sits at the top of the distribution: the
          // pivots bracket only ranks above ~99 %.
          if (c == trap && pct > 0.0 && pct < 0.95) {
            EXPECT_FALSE(by_pivots) << "the trap's pivots cannot hold rank " << pct;
          } else if (c != trap) {
            EXPECT_TRUE(by_pivots) << "case " << c << " percentile " << pct << ": pivots missed";
          }
        }
      }
    }
}

// The compact DOP sample a packed stack keeps at its expected last frame is
// its final state at pixels j * dop_sample_stride(n) (an odd width: sample
// pixels fall at different columns row by row; two threads: two bands), and
// it stops being current once a frame beyond the plan arrives.
TEST(StripingPass, StackKeepsTheDopSampleAtTheLastFrame) {
  constexpr uint32_t w = 701, h = 800, frames = 3;  // n / 262144 = 2
  const size_t n = size_t{w} * h, stride = dop_sample_stride(n);
  ASSERT_EQ(stride, 2u);
  std::mt19937 rng(3);
  std::vector<uint8_t> f(n);
  StripeStack st(w, h, true, frames);
  for (uint32_t k = 0; k <= frames; ++k) {
    for (auto& v : f) v = static_cast<uint8_t>(rng() % 256);
    st.add(sdk::gray_view(f.data(), w, h), static_cast<uint16_t>(k), 2);
    EXPECT_EQ(st.sample_current(), k + 1 == frames) << "after frame " << k;
    if (k + 1 != frames) continue;
    ASSERT_EQ(st.sample_size(), (n + stride - 1) / stride);
    size_t bad = 0;
    for (size_t j = 0; j < st.sample_size(); ++j)
      bad += st.sample_key1()[j] != st.key1()[j * stride] || st.sample_key2()[j] != st.key2()[j * stride] ||
             st.sample_sum16()[j] != st.sum16()[j * stride];
    EXPECT_EQ(bad, 0u) << "sample entries that differ from the stack";
  }
}

// The AVX2 pass divides the integer backgrounds and rises by K - 2 with a
// multiply and an FMA correction instead of the divider: the same float,
// bit for bit, as the division for every divisor a packed scan can have
// (K = 3..256) and every integer it divides (|n| <= 2^17; the 16-bit sums
// and D t1 - N stay within 65535 in magnitude).
TEST(StripingPass, MultiplyAddQuotientsAreTheDivision) {
  if (!pass_kernel_available(PassKernel::avx2)) GTEST_SKIP() << "no AVX2 + FMA on this CPU";
  for (int32_t d = 1; d <= 254; ++d) EXPECT_EQ(exact_quotients_mismatches(d), 0u) << "d = " << d;
}

// The report's quality means are taken on every quality_row_stride-th row
// (estimate.hpp); here at 1920x1200 (stride 8, as the bench's scan) on two
// polarised scenes, against the means of the same measures over every valid
// pixel, computed here from the "all" maps: a texture that varies along x
// and y (with a period in y that is not a multiple of 8) and a smooth
// object (a bright disc, falling off to the edges) over noise. Tolerance:
// 0.005 absolute on the [0, 1] means, 0.5 % relative on the enhanced mean
// (the differences measured were >= 10x smaller; docs: "Quality
// measures"). Rows below 512k pixels keep stride 1 (every test above).
TEST(StripingPass, SampledQualityMeansMatchTheFullImage) {
  constexpr uint32_t w = 1920, h = 1200, K = 16, pw = 1920;
  ASSERT_EQ(quality_row_stride(w, h), 8u);
  ASSERT_EQ(quality_row_stride(kW, kH), 1u);
  ASSERT_EQ(quality_row_stride(700, 748), 1u);
  for (int scene = 0; scene < 2; ++scene) {
    Config cfg;
    ASSERT_TRUE(parse_config("polarized-striping", {{"stripes", K}, {"maps", "all"}}, pw, cfg).ok());
    cfg.threads = 2;
    const Levels lv = levels_for(cfg, 255);
    StripeStack best(w, h, true, K), worst(w, h, true, K);
    std::mt19937 rng(21u + unsigned(scene));
    std::vector<uint8_t> f(size_t{w} * h);
    for (uint32_t k = 0; k < K; ++k)
      for (int a = 0; a < 2; ++a) {
        for (uint32_t y = 0; y < h; ++y)
          for (uint32_t x = 0; x < w; ++x) {
            const bool lit = x / (w / K) == k && x % (w / K) >= 20 && x % (w / K) < 100;
            double sig = 0;
            if (scene == 0) {
              sig = 20 + (x * 13 + y * 7) % 150;
            } else {
              const double r2 = (double(x) - 960) * (double(x) - 960) + (double(y) - 600) * (double(y) - 600);
              sig = 10 + 150 * std::exp(-r2 / (2 * 400.0 * 400.0));
            }
            const double haze = a == 0 ? 12 : 45;
            const double v = haze + (lit ? sig / 2 : 0) + double(rng() % 7) - 3;
            f[size_t{y} * w + x] = static_cast<uint8_t>(std::clamp(v, 0.0, 255.0));
          }
        (a == 0 ? best : worst).add(sdk::gray_view(f.data(), w, h), static_cast<uint16_t>(k), 2);
      }
    const Maps m = estimate_striping(best, &worst, cfg, lv, pw);
    ASSERT_GT(m.valid, size_t{w} * h / 4) << "scene " << scene;
    double c = 0, g = 0, wt = 0, cw = 0, gw = 0, e = 0;
    size_t n = 0;
    for (size_t i = 0; i < m.enhanced.size(); ++i) {
      if (std::isnan(m.stripe[i])) continue;
      const double ci = m.cqm[i], gi = m.gqm[i], wi = m.weight[i];
      c += ci, g += gi, wt += wi, cw += ci * wi, gw += gi * wi, e += double(m.enhanced[i]), ++n;
    }
    ASSERT_EQ(n, m.valid);
    const auto& q = m.quality;
    EXPECT_EQ(q["means_row_stride"].get<uint32_t>(), 8u);
    EXPECT_LT(q["means_pixels"].get<size_t>(), n / 6) << "a sample, not every pixel";
    EXPECT_GT(q["means_pixels"].get<size_t>(), n / 10);
    const std::string label = "scene " + std::to_string(scene);
    EXPECT_NEAR(q["cqm_mean"].get<double>(), c / double(n), 0.005) << label;
    EXPECT_NEAR(q["gqm_mean"].get<double>(), g / double(n), 0.005) << label;
    EXPECT_NEAR(q["snr_weight_mean"].get<double>(), wt / double(n), 0.005) << label;
    EXPECT_NEAR(q["cqm_w_mean"].get<double>(), cw / double(n), 0.005) << label;
    EXPECT_NEAR(q["gqm_w_mean"].get<double>(), gw / double(n), 0.005) << label;
    EXPECT_NEAR(q["enhanced"]["mean"].get<double>(), e / double(n), 0.005 * e / double(n)) << label;
    std::printf("%s: sampled - full: cqm %.2e gqm %.2e w %.2e cqm_w %.2e gqm_w %.2e enhanced %.2e rel (p %.3f)\n",
                label.c_str(), q["cqm_mean"].get<double>() - c / double(n), q["gqm_mean"].get<double>() - g / double(n),
                q["snr_weight_mean"].get<double>() - wt / double(n), q["cqm_w_mean"].get<double>() - cw / double(n),
                q["gqm_w_mean"].get<double>() - gw / double(n), q["enhanced"]["mean"].get<double>() / (e / double(n)) - 1,
                m.p);
  }
}

}  // namespace
}  // namespace procam::polarized_striping
