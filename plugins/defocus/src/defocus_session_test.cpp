// SPDX-License-Identifier: MIT
// Sessions end to end on synthetic frames from the thin-lens model: a pixel
// at depth z sees at focus f the 3rd harmonic scaled by exp(-c (1/f - 1/z)^2)
// (a Gaussian blur, sigma linear in |1/f - 1/z|). The calibration table is
// that closed form, so depths must come back within interpolation error.
// Hard cases: black, saturated, no peak inside the sweep, zero denominator,
// 8/12/16-bit and float frames, a missing or mismatched table.
#include "defocus_session.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "calibration.hpp"
#include "focus_measures.hpp"

namespace procam::defocus {
namespace {

constexpr uint32_t kW = 8, kH = 2;
constexpr double kC = 1.11e7;  // E ∝ exp(-kC (1/f - 1/z)^2): the sim-colocated rig's 15 mm aperture

// Truth depth per pixel; pixel 5: black, 6: saturates, 7: beyond the sweep (peak at an end).
const double kDepth[kW] = {660, 720, 800, 880, 1000, 800, 800, 1500};

// fbar -> depth table from the closed form (sweep uniform in 1/f).
nlohmann::json multi_table(const std::vector<double>& focus) {
  sdk::CalibrationTable t;
  t.name = kMultiFocal.table_name;
  t.x_name = kMultiFocal.x_name;
  t.x_unit = kMultiFocal.x_unit;
  t.extra = {{"focus_mm", focus}};
  const double a = 1 / focus.front(), step = (1 / focus.front() - 1 / focus.back()) / double(focus.size() - 1);
  for (int k = 0; k <= 100; ++k) {
    const double fbar = 0.5 + 0.04 * k;
    t.samples.emplace_back(fbar, 1 / (a - fbar * step));
  }
  return sdk::to_json(t);
}

nlohmann::json rig_json(uint32_t bits, const nlohmann::json& tables) {
  return {{"projector", {{"width", 48}, {"height", 4}}},
          {"cameras", {{{"width", kW}, {"height", kH}, {"bit_depth", bits}}}},
          {"threads", 2},
          {"calibration_tables", tables}};
}

// Pixel value at (focus f, shift t): mean m + amplitude cos(ω (x - t)).
double synth(uint32_t x, double f_mm, uint32_t t, double full) {
  if (x == 5) return 0.004 * full;  // black
  const double z = kDepth[x];
  const double m = 0.4 * full, amp = 0.3 * full * std::exp(-kC * std::pow(1 / f_mm - 1 / z, 2));
  const double v = m + amp * std::cos(2 * std::numbers::pi * 3 * (double(x) - t) / 24.0);
  return x == 6 && t == 3 ? full : v;  // saturates once
}

template <class T>
std::vector<T> frame_of(const std::vector<double>& focus, uint32_t index, double full) {
  std::vector<T> v(size_t{kW} * kH);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      const double s = synth(x, focus[index / 24], index % 24, full);
      if constexpr (std::is_floating_point_v<T>) v[size_t{y} * kW + x] = static_cast<T>(s);
      else v[size_t{y} * kW + x] = static_cast<T>(std::lround(s));
    }
  return v;
}

const procam_output* find(const procam_output* o, uint32_t n, const std::string& name) {
  for (uint32_t i = 0; i < n; ++i)
    if (name == o[i].name) return &o[i];
  return nullptr;
}

template <class T>
void run_multi_focal(uint32_t bits, uint32_t type) {
  const std::vector<double> focus = focus_sweep_mm(600, 1200, 6);
  sdk::CreateArgs args{"multi-focal", nlohmann::json::object(),
                       rig_json(bits, {{"defocus.multi-focal", multi_table(focus)}})};
  std::unique_ptr<sdk::Session> s;
  const sdk::Error ce = create_session(args, s);
  ASSERT_TRUE(ce.ok()) << ce.message;
  sdk::Plan plan;
  bool has_round = false;
  ASSERT_TRUE(s->next_plan(plan, has_round).ok());
  ASSERT_TRUE(has_round);
  ASSERT_EQ(plan.size(), 144u);
  EXPECT_DOUBLE_EQ(plan.settings(30).projector_focus_mm, focus[1]);
  EXPECT_EQ(plan.label(30), "focus 1 shift 6");
  const double full = type == PROCAM_PIXEL_F32 ? 1.0 : std::ldexp(1.0, int(bits)) - 1;
  for (uint32_t i = 0; i < plan.size(); ++i) {
    auto px = frame_of<T>(focus, i, full);
    procam_image img{};
    if constexpr (std::is_same_v<T, uint8_t>) img = sdk::gray_view(px.data(), kW, kH, 8);
    else if constexpr (std::is_same_v<T, uint16_t>) img = sdk::gray_view(px.data(), kW, kH, bits);
    else img = sdk::gray_view(px.data(), kW, kH);
    const sdk::Error e = s->add_frame(i, img);
    ASSERT_TRUE(e.ok()) << e.message;
  }
  ASSERT_TRUE(s->end_round().ok());
  sdk::Outputs out;
  ASSERT_TRUE(s->outputs(out).ok());
  const procam_output* o = out.view();
  const procam_output* depth = find(o, out.size(), "depth_mm");
  const procam_output* fbar = find(o, out.size(), "fbar");
  ASSERT_NE(depth, nullptr);
  ASSERT_NE(fbar, nullptr);
  const auto* d = static_cast<const float*>(depth->image.data);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      const float v = d[y * kW + x];
      if (x >= 5) {
        EXPECT_TRUE(std::isnan(v)) << "pixel " << x << " must be invalid, got " << v;
      } else {
        // Gaussian interpolation is exact for this model; quantisation of
        // 8-bit frames moves fbar by < 0.01 index (~0.2 % of depth).
        EXPECT_NEAR(v, kDepth[x], 0.004 * kDepth[x]) << "pixel " << x << " bits " << bits;
      }
    }
  const procam_output* vf = find(o, out.size(), "valid_fraction");
  ASSERT_NE(vf, nullptr);
  EXPECT_DOUBLE_EQ(vf->scalar, 5.0 / 8.0);
  ASSERT_NE(find(o, out.size(), "report"), nullptr);
  const auto report = nlohmann::json::parse(find(o, out.size(), "report")->json);
  EXPECT_EQ(report.at("method"), "multi-focal");
  EXPECT_EQ(report.at("patterns"), 144);
}

TEST(DefocusSession, MultiFocalU8) { run_multi_focal<uint8_t>(8, PROCAM_PIXEL_U8); }
TEST(DefocusSession, MultiFocalU12) { run_multi_focal<uint16_t>(12, PROCAM_PIXEL_U16); }
TEST(DefocusSession, MultiFocalU16) { run_multi_focal<uint16_t>(16, PROCAM_PIXEL_U16); }
TEST(DefocusSession, MultiFocalF32) { run_multi_focal<float>(32, PROCAM_PIXEL_F32); }

TEST(DefocusSession, MissingTableSaysHowToMakeOne) {
  sdk::CreateArgs args{"multi-focal", nlohmann::json::object(), rig_json(8, nlohmann::json::object())};
  std::unique_ptr<sdk::Session> s;
  const sdk::Error e = create_session(args, s);
  EXPECT_EQ(e.code, PROCAM_ERR_FAILED_PRECONDITION) << "the rig lacks data: not a bad argument";
  EXPECT_NE(e.message.find("defocus.multi-focal"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find("procam calibrate defocus/calibrate-multi-focal"), std::string::npos) << e.message;
  EXPECT_EQ(s, nullptr);
}

TEST(DefocusSession, TableFromOtherFocusSettingsIsRefused) {
  const auto other = focus_sweep_mm(500, 1500, 6);
  sdk::CreateArgs args{"multi-focal", nlohmann::json::object(),
                       rig_json(8, {{"defocus.multi-focal", multi_table(other)}})};
  std::unique_ptr<sdk::Session> s;
  const sdk::Error e = create_session(args, s);
  EXPECT_EQ(e.code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_NE(e.message.find("made with focus settings"), std::string::npos) << e.message;
}

TEST(DefocusSession, BadParamsAreNamed) {
  std::unique_ptr<sdk::Session> s;
  auto e = create_session({"two-focal", {{"f1_mm", 800}, {"f2_mm", 800}}, rig_json(8, nlohmann::json::object())}, s);
  EXPECT_EQ(e.code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_NE(e.message.find("f1_mm"), std::string::npos) << e.message;
  e = create_session({"invariance", {{"pairs", "1,1,99,0"}}, rig_json(8, nlohmann::json::object())}, s);
  EXPECT_EQ(e.code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_NE(e.message.find("pairs"), std::string::npos) << e.message;
  e = create_session({"multi-focal", {{"focus_count", 2}}, rig_json(8, nlohmann::json::object())}, s);
  EXPECT_EQ(e.code, PROCAM_ERR_INVALID_ARGUMENT);
}

TEST(DefocusSession, InvarianceReportsGAtPairs) {
  std::unique_ptr<sdk::Session> s;
  ASSERT_TRUE(create_session({"invariance", {{"pairs", "2,0,2,1"}}, rig_json(16, nlohmann::json::object())}, s).ok());
  sdk::Plan plan;
  bool has_round = false;
  ASSERT_TRUE(s->next_plan(plan, has_round).ok());
  const auto focus = focus_sweep_mm(600, 1200, 6);
  for (uint32_t i = 0; i < plan.size(); ++i) {
    auto px = frame_of<uint16_t>(focus, i, 65535);
    for (uint32_t x = 0; x < kW; ++x) {  // row 0 = B: E halved by global blur, mean raised
      const double v = 0.5 * (double(px[kW + x]) - 0.4 * 65535) + 0.5 * 65535;
      px[x] = static_cast<uint16_t>(std::lround(v));
    }
    ASSERT_TRUE(s->add_frame(i, sdk::gray_view(px.data(), kW, kH, 16)).ok());
  }
  ASSERT_TRUE(s->end_round().ok());
  sdk::Outputs out;
  ASSERT_TRUE(s->outputs(out).ok());
  const auto report = nlohmann::json::parse(find(out.view(), out.size(), "report")->json);
  const auto& pair = report.at("pairs").at(0);
  ASSERT_TRUE(pair.at("valid").get<bool>());
  for (const auto& g : pair.at("g")) EXPECT_NEAR(g.get<double>(), 0.5, 0.01);
  EXPECT_LT(pair.at("g_variation").get<double>(), 0.02);
  EXPECT_GT(pair.at("e3_b_variation").get<double>(), 0.25);
  EXPECT_NE(find(out.view(), out.size(), "e3_f5_dn"), nullptr);
}

TEST(DefocusSession, PatternsArePrefilteredUnlessAskedNot) {
  for (double sigma : {0.0, 1.0}) {
    std::unique_ptr<sdk::Session> s;
    ASSERT_TRUE(create_session({"invariance", {{"prefilter_sigma_px", sigma}}, rig_json(8, nlohmann::json::object())}, s).ok());
    sdk::Plan plan;
    bool has_round = false;
    ASSERT_TRUE(s->next_plan(plan, has_round).ok());
    const auto px = plan.pattern_u8(0);
    size_t grey = 0;
    for (uint8_t v : px) grey += (v != 0 && v != 255) ? 1u : 0u;
    if (sigma == 0.0) EXPECT_EQ(grey, 0u);
    else EXPECT_GT(grey, px.size() / 4);  // edges are ramps
    // Shift 1 moves the pattern one projector pixel to the right.
    EXPECT_EQ(plan.pattern_u8(1)[1], px[0]);
  }
}

}  // namespace
}  // namespace procam::defocus

namespace procam::defocus {
namespace {

// calibrate-multi-focal on a synthetic inclined plane (depth 650 -> 1150 mm
// across 64 columns, the thin-lens E(f) above): the table it outputs maps
// fbar to depth as the closed form does, and multi-focal with that table
// recovers the plane.
TEST(DefocusSession, CalibrateMultiFocalMakesTheTableAndItRecoversThePlane) {
  constexpr uint32_t W = 64, H = 4;
  const std::vector<double> focus = focus_sweep_mm(600, 1200, 6);
  auto depth_at = [](uint32_t x) { return 650.0 + 500.0 * x / (W - 1); };
  std::vector<float> plane(size_t{W} * H);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W; ++x) plane[size_t{y} * W + x] = static_cast<float>(depth_at(x));
  auto frame = [&](uint32_t index) {
    std::vector<uint16_t> v(size_t{W} * H);
    const double full = 4095, f = focus[index / 24];
    for (uint32_t y = 0; y < H; ++y)
      for (uint32_t x = 0; x < W; ++x) {
        const double amp = 0.3 * full * std::exp(-kC * std::pow(1 / f - 1 / depth_at(x), 2));
        v[size_t{y} * W + x] = static_cast<uint16_t>(
            std::lround(0.4 * full + amp * std::cos(2 * std::numbers::pi * 3 * (double(x) - index % 24) / 24.0)));
      }
    return v;
  };
  const nlohmann::json rig = {{"projector", {{"width", 96}, {"height", 4}}},
                              {"cameras", {{{"width", W}, {"height", H}, {"bit_depth", 12}}}},
                              {"threads", 2}};
  auto run = [&](sdk::CreateArgs args) {
    std::unique_ptr<sdk::Session> s;
    const sdk::Error ce = create_session(args, s);
    EXPECT_TRUE(ce.ok()) << ce.message;
    auto out = std::make_unique<sdk::Outputs>();
    if (!s) return out;
    sdk::Plan plan;
    bool has_round = false;
    EXPECT_TRUE(s->next_plan(plan, has_round).ok());
    for (uint32_t i = 0; i < plan.size(); ++i) {
      auto px = frame(i);
      EXPECT_TRUE(s->add_frame(i, sdk::gray_view(px.data(), W, H, 12)).ok());
    }
    EXPECT_TRUE(s->end_round().ok());
    EXPECT_TRUE(s->outputs(*out).ok());
    return out;
  };
  sdk::CreateArgs cal{"calibrate-multi-focal", {{"bins", 16}}, rig};
  cal.inputs.add_image_f32("depth_mm", W, H, plane);
  auto cal_out = run(cal);
  const procam_output* table_out = find(cal_out->view(), cal_out->size(), "calibration_table");
  ASSERT_NE(table_out, nullptr);
  sdk::CalibrationTable table;
  ASSERT_TRUE(sdk::parse_table(nlohmann::json::parse(table_out->json), table).ok());
  EXPECT_EQ(table.name, "defocus.multi-focal");
  EXPECT_EQ(table.samples.size(), 16u);
  // Closed form of the sweep (uniform in 1/f): depth = 1 / (1/f0 - fbar * step).
  const double a = 1 / focus.front(), step = (1 / focus.front() - 1 / focus.back()) / double(focus.size() - 1);
  for (const auto& [fbar, depth] : table.samples) EXPECT_NEAR(depth, 1 / (a - fbar * step), 0.005 * depth) << fbar;
  // The table in the rig: multi-focal recovers the plane inside the table's range.
  sdk::CreateArgs scan{"multi-focal", nlohmann::json::object(), rig};
  scan.rig["calibration_tables"] = {{"defocus.multi-focal", sdk::to_json(table)}};
  auto scan_out = run(scan);
  const procam_output* d = find(scan_out->view(), scan_out->size(), "depth_mm");
  ASSERT_NE(d, nullptr);
  const auto* depth = static_cast<const float*>(d->image.data);
  size_t checked = 0;
  for (uint32_t x = 0; x < W; ++x) {
    const float v = depth[x];
    if (std::isnan(v)) continue;  // outside the table's measured range: invalid, never extrapolated
    EXPECT_NEAR(v, depth_at(x), 0.01 * depth_at(x)) << "column " << x;
    ++checked;
  }
  EXPECT_GT(checked, W * 3 / 4);
  // Without the plane's depth there is nothing to calibrate against.
  std::unique_ptr<sdk::Session> s;
  const sdk::Error e = create_session({"calibrate-multi-focal", nlohmann::json::object(), rig}, s);
  EXPECT_FALSE(e.ok());
  EXPECT_NE(e.message.find("depth_mm"), std::string::npos) << e.message;
}

}  // namespace
}  // namespace procam::defocus
