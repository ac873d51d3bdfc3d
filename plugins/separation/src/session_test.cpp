// SPDX-License-Identifier: MIT
// The separation sessions end to end on a synthetic rig: camera pixel (x, y)
// sees projector pixel (x, y) (a co-located rig in focus) with direct light
// L_d(x) and global light L_g(x) times the pattern's mean, plus black level
// and ambient; frames are quantised like a camera. Expected components are
// the L_d, L_g put in.
#include "separation_session.hpp"

#include "procam/sdk/calibration_table.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace procam::separation {
namespace {

constexpr uint32_t kW = 48, kH = 32;
const nlohmann::json kRig = {{"projector", {{"width", kW}, {"height", kH}}},
                             {"cameras", {{{"width", kW}, {"height", kH}, {"bit_depth", 12}}}},
                             {"threads", 2}};

struct Truth {
  double ld(uint32_t x) const { return 800.0 + 40.0 * x; }  // DN
  double lg(uint32_t y) const { return global ? 100.0 + 10.0 * y : 0.0; }
  // Defocus stand-in: the pattern seen at column x swings by contrast(x, y) around its mean (a
  // uniform frame stays as it is), so beta+ - beta- = contrast(x) for the checkers.
  static double depth(uint32_t x, uint32_t y) { return 800.0 + 10.0 * x + 0.3 * y; }  // mm, all distinct
  double contrast(uint32_t x, uint32_t y) const { return defocused ? 1.0 - 0.001 * (depth(x, y) - 800.0) : 1.0; }
  double ambient = 30, black_level = 0.01;
  bool global = true, defocused = false;
};

// Renders planned frame i as a 12-bit camera would (rounded, clamped).
std::vector<uint16_t> render(const sdk::Plan& plan, uint32_t i, const Truth& t) {
  const auto px = plan.pattern_u8(i);
  double mean = 0;
  for (uint8_t v : px) mean += v / 255.0;
  mean /= double(px.size());
  std::vector<uint16_t> f(size_t{kW} * kH);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      const double p = mean + t.contrast(x, y) * (px[size_t{y} * kW + x] / 255.0 - mean), b = t.black_level;
      const double v = t.ambient + t.ld(x) * (b + (1 - b) * p) + t.lg(y) * (b + (1 - b) * mean);
      f[size_t{y} * kW + x] = static_cast<uint16_t>(std::lround(std::min(v, 4095.0)));
    }
  return f;
}

const procam_output* find(sdk::Outputs& out, const char* name) {
  for (size_t i = 0; i < out.size(); ++i)
    if (std::strcmp(out.view()[i].name, name) == 0) return &out.view()[i];
  return nullptr;
}

void run(sdk::Session& s, const Truth& t, sdk::Plan& plan) {
  bool has = false;
  ASSERT_TRUE(s.next_plan(plan, has).ok());
  ASSERT_TRUE(has);
  for (uint32_t i = 0; i < plan.size(); ++i) {
    auto f = render(plan, i, t);
    ASSERT_TRUE(s.add_frame(i, sdk::gray_view(f.data(), kW, kH, 12)).ok()) << i;
  }
  const sdk::Error e = s.end_round();
  ASSERT_TRUE(e.ok()) << e.message;
}

std::unique_ptr<sdk::Session> make(const std::string& method, nlohmann::json params = nlohmann::json::object(),
                                   nlohmann::json rig = kRig) {
  std::unique_ptr<sdk::Session> s;
  const sdk::Error e = create_session({method, std::move(params), std::move(rig)}, s);
  EXPECT_TRUE(e.ok()) << e.message;
  return s;
}

// In focus, S1 and its two-frame variant recover L_d and L_g within the
// camera's rounding (±0.5 DN per frame, amplified by 2 for L_g and by
// 1/(1 − b)).
TEST(CheckerSession, RecoversComponentsOfAnInFocusSceneWithBlackLevelAndAmbient) {
  const Truth t;
  for (const char* method : {"checker", "checker-pair"}) {
    auto s = make(method);
    sdk::Plan plan;
    run(*s, t, plan);
    EXPECT_EQ(plan.size(), std::string(method) == "checker" ? 26u : 3u);
    EXPECT_EQ(plan.label(plan.size() - 1), std::string("black"));
    sdk::Outputs out;
    ASSERT_TRUE(s->outputs(out).ok());
    const procam_output* d = find(out, "direct_dn");
    const procam_output* g = find(out, "global_dn");
    ASSERT_TRUE(d && g);
    EXPECT_STREQ(d->unit, "DN");
    const auto* dp = static_cast<const float*>(d->image.data);
    const auto* gp = static_cast<const float*>(g->image.data);
    for (uint32_t y = 0; y < kH; ++y)
      for (uint32_t x = 0; x < kW; ++x) {
        ASSERT_NEAR(dp[y * kW + x], t.ld(x), 1.1) << method << " " << x << "," << y;
        ASSERT_NEAR(gp[y * kW + x], t.lg(y), 2.2) << method << " " << x << "," << y;
      }
    EXPECT_DOUBLE_EQ(find(out, "valid_fraction")->scalar, 1.0);
  }
}

TEST(MultiFocalSession, PlansEachFocusSettingEquallySpacedInInverseFocus) {
  auto s = make("multi-focal", {{"focus_settings", 4}, {"focus_near_mm", 500}, {"focus_far_mm", 2000}});
  sdk::Plan plan;
  bool has = false;
  ASSERT_TRUE(s->next_plan(plan, has).ok());
  ASSERT_EQ(plan.size(), 4u * 25 + 1);
  const double expect[4] = {500, 1.0 / (1.0 / 500 - 0.0015 / 3), 1.0 / (1.0 / 500 - 0.003 / 3), 2000};
  for (uint32_t k = 0; k < 4; ++k) {
    EXPECT_NEAR(plan.settings(k * 25).projector_focus_mm, expect[k], 1e-9) << k;
    EXPECT_NEAR(plan.settings(k * 25 + 24).projector_focus_mm, expect[k], 1e-9) << k;
  }
}

TEST(Sessions, ErrorsSayWhatIsWrongAndWhatToDo) {
  std::unique_ptr<sdk::Session> s;
  sdk::Error e = create_session({"checker", {{"shifts", 2}, {"step_px", 3}}, kRig}, s);
  EXPECT_EQ(e.code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_NE(e.message.find("more shifts or a larger step"), std::string::npos) << e.message;
  e = create_session({"one-focal-depth", nlohmann::json::object(), kRig}, s);
  EXPECT_NE(e.message.find("input 'depth_mm' is missing"), std::string::npos) << e.message;
  // Through the scan inputs (ABI 2): a wrong-sized map is refused, the right one reaches the table check.
  sdk::CreateArgs with_input{"one-focal-depth", nlohmann::json::object(), kRig};
  with_input.inputs.add_image_f32("depth_mm", 4, 4, std::vector<float>(16, 900.f));
  e = create_session(with_input, s);
  EXPECT_NE(e.message.find("camera 0's size"), std::string::npos) << e.message;
  sdk::CreateArgs sized{"one-focal-depth", nlohmann::json::object(), kRig};
  sized.inputs.add_image_f32("depth_mm", kW, kH, std::vector<float>(size_t{kW} * kH, 900.f));
  e = create_session(sized, s);
  EXPECT_NE(e.message.find("no calibration table"), std::string::npos) << e.message;
  e = create_session_with_depth({"one-focal-depth", nlohmann::json::object(), kRig},
                                std::vector<float>(size_t{kW} * kH, 900.f), s);
  EXPECT_NE(e.message.find("no calibration table 'separation.one-focal-depth'"), std::string::npos) << e.message;
  EXPECT_EQ(e.code, PROCAM_ERR_FAILED_PRECONDITION) << "the rig lacks data: not a bad argument";
  EXPECT_NE(e.message.find("calibrate-one-focal"), std::string::npos) << e.message;
  e = create_session_with_depth({"calibrate-one-focal", nlohmann::json::object(), kRig}, std::vector<float>(5, 1.f),
                                s);
  EXPECT_NE(e.message.find("same camera"), std::string::npos) << e.message;
  e = create_session({"multi-focal", {{"focus_near_mm", 900}, {"focus_far_mm", 800}}, kRig}, s);
  EXPECT_NE(e.message.find("focus_far_mm"), std::string::npos) << e.message;
  EXPECT_FALSE(s);

  auto ok = make("checker");
  sdk::Plan plan;
  bool has = false;
  ASSERT_TRUE(ok->next_plan(plan, has).ok());
  std::vector<uint16_t> small(10, 0);
  EXPECT_EQ(ok->add_frame(0, sdk::gray_view(small.data(), 5, 2, 12)).code, PROCAM_ERR_BAD_FRAME);
  std::vector<uint8_t> other(size_t{kW} * kH, 0);
  std::vector<uint16_t> right(size_t{kW} * kH, 0);
  ASSERT_TRUE(ok->add_frame(0, sdk::gray_view(right.data(), kW, kH, 12)).ok());
  EXPECT_EQ(ok->add_frame(1, sdk::gray_view(other.data(), kW, kH)).code, PROCAM_ERR_BAD_FRAME)
      << "an 8-bit frame after 12-bit ones";
}

// S3 and its calibration through the sessions: calibrate on a plane without
// global light whose contrast falls with depth (as behind the focal plane),
// then separate a scene with global light at the same depths, with the table
// in the rig. Tolerances: rounding (±0.5 DN) divided by the contrast (>= 0.52)
// plus the table's linear interpolation between bin medians (exact for this
// linear contrast but for the medians' pairing; no window averaging: the
// synthetic contrast has no grid phase).
TEST(OneFocalSession, CalibrateThenSeparateWithTheTable) {
  std::vector<float> depth(size_t{kW} * kH);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) depth[size_t{y} * kW + x] = static_cast<float>(Truth::depth(x, y));
  Truth plane;
  plane.global = false;
  plane.defocused = true;
  std::unique_ptr<sdk::Session> cal;
  ASSERT_TRUE(create_session_with_depth({"calibrate-one-focal", {{"bins", 12}, {"window_px", 1}}, kRig}, depth, cal).ok());
  sdk::Plan plan;
  run(*cal, plane, plan);
  EXPECT_EQ(plan.size(), 66u);
  EXPECT_EQ(plan.label(64), std::string("white"));
  sdk::Outputs out;
  ASSERT_TRUE(cal->outputs(out).ok());
  const procam_output* table = find(out, "calibration_table");
  ASSERT_TRUE(table);
  const nlohmann::json tj = nlohmann::json::parse(table->json);
  sdk::CalibrationTable t;
  ASSERT_TRUE(sdk::parse_table(tj, t).ok());
  EXPECT_EQ(t.name, "separation.one-focal-depth");
  for (double z = 830; z < 1250; z += 37) EXPECT_NEAR(t.lookup(z), 1.0 - 0.001 * (z - 800), 0.003) << z;

  nlohmann::json rig = kRig;
  rig["calibration_tables"] = {{"separation.one-focal-depth", tj}};
  Truth scene;
  scene.defocused = true;
  std::unique_ptr<sdk::Session> s;
  ASSERT_TRUE(create_session_with_depth({"one-focal-depth", nlohmann::json::object(), rig}, depth, s).ok());
  sdk::Plan plan2;
  run(*s, scene, plan2);
  sdk::Outputs out2;
  ASSERT_TRUE(s->outputs(out2).ok());
  const auto* dp = static_cast<const float*>(find(out2, "direct_dn")->image.data);
  const auto* gp = static_cast<const float*>(find(out2, "global_dn")->image.data);
  size_t valid = 0;
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      const float d = dp[y * kW + x], g = gp[y * kW + x];
      if (std::isnan(d)) continue;  // outside the table's depth range (ends of the bins)
      ++valid;
      ASSERT_NEAR(d, scene.ld(x), 0.015 * scene.ld(x)) << x << "," << y;
      ASSERT_NEAR(g, scene.lg(y), 0.015 * scene.ld(x)) << x << "," << y;
    }
  EXPECT_GE(valid, size_t{kW - 8} * kH) << "pixels inside the table's range are valid";
}

}  // namespace
}  // namespace procam::separation
