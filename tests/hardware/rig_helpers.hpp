// SPDX-License-Identifier: MIT
// Helpers shared by the sync tests and the sync benchmark: rigs from the
// shipped configs, and a sim projector paired with a real Aravis camera.
#pragma once

#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "procam/hw/aravis/aravis_camera.hpp"
#include "procam/hw/rig.hpp"

namespace procam::testing {

inline nlohmann::json read_rig(const std::string& name) {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/" + name);
  return nlohmann::json::parse(in);
}

inline hw::RigContext ctx() {
  hw::RigContext c;
  c.config_dir = std::string(PROCAM_SOURCE_DIR) + "/configs/rigs";
  c.scene_dirs = {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"};
  return c;
}

inline std::unique_ptr<hw::Rig> make_rig(const std::string& name, const nlohmann::json& patch = {}) {
  auto cfg = read_rig(name);
  if (!patch.is_null()) cfg.merge_patch(patch);
  auto r = hw::create_rig(cfg, ctx());
  if (!r.ok()) std::fprintf(stderr, "make_rig(%s): %s\n", name.c_str(), r.status().to_string().c_str());
  return r.ok() ? std::move(*r) : nullptr;
}

// The sim projector with a real Aravis camera (GigE fake or in-process Fake).
class SimProjectorGvCameraRig final : public hw::Rig {
public:
  SimProjectorGvCameraRig(std::unique_ptr<hw::Rig> sim, std::unique_ptr<aravis::AravisCamera> cam)
      : sim_(std::move(sim)), cam_(std::move(cam)) {}
  hw::Projector& projector() override { return sim_->projector(); }
  size_t camera_count() const override { return 1; }
  hw::Camera& camera(size_t) override { return *cam_; }
  const Intrinsics& projector_intrinsics() const override { return sim_->projector_intrinsics(); }
  const std::vector<CameraCalibration>& camera_calibrations() const override { return sim_->camera_calibrations(); }
  nlohmann::json describe() const override { return {}; }
  Status apply_scan_options(const nlohmann::json&) override { return Status::Ok(); }
  Result<hw::GroundTruth> ground_truth(size_t) override { return Error(Code::unavailable, "none"); }

private:
  std::unique_ptr<hw::Rig> sim_;
  std::unique_ptr<aravis::AravisCamera> cam_;
};

}  // namespace procam::testing
