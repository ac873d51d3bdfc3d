// SPDX-License-Identifier: MIT
// Thesis ch. 2 claims as tests against the simulated co-located rig's ground
// truth (issue 12 "Report and claims"): sweeps captured through the sim
// projector and camera (per-frame focus, shot/read noise, inter-reflection and
// sub-surface scattering) at 320x200 camera pixels - the same field of view
// as the 1280x800 rig, each pixel a point sample of the scene, so the claims
// do not depend on resolution while the test stays fast.
//
// Calibration as on a real rig, except that the plane's per-pixel depth comes
// from the sim's ground truth (on the zero-baseline rig structured light
// cannot triangulate; a real user measures the plane on a normal rig).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>

#include "calibration.hpp"
#include "focus_measures.hpp"
#include "sim_scan.hpp"

namespace procam::defocus {
namespace {

constexpr uint32_t kW = 320, kH = 200;
// The invariance claims (D5) need the camera to sample the projected pattern
// finer than its 3rd harmonic (8 projector px): the sim computes global light
// from camera-pixel samples of the irradiance, which alias at 320 px
// (1 camera px = 4.4 projector px) but not at 640 (2.2 px; 3.6 camera px per
// period of the harmonic).
constexpr uint32_t kW2 = 640, kH2 = 400;

const std::vector<double>& sweep6() {
  static const std::vector<double> f = focus_sweep_mm(600, 1200, 6);
  return f;
}
const std::vector<double> kSweep2 = {700, 950};  // two-focal defaults; single-focal uses the first (700 mm)

// One capture per (scene, sweep, noise) for the whole test binary.
const test::SimSweep& scan(const std::string& scene, bool two_focal, bool noiseless = false) {
  static std::map<std::string, test::SimSweep> cache;
  const std::string key = scene + (two_focal ? "/2" : "/6") + (noiseless ? "/clean" : "");
  auto it = cache.find(key);
  if (it == cache.end())
    it = cache
             .emplace(key, noiseless ? test::capture_sweep(scene, sweep6(), kW2, kH2, 16, true)
                                     : test::capture_sweep(scene, two_focal ? kSweep2 : sweep6(), kW, kH))
             .first;
  return it->second;
}

struct Tables {
  sdk::CalibrationTable multi, two, single;
};

// Tables from the inclined plane with the truth depth (Fig. 2.6).
const Tables& tables() {
  static const Tables t = [] {
    Tables out;
    const auto& s6 = scan("ch2-calibration-plane", false);
    const auto& s2 = scan("ch2-calibration-plane", true);
    const Validity rule;
    std::vector<float> cue;
    fbar_map(*s6.acc, rule, 2, cue);
    EXPECT_TRUE(make_table(kMultiFocal, cue, s6.depth_mm, sweep6(), 48, out.multi).ok());
    omega_map(*s2.acc, 0, 1, rule, 2, cue);
    EXPECT_TRUE(make_table(kTwoFocal, cue, s2.depth_mm, kSweep2, 48, out.two).ok());
    modulation_map(*s2.acc, 0, rule, 2, cue);
    EXPECT_TRUE(make_table(kSingleFocal, cue, s2.depth_mm, {kSweep2[0]}, 48, out.single).ok());
    // PROCAM_DEFOCUS_WRITE_TABLES=<dir>: write them as the rig's table files
    // (configs/rigs/tables/ holds the committed ones).
    if (const char* dir = std::getenv("PROCAM_DEFOCUS_WRITE_TABLES"))
      for (const sdk::CalibrationTable* tab : {&out.multi, &out.two, &out.single})
        test::write_table_file(dir, "sim-colocated", "ch2-calibration-plane",
                               "plugins/defocus/src/sim_claims_test.cpp at 320x200", *tab);
    return out;
  }();
  return t;
}

struct Depths {
  std::vector<float> multi, two, single;
};
Depths depths(const std::string& scene) {
  Depths d;
  const Validity rule;
  std::vector<float> cue;
  fbar_map(*scan(scene, false).acc, rule, 2, cue);
  depth_from_cue(tables().multi, cue, 2, d.multi);
  omega_map(*scan(scene, true).acc, 0, 1, rule, 2, cue);
  depth_from_cue(tables().two, cue, 2, d.two);
  modulation_map(*scan(scene, true).acc, 0, rule, 2, cue);
  depth_from_cue(tables().single, cue, 2, d.single);
  return d;
}

struct ErrorStats {
  double rel_rms = NAN;
  size_t valid = 0, total = 0;
};
// Relative RMS of depth against truth over pixels where keep(i).
template <class Keep>
ErrorStats rel_rms(const std::vector<float>& depth, const std::vector<float>& truth, Keep&& keep) {
  ErrorStats s;
  double sum = 0;
  for (size_t i = 0; i < depth.size(); ++i) {
    if (!keep(i)) continue;
    ++s.total;
    if (!std::isfinite(depth[i])) continue;
    const double r = (double(depth[i]) - double(truth[i])) / double(truth[i]);
    sum += r * r;
    ++s.valid;
  }
  if (s.valid > 0) s.rel_rms = std::sqrt(sum / double(s.valid));
  return s;
}

// The table files the sim-colocated rig config references are what this
// calibration makes (within 0.5 % of depth wherever both are defined).
TEST(SimClaims, CommittedTablesMatchAFreshCalibration) {
  for (const sdk::CalibrationTable* fresh : {&tables().multi, &tables().two, &tables().single}) {
    sdk::CalibrationTable committed;
    const sdk::Error e = test::read_table_file("sim-colocated", fresh->name, committed);
    ASSERT_TRUE(e.ok()) << e.message << ": run with PROCAM_DEFOCUS_WRITE_TABLES=configs/rigs/tables";
    EXPECT_GT(test::expect_tables_agree(committed, *fresh, 0.005), committed.samples.size() / 2) << fresh->name;
  }
}

TEST(SimClaims, CalibrationTablesFollowTheThinLens) {
  // Independent closed form: with a Gaussian blur of sigma = A fx |1/f - 1/z| / 4
  // E(f) peaks where 1/f = 1/z, i.e. at focus index (1/near - 1/z) / step in
  // a sweep uniform in 1/f (focus_sweep_mm). The sim blends blur levels, so
  // allow 1.5 % of depth.
  const auto& t = tables().multi;
  ASSERT_GE(t.samples.size(), 20u);
  const double step = (1 / 600.0 - 1 / 1200.0) / 5;
  for (const auto& [fbar, depth] : t.samples) {
    const double z = 1.0 / (1 / 600.0 - fbar * step);
    EXPECT_NEAR(depth, z, 0.015 * z) << "fbar " << fbar;
  }
  // The table covers the depths the sweep can measure: ~650-1090 mm.
  EXPECT_LT(t.samples.front().second, 690);
  EXPECT_GT(t.samples.back().second, 1040);
  EXPECT_GE(tables().two.samples.size(), 20u);
  EXPECT_GE(tables().single.samples.size(), 20u);
}

// Fig. 2.7 on one scene: multi-focal and two-focal within `max_rel_rms` on
// the object (`object(i)`), with at least `min_valid` of its pixels valid;
// the single-focal baseline at least 5x worse on `region(i)`.
template <class Object, class Region>
void check_depth_claim(const std::string& scene, double max_rel_rms, double min_valid, Object&& object,
                       Region&& region) {
  const auto& s = scan(scene, false);
  const Depths d = depths(scene);
  const ErrorStats multi = rel_rms(d.multi, s.depth_mm, object), two = rel_rms(d.two, s.depth_mm, object);
  std::printf("%s: multi-focal rel RMS %.3f %% (%zu/%zu valid), two-focal %.3f %% (%zu/%zu)\n", scene.c_str(),
              100 * multi.rel_rms, multi.valid, multi.total, 100 * two.rel_rms, two.valid, two.total);
  EXPECT_LT(multi.rel_rms, max_rel_rms);
  EXPECT_LT(two.rel_rms, max_rel_rms);
  EXPECT_GE(double(multi.valid), min_valid * double(multi.total));
  EXPECT_GE(double(two.valid), min_valid * double(two.total));
  const ErrorStats mr = rel_rms(d.multi, s.depth_mm, region), tr = rel_rms(d.two, s.depth_mm, region);
  const ErrorStats sr = rel_rms(d.single, s.depth_mm, region);
  std::printf("%s region: multi %.3f %%, two %.3f %%, single-focal %.3f %% (%zu/%zu valid)\n", scene.c_str(),
              100 * mr.rel_rms, 100 * tr.rel_rms, 100 * sr.rel_rms, sr.valid, sr.total);
  ASSERT_GT(sr.valid, sr.total / 2);
  EXPECT_GE(sr.rel_rms, 5 * mr.rel_rms);
  EXPECT_GE(sr.rel_rms, 5 * tr.rel_rms);
}

// Fig. 2.7: relative RMS < 1 % on the V-groove for the multi-focal (Eq. 2.9)
// and two-focal (Eq. 2.10) methods; the single-focal baseline errs at least
// 5x more in the concavity.
TEST(SimClaims, VGrooveDepthWithinOnePercentAndBaselineFiveTimesWorseInTheConcavity) {
  const auto& s = scan("ch2-v-groove", false);
  auto face = [&](size_t i) { return s.object[i] == 1 || s.object[i] == 2; };
  auto concavity = [&](size_t i) { return face(i) && s.depth_mm[i] > 860.f; };  // within ~23 mm of the edge
  check_depth_claim("ch2-v-groove", 0.01, 0.95, face, concavity);
}

// Fig. 2.7: < 5 % on the candle; the baseline errs >= 5x more on exposed wax.
TEST(SimClaims, CandleDepthWithinFivePercentAndBaselineFiveTimesWorseOnWax) {
  const auto& s = scan("ch2-candle", false);
  auto candle = [&](size_t i) { return s.object[i] >= 1 && s.object[i] <= 3; };
  auto wax = [&](size_t i) { return s.object[i] == 1; };
  check_depth_claim("ch2-candle", 0.05, 0.9, candle, wax);
}

// Mean E(3, f) over rows [r0, r1) of column u, per focus setting.
std::vector<double> column_e3(const test::SimSweep& s, uint32_t u, uint32_t r0, uint32_t r1) {
  std::vector<double> e(s.acc->focus_count(), 0.0);
  for (uint32_t f = 0; f < e.size(); ++f) {
    for (uint32_t v = r0; v < r1; ++v) e[f] += double(s.acc->e3(f)[size_t{v} * s.width + u]);
    e[f] /= double(r1 - r0);
  }
  return e;
}

// First column (scanning from the image centre to the left) whose truth depth
// at the centre row is below `depth_mm` on object `obj`.
uint32_t column_at_depth(const test::SimSweep& s, int32_t obj, float depth_mm) {
  const uint32_t v = s.height / 2;
  for (uint32_t u = s.width / 2; u-- > 0;) {
    const size_t i = size_t{v} * s.width + u;
    if (s.object[i] == obj && s.depth_mm[i] < depth_mm) return u;
  }
  return 0;
}

// §2.3.2, Fig. 2.4: G(3, f) = E_B(f) / E_A(f) (Eq. 2.8) at a V-groove point B
// near the edge, A the same point with the right face removed: varies < 5 %
// over the sweep while E_B varies > 25 %. A claim about light transport, so
// captured without camera noise (16-bit, no shot/read noise: far from focus
// E is a few DN and the Rayleigh bias of |noise| would dominate the ratio),
// averaged over 80 rows of one image column (one depth on the vertical faces).
TEST(SimClaims, InvarianceOfGlobalBlurOnTheVGroove) {
  const auto& b = scan("ch2-v-groove", false, true);
  const auto& a = scan("ch2-v-groove-single", false, true);
  // Left face at 810 mm (52 mm from the edge in x, receiving 20 % extra light
  // from the right face), between focus settings 2 (750 mm) and 3 (857 mm):
  // see the note on near-perfect focus in hw/sim/SCENES.md.
  const uint32_t u = column_at_depth(b, 1, 810.f);
  ASSERT_GT(u, 0u);
  const auto eb = column_e3(b, u, kH2 / 2 - 80, kH2 / 2 + 80), ea = column_e3(a, u, kH2 / 2 - 80, kH2 / 2 + 80);
  std::vector<double> g;
  for (size_t f = 0; f < eb.size(); ++f) g.push_back(eb[f] / ea[f]);
  std::printf("v-groove column %u (depth %.0f mm): G variation %.2f %%, E variation %.1f %%\n", u,
              double(b.depth_mm[size_t{kH2 / 2} * kW2 + u]), 100 * relative_variation(g), 100 * relative_variation(eb));
  EXPECT_LT(relative_variation(g), 0.05);
  EXPECT_GT(relative_variation(eb), 0.25);
  for (size_t f = 0; f < g.size(); ++f) std::printf("  f%zu: E_B %.2f E_A %.2f G %.4f\n", f, eb[f], ea[f], g[f]);
  // B does receive inter-reflected light: its mean is well above A's.
  const size_t centre = size_t{kH2 / 2} * kW2 + u;
  EXPECT_GT(b.acc->mean()[centre], 1.1f * a.acc->mean()[centre]);
}

// §2.3.2, Fig. 2.5: on the candle, B on the exposed wax and A on the paper in
// the same column (same depth): G varies < 7 %, E > 25 %.
TEST(SimClaims, InvarianceOfGlobalBlurOnTheCandle) {
  const auto& s = scan("ch2-candle", false, true);  // noiseless, as above
  const uint32_t u = kW2 / 2;
  // Rows at 900 px per 800 mm: wax |y| < 60 mm -> |v - cy| < 68; paper 61-120 mm -> 69-135.
  const uint32_t cy = kH2 / 2;
  const auto eb = column_e3(s, u, cy - 30, cy + 30);
  const auto ea = column_e3(s, u, cy + 85, cy + 125);
  ASSERT_EQ(s.object[size_t{cy} * kW2 + u], 1);
  ASSERT_EQ(s.object[size_t{cy + 100} * kW2 + u], 3);
  std::vector<double> g;
  for (size_t f = 0; f < eb.size(); ++f) g.push_back(eb[f] / ea[f]);
  std::printf("candle column %u: G variation %.2f %%, E variation %.1f %%\n", u, 100 * relative_variation(g),
              100 * relative_variation(eb));
  for (size_t f = 0; f < g.size(); ++f) std::printf("  f%zu: E_B %.2f E_A %.2f G %.4f\n", f, eb[f], ea[f], g[f]);
  EXPECT_LT(relative_variation(g), 0.07);
  EXPECT_GT(relative_variation(eb), 0.25);
}

// Fig. 2.13, the failure case: a distant mirror sends the board its own
// pattern defocused over ~1750 mm. The invariance does not hold for that
// light (its blur changes with focus unlike the board's), so the global-light
// invariant methods are mitigated but not cured: on the board pixels the
// mirror reaches, their error grows well above the covered-mirror control,
// yet stays below the single-focal baseline's.
TEST(SimClaims, DistantMirrorIsMitigatedButNotRemoved) {
  const auto& lit = scan("ch2-mirror", false);
  const auto& dark = scan("ch2-mirror-covered", false);
  const Depths d = depths("ch2-mirror"), dc = depths("ch2-mirror-covered");
  // Board pixels that the mirror lights: mean raised by > 15 % over the control.
  size_t board = 0;
  std::vector<uint8_t> reached(lit.depth_mm.size(), 0);
  for (size_t i = 0; i < reached.size(); ++i) {
    if (lit.object[i] != 0) continue;
    ++board;
    reached[i] = lit.acc->mean()[i] > 1.15f * dark.acc->mean()[i] ? 1 : 0;
  }
  const auto keep = [&](size_t i) { return reached[i] != 0; };
  size_t n = 0;
  for (uint8_t r : reached) n += r;
  const ErrorStats m = rel_rms(d.multi, lit.depth_mm, keep), t = rel_rms(d.two, lit.depth_mm, keep),
                   s1 = rel_rms(d.single, lit.depth_mm, keep);
  const ErrorStats mc = rel_rms(dc.multi, dark.depth_mm, keep), tc = rel_rms(dc.two, dark.depth_mm, keep),
                   sc = rel_rms(dc.single, dark.depth_mm, keep);
  std::printf("mirror: %zu of %zu board pixels reached; rel RMS with mirror / covered: multi %.2f / %.2f %% (%zu/%zu "
              "valid), two %.2f / %.2f %%, single %.2f / %.2f %%\n",
              n, board, 100 * m.rel_rms, 100 * mc.rel_rms, m.valid, m.total, 100 * t.rel_rms, 100 * tc.rel_rms,
              100 * s1.rel_rms, 100 * sc.rel_rms);
  ASSERT_GT(n, board / 10) << "the mirror must light a good part of the board";
  // Measured (seed 1): multi 1.15 % vs 0.47 % covered, two-focal 3.0 % vs
  // 1.4 %, single-focal 9.8 % vs 2.6 %.
  // Not removed: the mirror at least 1.8x the error without it.
  EXPECT_GT(m.rel_rms, 1.8 * mc.rel_rms);
  EXPECT_GT(t.rel_rms, 1.8 * tc.rel_rms);
  // Mitigated: well below the baseline's error on the same pixels.
  EXPECT_LT(m.rel_rms, s1.rel_rms / 3);
  EXPECT_LT(t.rel_rms, s1.rel_rms / 2);
}

}  // namespace
}  // namespace procam::defocus
