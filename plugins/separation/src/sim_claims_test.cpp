// SPDX-License-Identifier: MIT
// Thesis §2.5 claims (issue 12, "S1 against S2/S3") on the simulated rig,
// against the sim's component truth (hw::GroundTruth::direct / global: the
// light under a full-white pattern, without ambient, noise-free DN).
//
// Rig (built here, not a shipped config): a co-located camera and projector
// (shared centre, identical 320x200 intrinsics, as the thesis's beam
// splitter, Fig. 2.3a) with a 28 mm projector aperture, 12-bit camera. Small
// resolution keeps the test at a few seconds; the checker (8 projector px)
// then spans 18 mm at 900 mm, still far finer than the inter-reflection
// kernel of the V-groove. Scene: the shipped v-groove (faces 750-900 mm,
// wall 1000 mm). "Focal plane in front of the scene": 550 mm, where the
// thin-lens blur at the scene is sigma = 1.4-2.3 projector px. Also the wax
// candle (ch2-candle) and the 0.3-2 m ch2-candle-marble (ClaimsOn.*), where
// the claim holds only in part: see the comments there and the README.
//
// Measures, over lit pixels whose truth is >= 1 DN (as the daemon's
// evaluator) and where the compared methods give a value: median signed and
// absolute relative error of direct and global. Bounds are the issue's:
// S1 >= 20 % off with direct under- and global over-estimated; S2, S3
// <= 5 % median relative error; S1's answer changes with focus.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "procam/hw/sim/sim_rig.hpp"
#include "separation_session.hpp"

namespace procam::separation {
namespace {

constexpr uint32_t kW = 320, kH = 200;

// The camera: 12 bits, a 1e5 e- well. `Sensor` overrides it for the 0.3-2 m
// scene, whose irradiance falls 44x from the candle to the wall: 16 bits and
// a 1.5e6 e- well (as the HDR camera of configs/rigs/sim-colocated-deep.json),
// 20 ms so that the white pot at 300 mm is ~75 % of the well.
struct Sensor {
  uint32_t bit_depth = 12;
  double exposure_us = 12000, full_well_e = 100000;
};

nlohmann::json rig_config(const Sensor& cam) {
  const nlohmann::json k = {{"width", kW}, {"height", kH}, {"fx", 400.0}, {"fy", 400.0}, {"cx", 159.5}, {"cy", 99.5}};
  return {{"name", "sep-colocated"},
          {"scene", "v-groove"},
          {"seed", 3},
          {"threads", 2},
          {"projector", {{"backend", "sim"}, {"intrinsics", k}, {"black_level", 0.01}, {"aperture_mm", 28.0},
                         {"focus_mm", 800}}},
          {"cameras", {{{"backend", "sim"}, {"intrinsics", k}, {"bit_depth", cam.bit_depth},
                        {"exposure_us", cam.exposure_us}, {"sensitivity", 20.0}, {"full_well_e", cam.full_well_e},
                        {"cam_from_proj", {{"euler_deg", {0, 0, 0}}, {"translation_mm", {0, 0, 0}}}}}}}};
}

std::unique_ptr<sim::SimRig> make_rig(const std::string& scene, const Sensor& cam = {}) {
  auto cfg = sim::parse_sim_rig_config(rig_config(cam));
  EXPECT_TRUE(cfg.ok()) << cfg.status().to_string();
  if (!cfg.ok()) return nullptr;
  const std::string configs = std::string(PROCAM_SOURCE_DIR) + "/configs";
  auto rig = sim::SimRig::create(*cfg, {configs + "/rigs", {configs + "/scenes"}});
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  if (!rig.ok()) return nullptr;
  EXPECT_TRUE((*rig)->set_scene(scene).ok());
  return std::move(rig).value();
}

nlohmann::json session_rig(nlohmann::json tables = nlohmann::json::object(), uint32_t bit_depth = 12) {
  return {{"projector", {{"width", kW}, {"height", kH}}},
          {"cameras", {{{"width", kW}, {"height", kH}, {"bit_depth", bit_depth}}}},
          {"threads", 2},
          {"calibration_tables", std::move(tables)}};
}

struct ScanResult {
  std::vector<float> direct, global;
  std::string table;  // calibration_table JSON (calibrate-one-focal)
};

// plan -> sim capture (each frame at its planned focus) -> add_frame -> end_round -> outputs.
ScanResult scan(sim::SimRig& rig, const std::string& method, const nlohmann::json& params,
         std::optional<std::vector<float>> depth = std::nullopt, nlohmann::json tables = nlohmann::json::object(),
         uint32_t bit_depth = 12) {
  ScanResult r;
  std::unique_ptr<sdk::Session> s;
  const sdk::Error ce =
      create_session_with_depth({method, params, session_rig(std::move(tables), bit_depth)}, std::move(depth), s);
  EXPECT_TRUE(ce.ok()) << ce.message;
  if (!ce.ok()) return r;
  sdk::Plan plan;
  bool has = false;
  EXPECT_TRUE(s->next_plan(plan, has).ok());
  plan.view();  // fills the patterns' data pointers
  for (uint32_t i = 0; i < plan.size(); ++i) {
    EXPECT_TRUE(rig.projector().set_focus_mm(plan.settings(i).projector_focus_mm).ok());
    const Status shown = rig.projector().show(plan.pattern(i), i + 1);
    EXPECT_TRUE(shown.ok()) << shown.to_string();
    if (!shown.ok()) return r;
    auto frame = rig.camera(0).capture(std::chrono::milliseconds(1000));
    EXPECT_TRUE(frame.ok());
    if (!frame.ok()) return r;
    const sdk::Error e = s->add_frame(i, frame->image.view());
    EXPECT_TRUE(e.ok()) << e.message;
  }
  const sdk::Error e = s->end_round();
  EXPECT_TRUE(e.ok()) << e.message;
  sdk::Outputs out;
  EXPECT_TRUE(s->outputs(out).ok());
  for (size_t i = 0; i < out.size(); ++i) {
    const procam_output& o = out.view()[i];
    const auto copy = [&](std::vector<float>& v) {
      const auto* p = static_cast<const float*>(o.image.data);
      v.assign(p, p + size_t{kW} * kH);
    };
    if (std::strcmp(o.name, "direct_dn") == 0) copy(r.direct);
    if (std::strcmp(o.name, "global_dn") == 0) copy(r.global);
    if (std::strcmp(o.name, "calibration_table") == 0) r.table = o.json;
  }
  return r;
}

struct Err {
  double signed_median = NAN, abs_median = NAN;
  size_t pixels = 0;
};

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// Relative error of `est` against `truth` over `mask`.
Err relative_error(const std::vector<float>& est, const Image& truth, const std::vector<uint8_t>& mask) {
  std::vector<double> s, a;
  for (size_t i = 0; i < mask.size(); ++i) {
    const double t = truth.ptr<float>()[i];
    if (!mask[i] || !(t >= 1.0)) continue;
    const double e = (double(est[i]) - t) / t;
    s.push_back(e);
    a.push_back(std::abs(e));
  }
  return {median(s), median(a), s.size()};
}

struct Claims : ::testing::Test {
  static void SetUpTestSuite() {
    rig = make_rig("v-groove").release();
    ASSERT_TRUE(rig);
    auto gt = rig->ground_truth(0);
    ASSERT_TRUE(gt.ok());
    truth = new hw::GroundTruth(std::move(gt).value());
  }
  static void TearDownTestSuite() {
    delete truth;
    delete rig;
  }
  // Lit pixels where every run has both components.
  static std::vector<uint8_t> common_mask(const std::vector<const ScanResult*>& runs) {
    std::vector<uint8_t> m(size_t{kW} * kH, 0);
    for (size_t i = 0; i < m.size(); ++i) {
      bool ok = truth->lit.ptr<uint8_t>()[i] != 0;
      for (const ScanResult* r : runs) ok = ok && std::isfinite(r->direct[i]) && std::isfinite(r->global[i]);
      m[i] = ok ? 1 : 0;
    }
    return m;
  }
  static void print(const char* what, const Err& d, const Err& g) {
    std::printf("%-28s direct: median %+6.1f %% (|.| %5.1f %%)  global: median %+6.1f %% (|.| %5.1f %%)  over %zu px\n",
                what, 100 * d.signed_median, 100 * d.abs_median, 100 * g.signed_median, 100 * g.abs_median, d.pixels);
  }
  static sim::SimRig* rig;
  static hw::GroundTruth* truth;
};
sim::SimRig* Claims::rig = nullptr;
hw::GroundTruth* Claims::truth = nullptr;

const nlohmann::json kFront = {{"focus_mm", 550.0}};
const nlohmann::json kSweep = {{"focus_settings", 6}, {"focus_near_mm", 650.0}, {"focus_far_mm", 1150.0}};

// One claim set-up: the scene, its camera, the focal plane in front of it
// (S1, S3), S2's sweep, and S3's calibration plane (no global light).
struct Setup {
  std::string scene;
  Sensor cam;
  nlohmann::json front, sweep;
  std::string plane = "sep-inclined-plane";
};

// S1 (checker at `front`), S2 (multi-focal over `sweep`) and S3
// (one-focal-depth at `front` with the truth depth, its table made on
// `plane` with the plane's truth depth) on the set-up's scene, and its truth.
struct Runs {
  ScanResult s1, s2, s3;
  std::optional<hw::GroundTruth> truth;
};
Runs run_all(const Setup& st) {
  Runs r;
  std::string table;
  {
    auto plane_rig = make_rig(st.plane, st.cam);
    if (!plane_rig) return r;
    auto pt = plane_rig->ground_truth(0);
    EXPECT_TRUE(pt.ok());
    if (!pt.ok()) return r;
    const float* z = pt->depth_mm.ptr<float>();
    table = scan(*plane_rig, "calibrate-one-focal", st.front, std::vector<float>(z, z + size_t{kW} * kH),
                 nlohmann::json::object(), st.cam.bit_depth)
                .table;
    EXPECT_FALSE(table.empty());
    if (table.empty()) return r;
  }
  auto rig = make_rig(st.scene, st.cam);
  if (!rig) return r;
  auto gt = rig->ground_truth(0);
  EXPECT_TRUE(gt.ok());
  if (!gt.ok()) return r;
  r.truth = std::move(gt).value();
  const float* z = r.truth->depth_mm.ptr<float>();
  r.s1 = scan(*rig, "checker", st.front, std::nullopt, nlohmann::json::object(), st.cam.bit_depth);
  r.s2 = scan(*rig, "multi-focal", st.sweep, std::nullopt, nlohmann::json::object(), st.cam.bit_depth);
  r.s3 = scan(*rig, "one-focal-depth", st.front, std::vector<float>(z, z + size_t{kW} * kH),
              {{kOneFocalTable, nlohmann::json::parse(table)}}, st.cam.bit_depth);
  return r;
}

struct RegionErrors {
  Err d1, g1, d2, g2, d3, g3;
  size_t region = 0;  // lit pixels of the region
};
// Errors over the lit pixels of `objects` (truth object ids, 1 + scene
// index; empty: all): S1 and S2 where both give both components, S3 where
// S1 and S3 do (S3 has no answer where its one focus blurs the checker too
// much; the claim is about the pixels where S1 is off).
RegionErrors region_errors(const Runs& r, const std::vector<uint8_t>& objects, const char* what) {
  const hw::GroundTruth& t = *r.truth;
  const size_t n = size_t{kW} * kH;
  std::vector<uint8_t> m12(n, 0), m13(n, 0);
  RegionErrors e;
  const auto both = [](const ScanResult& s, size_t i) { return std::isfinite(s.direct[i]) && std::isfinite(s.global[i]); };
  for (size_t i = 0; i < n; ++i) {
    const bool in = t.lit.ptr<uint8_t>()[i] != 0 &&
                    (objects.empty() || std::find(objects.begin(), objects.end(), t.object.ptr<uint8_t>()[i]) != objects.end());
    e.region += in ? 1u : 0u;
    m12[i] = in && both(r.s1, i) && both(r.s2, i) ? 1 : 0;
    m13[i] = in && both(r.s1, i) && both(r.s3, i) ? 1 : 0;
  }
  e.d1 = relative_error(r.s1.direct, t.direct, m12);
  e.g1 = relative_error(r.s1.global, t.global, m12);
  e.d2 = relative_error(r.s2.direct, t.direct, m12);
  e.g2 = relative_error(r.s2.global, t.global, m12);
  e.d3 = relative_error(r.s3.direct, t.direct, m13);
  e.g3 = relative_error(r.s3.global, t.global, m13);
  std::printf("-- %s (%zu lit px)\n", what, e.region);
  Claims::print("S1 checker (front focus)", e.d1, e.g1);
  Claims::print("S2 multi-focal", e.d2, e.g2);
  Claims::print("S3 one-focal-depth", e.d3, e.g3);
  return e;
}

// The claim: S1 >= 20 % off (direct under-, global over-estimated), S2 and
// S3 within 5 % median relative error.
void expect_claim(const RegionErrors& e, size_t min_pixels) {
  ASSERT_GT(e.d1.pixels, min_pixels) << "the region must be lit and separated by S1 and S2";
  ASSERT_GT(e.d3.pixels, min_pixels) << "the region must be lit and separated by S1 and S3";
  EXPECT_LE(e.d1.signed_median, -0.20) << "S1 under-estimates direct light out of focus (Fig. 2.16)";
  EXPECT_GE(e.g1.signed_median, 0.20) << "S1 over-estimates global light out of focus (Fig. 2.16)";
  EXPECT_LE(e.d2.abs_median, 0.05);
  EXPECT_LE(e.g2.abs_median, 0.05);
  EXPECT_LE(e.d3.abs_median, 0.05);
  EXPECT_LE(e.g3.abs_median, 0.05);
}

TEST(ClaimsOn, VGrooveFocalPlaneInFrontS1IsOffWhileS2AndS3StayWithinFivePercent) {
  const Runs r = run_all({"v-groove", {}, kFront, kSweep});
  ASSERT_TRUE(r.truth);
  expect_claim(region_errors(r, {}, "v-groove, whole view"), size_t{kW} * kH / 2);
}

// Truth object ids (1 + index in the scene file).
constexpr uint8_t kCandleWax = 2;     // ch2-candle and ch2-candle-marble: the wax cylinder
constexpr uint8_t kCandleMarble = 4;  // ch2-candle-marble: the marble ball

// The candle (Fig. 2.5, 2.16-2.17): wax (sub-surface scattering, diffusion
// length 8.2 mm) with paper sleeves, front at 800 mm before a wall at 1000 mm.
// Same rig; 8 ms so that the paper (albedo 0.75, facing the camera) stays
// below the well. Focal plane in front at 550 mm (sigma 1.8-2.3 px).
//
// Measured (seed 3): over the whole view the direct part of the claim holds
// (S1 -29.8 %, S2 +1.5 %, S3 0.6 %); global is not comparable there (the
// wall, most of the view, has almost none: relative errors of 10^2-10^4 %).
// On the exposed wax the claim does NOT hold, for any method and for S1 in
// focus too: the checker's 16 mm squares (8 px of this 320-px projector at
// 800 mm) are coarser than the 8.2 mm diffusion length, so the sub-surface
// light under a lit square differs from that under a dark one (Nayar's
// high-frequency condition fails) and every method counts that difference as
// direct: S1 +1565 % (in focus +1925 %), S2 +1935 %, S3 +1791 %. The truth's
// direct on wax is its 3 % Fresnel reflection. Asserted as measured so a
// change shows; the fix is a finer checker than the diffusion length (a
// full-resolution projector), not a looser bound.
TEST(ClaimsOn, CandleDirectClaimHoldsAndWaxBreaksTheHighFrequencyCondition) {
  const Runs r = run_all({"ch2-candle", {12, 8000, 100000}, kFront, kSweep});
  ASSERT_TRUE(r.truth);
  const RegionErrors all = region_errors(r, {}, "ch2-candle, whole view");
  ASSERT_GT(all.d1.pixels, size_t{kW} * kH / 2);
  EXPECT_LE(all.d1.signed_median, -0.20) << "S1 under-estimates direct light out of focus (Fig. 2.16)";
  EXPECT_LE(all.d2.abs_median, 0.05);
  EXPECT_LE(all.d3.abs_median, 0.05);
  Runs in_focus = r;
  auto rig = make_rig("ch2-candle", {12, 8000, 100000});
  ASSERT_TRUE(rig);
  in_focus.s1 = scan(*rig, "checker", {{"focus_mm", 840.0}});
  const RegionErrors wax = region_errors(r, {kCandleWax}, "ch2-candle, exposed wax");
  const RegionErrors wax_focus = region_errors(in_focus, {kCandleWax}, "ch2-candle, exposed wax, S1 in focus (840 mm)");
  ASSERT_GT(wax.d3.pixels, 1000u);
  for (const Err* e : {&wax.d1, &wax_focus.d1, &wax.d2, &wax.d3})
    EXPECT_GT(e->signed_median, 1.0) << "every method counts near-field sub-surface light as direct on the wax";
}

// Fig. 2.17: the candle-and-marble scene, 0.3-2 m. Focal plane in front of it
// at 250 mm; S2 over the 0.3-2 m sweep of the defocus plugin (14 settings
// uniform in 1/f from 270 to 5000 mm, ~0.75 px of blur per step here); S3's
// table from the 280-2300 mm inclined plane at 250 mm.
//
// Measured (seed 3), median relative error direct / global:
//   V-groove (1125-1200 mm, inter-reflections): S1 -98 % / +223 %, S2 +1.5 % /
//     -2.3 %: the claim holds for S2. S3 has no answer there: at one focus
//     of 250 mm the checker is blurred by sigma ~7-8 px beyond ~0.6 m and
//     beta+ - beta- falls below min_contrast (invalid, not wrong).
//   pot (~300 mm, matte): S1 -22.9 % direct; S2 +0.6 %, S3 0.8 %. Its global
//     (light from the candle) is small: S2 9.5 %, S3 35 % abs: not within 5 %.
//   wax candle and marble (sub-surface): the claim does not hold (S2 direct
//     +1156 % on wax, +1552 % on the marble), for the reason given above: the
//     checker is coarser than the diffusion length.
TEST(ClaimsOn, CandleMarbleClaimHoldsOnTheGrooveNotOnTranslucentBodies) {
  const nlohmann::json sweep = {{"focus_settings", 14}, {"focus_near_mm", 270.0}, {"focus_far_mm", 5000.0}};
  const Runs r = run_all({"ch2-candle-marble", {16, 20000, 1500000}, {{"focus_mm", 250.0}}, sweep,
                          "ch2-calibration-plane-deep"});
  ASSERT_TRUE(r.truth);
  region_errors(r, {}, "ch2-candle-marble, whole view");
  const RegionErrors groove = region_errors(r, {5, 6}, "ch2-candle-marble, V-groove");
  ASSERT_GT(groove.d1.pixels, 3000u);
  EXPECT_LE(groove.d1.signed_median, -0.20);
  EXPECT_GE(groove.g1.signed_median, 0.20);
  EXPECT_LE(groove.d2.abs_median, 0.05);
  EXPECT_LE(groove.g2.abs_median, 0.05);
  EXPECT_EQ(groove.d3.pixels, 0u) << "S3 at 250 mm: no answer this far behind its focus";
  const RegionErrors pot = region_errors(r, {3}, "ch2-candle-marble, pot");
  ASSERT_GT(pot.d3.pixels, 1000u);
  EXPECT_LE(pot.d1.signed_median, -0.20);
  EXPECT_LE(pot.d2.abs_median, 0.05);
  EXPECT_LE(pot.d3.abs_median, 0.05);
  const RegionErrors wax = region_errors(r, {kCandleWax}, "ch2-candle-marble, wax candle at ~330 mm");
  const RegionErrors marble = region_errors(r, {kCandleMarble}, "ch2-candle-marble, marble at ~700 mm");
  ASSERT_GT(wax.d2.pixels, 1000u);
  ASSERT_GT(marble.d2.pixels, 1000u);
  EXPECT_GT(wax.d2.signed_median, 1.0) << "sub-surface light counted as direct (checker coarser than diffusion)";
  EXPECT_GT(marble.d2.signed_median, 1.0) << "sub-surface light counted as direct (checker coarser than diffusion)";
}

TEST_F(Claims, ControlS1InFocusIsAccurate) {
  const ScanResult s0 = scan(*rig, "checker", {{"focus_mm", 850.0}});
  const auto mask = common_mask({&s0});
  const Err d = relative_error(s0.direct, truth->direct, mask), g = relative_error(s0.global, truth->global, mask);
  print("S1 checker, focus 850 mm", d, g);
  EXPECT_LE(d.abs_median, 0.05);
  EXPECT_LE(g.abs_median, 0.05);
}

// Fig. 2.17: S1's separation depends on the focus setting (it should not: the
// split is a property of the scene); S2's does not, by construction of its sweep.
TEST_F(Claims, S1AnswerChangesWithFocusSetting) {
  const ScanResult near = scan(*rig, "checker", {{"focus_mm", 550.0}});
  const ScanResult mid = scan(*rig, "checker", {{"focus_mm", 700.0}});
  const auto mask = common_mask({&near, &mid});
  std::vector<double> ratio;
  for (size_t i = 0; i < mask.size(); ++i)
    if (mask[i] && mid.direct[i] > 0) ratio.push_back(double(near.direct[i]) / double(mid.direct[i]));
  const double r = median(ratio);
  std::printf("S1 direct, focus 550 mm / focus 700 mm: median ratio %.3f over %zu px\n", r, ratio.size());
  EXPECT_LE(r, 0.9) << "S1's direct light changes by > 10 % between two focus settings";
}

}  // namespace
}  // namespace procam::separation
