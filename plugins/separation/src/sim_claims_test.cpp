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
// thin-lens blur at the scene is sigma = 1.4-2.3 projector px.
//
// Measures, over lit pixels whose truth is >= 1 DN (as the daemon's
// evaluator) and where every method gives a value: median signed and
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

nlohmann::json rig_config() {
  const nlohmann::json k = {{"width", kW}, {"height", kH}, {"fx", 400.0}, {"fy", 400.0}, {"cx", 159.5}, {"cy", 99.5}};
  return {{"name", "sep-colocated"},
          {"scene", "v-groove"},
          {"seed", 3},
          {"threads", 2},
          {"projector", {{"backend", "sim"}, {"intrinsics", k}, {"black_level", 0.01}, {"aperture_mm", 28.0},
                         {"focus_mm", 800}}},
          {"cameras", {{{"backend", "sim"}, {"intrinsics", k}, {"bit_depth", 12}, {"exposure_us", 12000}, {"sensitivity", 20.0}, {"full_well_e", 100000},
                        {"cam_from_proj", {{"euler_deg", {0, 0, 0}}, {"translation_mm", {0, 0, 0}}}}}}}};
}

std::unique_ptr<sim::SimRig> make_rig(const std::string& scene) {
  auto cfg = sim::parse_sim_rig_config(rig_config());
  EXPECT_TRUE(cfg.ok()) << cfg.status().to_string();
  if (!cfg.ok()) return nullptr;
  const std::string configs = std::string(PROCAM_SOURCE_DIR) + "/configs";
  auto rig = sim::SimRig::create(*cfg, {configs + "/rigs", {configs + "/scenes"}});
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  if (!rig.ok()) return nullptr;
  EXPECT_TRUE((*rig)->set_scene(scene).ok());
  return std::move(rig).value();
}

nlohmann::json session_rig(nlohmann::json tables = nlohmann::json::object()) {
  return {{"projector", {{"width", kW}, {"height", kH}}},
          {"cameras", {{{"width", kW}, {"height", kH}, {"bit_depth", 12}}}},
          {"threads", 2},
          {"calibration_tables", std::move(tables)}};
}

struct ScanResult {
  std::vector<float> direct, global;
  std::string table;  // calibration_table JSON (calibrate-one-focal)
};

// plan -> sim capture (each frame at its planned focus) -> add_frame -> end_round -> outputs.
ScanResult scan(sim::SimRig& rig, const std::string& method, const nlohmann::json& params,
         std::optional<std::vector<float>> depth = std::nullopt, nlohmann::json tables = nlohmann::json::object()) {
  ScanResult r;
  std::unique_ptr<sdk::Session> s;
  const sdk::Error ce = create_session_with_depth({method, params, session_rig(std::move(tables))}, std::move(depth), s);
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

TEST_F(Claims, FocalPlaneInFrontS1IsOffWhileS2AndS3StayWithinFivePercent) {
  // S3's table from the inclined plane (no global light), its truth depth as input.
  std::vector<float> plane_depth;
  std::string table;
  {
    auto plane_rig = make_rig("sep-inclined-plane");
    ASSERT_TRUE(plane_rig);
    auto pt = plane_rig->ground_truth(0);
    ASSERT_TRUE(pt.ok());
    const float* z = pt->depth_mm.ptr<float>();
    plane_depth.assign(z, z + size_t{kW} * kH);
    table = scan(*plane_rig, "calibrate-one-focal", kFront, plane_depth).table;
    ASSERT_FALSE(table.empty());
  }
  const float* z = truth->depth_mm.ptr<float>();
  const ScanResult s1 = scan(*rig, "checker", kFront);
  const ScanResult s2 = scan(*rig, "multi-focal", kSweep);
  const ScanResult s3 = scan(*rig, "one-focal-depth", kFront, std::vector<float>(z, z + size_t{kW} * kH),
                      {{kOneFocalTable, nlohmann::json::parse(table)}});
  const auto mask = common_mask({&s1, &s2, &s3});
  const Err d1 = relative_error(s1.direct, truth->direct, mask), g1 = relative_error(s1.global, truth->global, mask);
  const Err d2 = relative_error(s2.direct, truth->direct, mask), g2 = relative_error(s2.global, truth->global, mask);
  const Err d3 = relative_error(s3.direct, truth->direct, mask), g3 = relative_error(s3.global, truth->global, mask);
  print("S1 checker, focus 550 mm", d1, g1);
  print("S2 multi-focal 650-1150 mm", d2, g2);
  print("S3 one-focal-depth 550 mm", d3, g3);
  ASSERT_GT(d1.pixels, size_t{kW} * kH / 2) << "most of the view is lit and separated by all three";
  EXPECT_LE(d1.signed_median, -0.20) << "S1 under-estimates direct light out of focus (Fig. 2.16)";
  EXPECT_GE(g1.signed_median, 0.20) << "S1 over-estimates global light out of focus (Fig. 2.16)";
  EXPECT_LE(d2.abs_median, 0.05);
  EXPECT_LE(g2.abs_median, 0.05);
  EXPECT_LE(d3.abs_median, 0.05);
  EXPECT_LE(g3.abs_median, 0.05);
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
