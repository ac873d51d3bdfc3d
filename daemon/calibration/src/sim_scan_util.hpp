// SPDX-License-Identifier: MIT
// Test helper shared by the sim calibration tests (geometric_sim_test,
// charuco_sim_test): the distorted sim rig (configs/rigs/sim-distorted.json)
// scans board poses with structured-light/gray rows=true, recording the frames
// as a scan with save_frames does, and each recorded folder is decoded again
// as `procam calibrate-geometry` does. Single-threaded use; gtest EXPECTs
// report failures, an empty result stops early.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "procam/calibration/captures.hpp"
#include "procam/calibration/geometric.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/hw/rig.hpp"

namespace procam::calibration::test {

constexpr uint32_t kSimProjW = 800, kSimProjH = 600;  // configs/rigs/sim-distorted.json

inline nlohmann::json sim_rig_config() {
  std::ifstream in(PROCAM_SOURCE_DIR "/configs/rigs/sim-distorted.json");
  return nlohmann::json::parse(in);
}

inline LensModel lens_of(const nlohmann::json& k) {
  LensModel m{k.at("width").get<uint32_t>(), k.at("height").get<uint32_t>(), k.at("fx").get<double>(),
              k.at("fy").get<double>(), k.at("cx").get<double>(), k.at("cy").get<double>(), {}};
  const auto d = k.at("distortion").get<std::vector<double>>();
  for (size_t i = 0; i < 5; ++i) m.distortion[i] = d[i];
  return m;
}

struct Scanned {
  std::vector<View> views;
  std::string dir;  // recorded frames, removed by the caller
};

// Scans scenes `names` (looked up in `scene_dir`) through the sim rig,
// recording under a fresh temp folder tagged `tag`, and decodes each
// recorded folder again.
inline Scanned scan_sim_poses(const std::string& scene_dir, const std::vector<std::string>& names,
                              const std::string& tag) {
  namespace fs = std::filesystem;
  Scanned out;
  out.dir = (fs::temp_directory_path() / ("procam_" + tag + "_" + std::to_string(::getpid()))).string();
  fs::remove_all(out.dir);
  auto rig = hw::create_rig(sim_rig_config(), {PROCAM_SOURCE_DIR "/configs/rigs", {scene_dir}});
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  if (!rig.ok()) return out;
  host::PluginHost host(host::LoadOptions{.probe_in_child = false});
  host.load_directories({PROCAM_PLUGIN_DIR});
  const nlohmann::json rig_json = engine::plugin_rig_json(**rig, 2);
  DecodeOptions o;
  o.projector_width = kSimProjW;
  o.projector_height = kSimProjH;
  for (const std::string& name : names) {
    Status st = (*rig)->apply_scan_options({{"scene", name}});
    EXPECT_TRUE(st.ok()) << st.to_string();
    auto session = host.create_session("structured-light", "gray", R"({"rows": true})", rig_json.dump());
    EXPECT_TRUE(session.ok()) << session.status().to_string();
    if (!st.ok() || !session.ok()) return out;
    engine::CaptureOptions co;
    co.record_dir = out.dir + "/" + fs::path(name).filename().string();
    fs::create_directories(co.record_dir);
    std::atomic<bool> cancel{false};
    auto scan = engine::run_scan(**rig, *session, co, nullptr, cancel);
    EXPECT_TRUE(scan.ok()) << scan.status().to_string();
    auto v = decode_capture(host, co.record_dir, o);
    EXPECT_TRUE(v.ok()) << v.status().to_string();
    if (!v.ok()) return out;
    out.views.push_back(std::move(*v));
  }
  return out;
}

}  // namespace procam::calibration::test
