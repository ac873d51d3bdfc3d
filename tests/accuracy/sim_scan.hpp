// SPDX-License-Identifier: MIT
// Shared by the accuracy suites that run a plugin through the real path on a
// sim rig: plan -> sim capture -> streaming decode -> outputs, plus the rig's
// ground truth. Test-only (gtest assertions inside).
//
// Contract: the rig config is read from configs/rigs/<rig_file>; scene names
// resolve in `scene_dirs` first, then configs/scenes. `scale` divides the
// camera's and projector's width, height and focal lengths alike (same
// fields of view, fewer pixels) to keep tests short.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

namespace procam::testing {

inline std::string source_path(const std::string& rel) { return std::string(PROCAM_SOURCE_DIR) + "/" + rel; }

struct ScanRun {
  std::unique_ptr<hw::Rig> rig;
  std::optional<host::Session> session;
  std::vector<host::Output> outputs;
  hw::GroundTruth truth;
};

struct RigChoice {
  std::string rig_file = "sim.json";    // under configs/rigs
  int scale = 1;                        // divide resolution and focal lengths by this
  double exposure_us = 0;               // > 0: every camera's exposure
  std::vector<std::string> scene_dirs;  // searched before configs/scenes
  // Applied to the rig config last (e.g. a camera's noise, bit depth, seed).
  std::function<void(nlohmann::json&)> edit;
};

// `choice.rig_file` at 1/scale resolution showing `scene`; nullptr (and a
// test failure) on error.
inline std::unique_ptr<hw::Rig> scaled_rig(const std::string& scene, const RigChoice& choice) {
  auto cfg = engine::read_json_file(source_path("configs/rigs/" + choice.rig_file));
  EXPECT_TRUE(cfg.ok()) << cfg.status().message();
  if (!cfg.ok()) return nullptr;
  const int s = choice.scale;
  auto shrink = [s](nlohmann::json& k) {
    k["width"] = k["width"].get<int>() / s;
    k["height"] = k["height"].get<int>() / s;
    k["fx"] = k["fx"].get<double>() / s;
    k["fy"] = k["fy"].get<double>() / s;
    k["cx"] = (k["width"].get<double>() - 1.0) / 2.0;
    k["cy"] = (k["height"].get<double>() - 1.0) / 2.0;
  };
  if (s > 1) shrink((*cfg)["projector"]["intrinsics"]);
  for (auto& c : (*cfg)["cameras"]) {
    if (s > 1) shrink(c["intrinsics"]);
    if (choice.exposure_us > 0) c["exposure_us"] = choice.exposure_us;
  }
  if (choice.edit) choice.edit(*cfg);
  std::vector<std::string> dirs = choice.scene_dirs;
  dirs.push_back(source_path("configs/scenes"));
  auto rig = hw::create_rig(*cfg, {source_path("configs/rigs"), dirs});
  EXPECT_TRUE(rig.ok()) << rig.status().message();
  if (!rig.ok()) return nullptr;
  const Status st = (*rig)->apply_scan_options({{"scene", scene}});
  EXPECT_TRUE(st.ok()) << st.to_string();
  return st.ok() ? std::move(*rig) : nullptr;
}

// One scan of plugin/method with `params` on the rig already in r.rig
// (e.g. made by scaled_rig()), through the real path; fills outputs and the
// rig's ground truth for camera 0.
inline bool run_on_rig(const std::string& plugin, const std::string& method, const nlohmann::json& params,
                       ScanRun& r) {
  if (!r.rig) return false;
  host::PluginHost host;
  host.load_directories({PROCAM_PLUGIN_DIR});
  auto session = host.create_session(plugin, method, params.dump(), engine::plugin_rig_json(*r.rig, 2).dump());
  EXPECT_TRUE(session.ok()) << session.status().to_string();
  if (!session.ok()) return false;
  r.session.emplace(std::move(*session));
  std::atomic<bool> cancel{false};
  auto outcome = engine::run_scan(*r.rig, *r.session, engine::CaptureOptions{}, nullptr, cancel);
  EXPECT_TRUE(outcome.ok()) << outcome.status().to_string();
  if (!outcome.ok()) return false;
  auto outs = r.session->outputs();
  EXPECT_TRUE(outs.ok()) << outs.status().to_string();
  if (!outs.ok()) return false;
  r.outputs = std::move(*outs);
  auto truth = r.rig->ground_truth(0);
  EXPECT_TRUE(truth.ok()) << truth.status().to_string();
  if (!truth.ok()) return false;
  r.truth = std::move(*truth);
  return true;
}

// scaled_rig() + run_on_rig().
inline bool run_scan(const std::string& plugin, const std::string& method, const std::string& scene,
                     const RigChoice& choice, const nlohmann::json& params, ScanRun& r) {
  r.rig = scaled_rig(scene, choice);
  return run_on_rig(plugin, method, params, r);
}

// The F32 image output `name`, or nullptr (and a test failure).
inline const float* output_image(const ScanRun& r, const std::string& name) {
  for (const auto& o : r.outputs)
    if (o.kind == PROCAM_OUTPUT_IMAGE && o.name == name && o.image.pixel_type == PROCAM_PIXEL_F32)
      return static_cast<const float*>(o.image.data);
  ADD_FAILURE() << "no F32 output " << name;
  return nullptr;
}

// The scalar output `name`; NaN when absent.
inline double output_scalar(const ScanRun& r, const std::string& name) {
  for (const auto& o : r.outputs)
    if (o.kind == PROCAM_OUTPUT_SCALAR && o.name == name) return o.scalar;
  return std::nan("");
}

// The `report` JSON output (null when absent or unparsable).
inline nlohmann::json output_report(const ScanRun& r) {
  for (const auto& o : r.outputs)
    if (o.kind == PROCAM_OUTPUT_JSON && o.name == "report") return nlohmann::json::parse(o.json, nullptr, false);
  return nullptr;
}

}  // namespace procam::testing
