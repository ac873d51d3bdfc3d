// SPDX-License-Identifier: MIT
// Geometric calibration end to end against the sim's truth (issue 16 item 1):
// the distorted sim rig (configs/rigs/sim-distorted.json: 640x480 camera with
// k1 -0.1, 800x600 projector with k1 0.05) scans the eight chessboard poses
// configs/scenes/calib/board-0..7 with structured-light/gray rows=true,
// recording the frames as a scan with save_frames does; each recorded folder
// is decoded again and calibrated as `procam calibrate-geometry` does. Every
// fitted parameter is compared with the rig config, which rendered the
// frames. Tolerances (issue 16): intrinsics within 0.5 %, cam_from_proj within
// 0.5 mm and 0.05 degrees; distortion by the displacement its model applies
// over the image points the views covered, within 0.5 px of the truth's.
// The small rig keeps the whole test at ~25-35 s on two shared cores (most of
// it rendering and decoding 8 x 40 frames, twice decoded: in the scan and
// again from the recorded folder).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "calibration_test_util.hpp"
#include "sim_scan_util.hpp"
#include "procam/calibration/captures.hpp"
#include "procam/calibration/geometric.hpp"
#include "procam/hw/sim/scene.hpp"
#include "procam/hw/sim/texture.hpp"

namespace procam::calibration {
namespace {
namespace fs = std::filesystem;

constexpr int kPoses = 8;
constexpr uint32_t kProjW = test::kSimProjW, kProjH = test::kSimProjH;
const BoardSpec kBoard{9, 7, 30.0};

using test::Scanned;

Scanned scan_poses() {
  std::vector<std::string> names;
  for (int k = 0; k < kPoses; ++k) names.push_back("calib/board-" + std::to_string(k));
  return test::scan_sim_poses(PROCAM_SOURCE_DIR "/configs/scenes", names, "cal16");
}

class SimCalibration : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { scanned_ = new Scanned(scan_poses()); }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(scanned_->dir, ec);
    delete scanned_;
  }
  static Scanned* scanned_;
};
Scanned* SimCalibration::scanned_ = nullptr;

// The corners the calibration measured lie where the scene's geometry and
// the lenses put them: in the camera (cv::findChessboardCorners on the
// white images: the anti-aliased texture is sub-pixel faithful) and in the
// projector (local homographies of the decoded Gray codes).
TEST_F(SimCalibration, CornersMatchTheSceneGeometry) {
  ASSERT_EQ(scanned_->views.size(), size_t{kPoses});
  auto r = calibrate(scanned_->views, kBoard, kProjW, kProjH);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const test::RigTruth rig = test::RigTruth::load();
  test::CornerErrors errors;
  for (int k = 0; k < kPoses; ++k) {
    auto scene = sim::load_scene(PROCAM_SOURCE_DIR "/configs/scenes/calib/board-" + std::to_string(k) + ".json", {});
    ASSERT_TRUE(scene.ok()) << scene.status().to_string();
    const auto& obj = scene->objects[0];
    const auto& plane = std::get<sim::Plane>(obj.shape);
    std::vector<std::array<double, 4>> truth;  // camera u, v; projector u, v
    for (int rr = 0; rr < kBoard.rows; ++rr)
      for (int c = 0; c < kBoard.cols; ++c)
        truth.push_back(rig.project(sim::board_corner_world(*obj.texture, plane, c, rr)));  // world = camera frame
    errors.add_view(r->views[static_cast<size_t>(k)], truth);
  }
  errors.expect_within_tolerance("chessboard", 8u * 50u);
}

TEST_F(SimCalibration, RecoversTheRigConfig) {
  ASSERT_EQ(scanned_->views.size(), size_t{kPoses});
  auto r = calibrate(scanned_->views, kBoard, kProjW, kProjH);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  std::printf("%s", report_markdown(*r).c_str());
  for (const ViewReport& v : r->views) EXPECT_TRUE(v.used) << v.name << ": " << v.rejected_because;
  test::expect_recovers_rig(*r, kBoard.square_mm);
  EXPECT_LT(r->stereo_rms_px, 0.3);
  EXPECT_LT(r->square.rms_error_mm, 0.2);
}

}  // namespace
}  // namespace procam::calibration
