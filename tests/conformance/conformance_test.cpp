// SPDX-License-Identifier: MIT
// Conformance suite: loads every plugin in PROCAM_PLUGIN_DIR, and runs every
// method each one lists (default parameters) through the real path — plan ->
// sim rig capture (engine::run_scan, all rounds) -> streaming decode ->
// outputs — on the sim scenes "plane" and "tilted-box". Checks, per run:
//   - the scan finishes; pattern_count matches the frames captured;
//   - proj_col_px exists, is F32 camera-sized, each value NaN or in
//     [-0.5, projector width - 0.5]; valid (if any) is 255 exactly where the
//     column is finite; confidence (if any) is finite in [0, 1]; depth_mm (if
//     any) is NaN or finite positive; report (if any) is JSON naming the method;
//   - on "plane" (direct light only): >= 95% of lit pixels decoded within one
//     column of the truth and <= 0.5% gross errors (|err| > 1 column).
// New plugins and methods are picked up without editing this file.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/engine/evaluate.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

namespace procam {
namespace {

std::string source(const std::string& rel) { return std::string(PROCAM_SOURCE_DIR) + "/" + rel; }

struct Case {
  std::string plugin, method, scene;
};
void PrintTo(const Case& c, std::ostream* os) { *os << c.plugin << "/" << c.method << " on " << c.scene; }

std::vector<Case> all_cases() {
  host::PluginHost host;
  host.load_directories({PROCAM_PLUGIN_DIR});
  std::vector<Case> cases;
  for (const auto& p : host.plugins())
    for (const auto& m : p.methods)
      for (const char* scene : {"plane", "tilted-box"}) cases.push_back({p.name, m.name, scene});
  return cases;
}

class Conformance : public ::testing::TestWithParam<Case> {};

TEST(ConformanceSetup, FindsPlugins) {
  host::PluginHost host;
  host.load_directories({PROCAM_PLUGIN_DIR});
  ASSERT_FALSE(host.plugins().empty()) << "no plugins in " << PROCAM_PLUGIN_DIR;
  for (const auto& r : host.rejected()) ADD_FAILURE() << "rejected plugin " << r.file;
}

TEST_P(Conformance, PlanCaptureDecode) {
  const Case& c = GetParam();
  auto cfg = engine::read_json_file(source("configs/rigs/sim.json"));
  ASSERT_TRUE(cfg.ok()) << cfg.status().message();
  auto rig = hw::create_rig(*cfg, {source("configs/rigs"), {source("configs/scenes")}});
  ASSERT_TRUE(rig.ok()) << rig.status().message();
  ASSERT_TRUE((*rig)->apply_scan_options({{"scene", c.scene}}).ok());
  host::PluginHost host;
  host.load_directories({PROCAM_PLUGIN_DIR});
  const nlohmann::json rig_json = engine::plugin_rig_json(**rig, 2);
  auto session = host.create_session(c.plugin, c.method, "{}", rig_json.dump());
  ASSERT_TRUE(session.ok()) << session.status().message();
  std::atomic<bool> cancel{false};
  auto outcome = engine::run_scan(**rig, *session, engine::CaptureOptions{}, nullptr, cancel);
  ASSERT_TRUE(outcome.ok()) << outcome.status().message();
  EXPECT_GT(outcome->patterns, 0u);
  auto outs = session->outputs();
  ASSERT_TRUE(outs.ok()) << outs.status().message();

  const uint32_t cw = rig_json["cameras"][0]["width"], ch = rig_json["cameras"][0]["height"];
  const double pw = rig_json["projector"]["width"];
  const host::Output* col = nullptr;
  const host::Output* valid = nullptr;
  for (const auto& o : *outs) {
    if (o.name == "proj_col_px") col = &o;
    if (o.name == "valid") valid = &o;
  }
  ASSERT_NE(col, nullptr) << "every decoder must output proj_col_px";
  ASSERT_EQ(col->kind, PROCAM_OUTPUT_IMAGE);
  ASSERT_EQ(col->image.pixel_type, PROCAM_PIXEL_F32);
  ASSERT_EQ(col->image.width, cw);
  ASSERT_EQ(col->image.height, ch);
  const Image cols = Image::copy_of(col->image);
  for (uint32_t y = 0; y < ch; ++y)
    for (uint32_t x = 0; x < cw; ++x) {
      const float v = cols.at<float>(x, y);
      if (std::isnan(v)) continue;
      ASSERT_TRUE(std::isfinite(v) && v >= -0.5f && static_cast<double>(v) <= pw - 0.5) << x << "," << y << ": " << v;
    }
  if (valid != nullptr) {
    const Image vm = Image::copy_of(valid->image);
    for (uint32_t y = 0; y < ch; ++y)
      for (uint32_t x = 0; x < cw; ++x)
        ASSERT_EQ(vm.at<uint8_t>(x, y) == 255, std::isfinite(cols.at<float>(x, y))) << x << "," << y;
  }
  for (const auto& o : *outs) {
    if (o.name == "confidence") {
      const Image m = Image::copy_of(o.image);
      for (uint32_t y = 0; y < ch; ++y)
        for (uint32_t x = 0; x < cw; ++x) {
          const float v = m.at<float>(x, y);
          ASSERT_TRUE(std::isfinite(v) && v >= 0.0f && v <= 1.0f) << x << "," << y;
        }
    }
    if (o.name == "depth_mm") {
      const Image m = Image::copy_of(o.image);
      for (uint32_t y = 0; y < ch; ++y)
        for (uint32_t x = 0; x < cw; ++x) {
          const float v = m.at<float>(x, y);
          ASSERT_TRUE(std::isnan(v) || (std::isfinite(v) && v > 0.0f)) << x << "," << y;
        }
    }
    if (o.name == "pattern_count") {
      EXPECT_EQ(o.scalar, static_cast<double>(outcome->patterns));
    }
    if (o.name == "report") {
      const nlohmann::json r = nlohmann::json::parse(o.json, nullptr, false);
      ASSERT_FALSE(r.is_discarded());
      EXPECT_EQ(r.value("method", ""), c.method);
    }
  }
  if (c.scene == "plane") {
    auto truth = (*rig)->ground_truth(0);
    ASSERT_TRUE(truth.ok());
    const nlohmann::json e = engine::evaluate_correspondence(cols, nullptr, *truth);
    EXPECT_GE(e["within_1col_fraction"].get<double>(), 0.95) << e.dump();
    EXPECT_LE(e["gross_error_fraction"].get<double>(), 0.005) << e.dump();
  }
}

INSTANTIATE_TEST_SUITE_P(AllPluginMethods, Conformance, ::testing::ValuesIn(all_cases()),
                         [](const ::testing::TestParamInfo<Case>& i) {
                           std::string n = i.param.plugin + "_" + i.param.method + "_" + i.param.scene;
                           for (char& ch : n)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return n;
                         });

}  // namespace
}  // namespace procam
