// SPDX-License-Identifier: MIT
// Test helper shared by the sim calibration tests (geometric_sim_test,
// charuco_sim_test): the distorted sim rig (configs/rigs/sim-distorted.json)
// scans board poses with structured-light/gray rows=true, recording the frames
// as a scan with save_frames does, and each recorded folder is decoded again
// as `procam calibrate-geometry` does. Single-threaded use; gtest EXPECTs
// report failures, an empty result stops early. Also the comparisons both
// tests make against the rig config that rendered the frames: measured
// corners against the true corners (CornerErrors), and the fitted model
// against the config (expect_recovers_rig).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "calibration_test_util.hpp"
#include "procam/base/calibration.hpp"
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

// The sim rig's lenses as the renderer applies them: true board corners
// (world = camera frame, mm) projected into camera and projector pixels.
struct RigTruth {
  Intrinsics cam, proj;
  Rigid3 proj_from_cam;
  static RigTruth load() {
    const nlohmann::json cfg = sim_rig_config();
    RigTruth t;
    from_json(cfg["cameras"][0]["intrinsics"], t.cam);
    from_json(cfg["projector"]["intrinsics"], t.proj);
    Rigid3 cam_from_proj;
    from_json(cfg["cameras"][0]["cam_from_proj"], cam_from_proj);
    t.proj_from_cam = cam_from_proj.inverse();
    return t;
  }
  // camera u, v; projector u, v
  std::array<double, 4> project(const Vec3& X) const {
    std::array<double, 4> t{};
    cam.project(X, t[0], t[1]);
    proj.project(proj_from_cam * X, t[2], t[3]);
    return t;
  }
};

// Distances of measured corners (camera and projector) from the true ones.
// Each measured corner is matched to the nearest true corner in the camera:
// OpenCV may number a chessboard from either end, and a ChArUco view may
// show only part of the board.
struct CornerErrors {
  double sum2[2] = {0, 0}, worst[2] = {0, 0}, mean[2][2] = {{0, 0}, {0, 0}};
  size_t n = 0;

  void add_view(const ViewReport& v, const std::vector<std::array<double, 4>>& truth) {
    for (size_t i = 0; i < v.cam_corners.size(); ++i) {
      const double m[4] = {v.cam_corners[i][0], v.cam_corners[i][1], v.proj_corners[i][0], v.proj_corners[i][1]};
      size_t best = 0;
      for (size_t j = 1; j < truth.size(); ++j)
        if (std::hypot(m[0] - truth[j][0], m[1] - truth[j][1]) <
            std::hypot(m[0] - truth[best][0], m[1] - truth[best][1]))
          best = j;
      for (size_t dev = 0; dev < 2; ++dev) {
        const double dx = m[2 * dev] - truth[best][2 * dev], dy = m[2 * dev + 1] - truth[best][2 * dev + 1];
        const double e = std::hypot(dx, dy);
        sum2[dev] += e * e;
        worst[dev] = std::max(worst[dev], e);
        mean[dev][0] += dx;
        mean[dev][1] += dy;
      }
      ++n;
    }
  }

  // Tolerances (issue 16): camera corners RMS < 0.1 px and none beyond
  // 0.3 px (the anti-aliased texture is sub-pixel faithful); projector
  // corners from the decoded codes RMS < 0.3 px, none beyond 1 px.
  void expect_within_tolerance(const char* label, size_t min_corners) const {
    const double nn = static_cast<double>(std::max<size_t>(n, 1));
    const char* who[2] = {"camera", "projector"};
    for (int dev = 0; dev < 2; ++dev)
      std::printf("%s: %s corners vs truth: %zu corners, RMS %.3f px, worst %.3f px, mean offset (%.3f, %.3f) px\n",
                  label, who[dev], n, std::sqrt(sum2[dev] / nn), worst[dev], mean[dev][0] / nn, mean[dev][1] / nn);
    EXPECT_GT(n, min_corners);
    EXPECT_LT(std::sqrt(sum2[0] / nn), 0.1) << label;
    EXPECT_LT(worst[0], 0.3) << label;
    EXPECT_LT(std::sqrt(sum2[1] / nn), 0.3) << label;
    EXPECT_LT(worst[1], 1.0) << label;
  }
};

// The fitted model against the rig config that rendered the frames
// (tolerances, issue 16): intrinsics within 0.5 %, the distortion model's
// displacement over the covered points within 0.5 px of the truth's,
// cam_from_proj within 0.05 degrees and 0.5 mm, triangulated squares within
// 0.05 mm of `square_mm` on average.
inline void expect_recovers_rig(const RigCalibration& r, double square_mm) {
  const nlohmann::json cfg = sim_rig_config();
  const LensModel cam = lens_of(cfg["cameras"][0]["intrinsics"]);
  const LensModel proj = lens_of(cfg["projector"]["intrinsics"]);
  print_lens("camera", r.camera, cam);
  print_lens("projector", r.projector, proj);
  expect_intrinsics_within(r.camera, cam, 0.005, "camera");
  expect_intrinsics_within(r.projector, proj, 0.005, "projector");
  const double cam_field = distortion_field_error_px(r, r.camera, cam, false);
  const double proj_field = distortion_field_error_px(r, r.projector, proj, true);
  std::printf("distortion field error over the covered points: camera %.3f px, projector %.3f px\n", cam_field,
              proj_field);
  EXPECT_LT(cam_field, 0.5) << "camera lens model over the covered image";
  EXPECT_LT(proj_field, 0.5) << "projector lens model over the covered image";
  const auto& e = cfg["cameras"][0]["cam_from_proj"]["euler_deg"];
  const cv::Matx33d R_true = rot(e[0].get<double>(), e[1].get<double>(), e[2].get<double>());
  const auto& tt = cfg["cameras"][0]["cam_from_proj"]["translation_mm"];
  const cv::Vec3d t_true(tt[0].get<double>(), tt[1].get<double>(), tt[2].get<double>());
  const cv::Matx33d R(r.cam_from_proj_rotation.data());
  const cv::Vec3d t(r.cam_from_proj_translation_mm.data());
  std::printf("cam_from_proj: rotation off by %.4f deg, translation off by %.3f mm (t = %.2f %.2f %.2f)\n",
              angle_deg(R, R_true), cv::norm(t - t_true), t[0], t[1], t[2]);
  EXPECT_LT(angle_deg(R, R_true), 0.05) << "cam_from_proj rotation";
  EXPECT_LT(cv::norm(t - t_true), 0.5) << "cam_from_proj translation: " << t;
  std::printf("squares triangulated: mean %.3f mm, RMS error %.3f mm (%zu pairs)\n", r.square.mean_mm,
              r.square.rms_error_mm, r.square.pairs);
  EXPECT_NEAR(r.square.mean_mm, square_mm, 0.05);
}

}  // namespace procam::calibration::test
