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

using test::lens_of;
using test::Scanned;
nlohmann::json rig_config() { return test::sim_rig_config(); }

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
  const nlohmann::json cfg = rig_config();
  Intrinsics K, Kp;
  from_json(cfg["cameras"][0]["intrinsics"], K);
  from_json(cfg["projector"]["intrinsics"], Kp);
  Rigid3 cam_from_proj;
  from_json(cfg["cameras"][0]["cam_from_proj"], cam_from_proj);
  const Rigid3 proj_from_cam = cam_from_proj.inverse();
  double sum2[2] = {0, 0}, worst[2] = {0, 0}, mean[2][2] = {{0, 0}, {0, 0}};
  size_t n = 0;
  for (int k = 0; k < kPoses; ++k) {
    auto scene = sim::load_scene(PROCAM_SOURCE_DIR "/configs/scenes/calib/board-" + std::to_string(k) + ".json", {});
    ASSERT_TRUE(scene.ok()) << scene.status().to_string();
    const auto& obj = scene->objects[0];
    const auto& plane = std::get<sim::Plane>(obj.shape);
    std::vector<std::array<double, 4>> truth;  // camera u, v; projector u, v
    for (int rr = 0; rr < kBoard.rows; ++rr)
      for (int c = 0; c < kBoard.cols; ++c) {
        const Vec3 X = sim::board_corner_world(*obj.texture, plane, c, rr);  // world = camera frame
        std::array<double, 4> t{};
        K.project(X, t[0], t[1]);
        Kp.project(proj_from_cam * X, t[2], t[3]);
        truth.push_back(t);
      }
    const ViewReport& v = r->views[static_cast<size_t>(k)];
    for (size_t i = 0; i < v.cam_corners.size(); ++i) {
      const double cu = static_cast<double>(v.cam_corners[i][0]), cv_ = static_cast<double>(v.cam_corners[i][1]);
      size_t best = 0;  // OpenCV may number the board from either end: match the nearest
      for (size_t j = 1; j < truth.size(); ++j)
        if (std::hypot(cu - truth[j][0], cv_ - truth[j][1]) < std::hypot(cu - truth[best][0], cv_ - truth[best][1]))
          best = j;
      const double d[2][2] = {{cu - truth[best][0], cv_ - truth[best][1]},
                              {static_cast<double>(v.proj_corners[i][0]) - truth[best][2],
                               static_cast<double>(v.proj_corners[i][1]) - truth[best][3]}};
      for (int dev = 0; dev < 2; ++dev) {
        const double e = std::hypot(d[dev][0], d[dev][1]);
        sum2[dev] += e * e;
        worst[dev] = std::max(worst[dev], e);
        mean[dev][0] += d[dev][0];
        mean[dev][1] += d[dev][1];
      }
      ++n;
    }
  }
  const double nn = static_cast<double>(n);
  const char* who[2] = {"camera", "projector"};
  for (int dev = 0; dev < 2; ++dev)
    std::printf("%s corners vs truth: %zu corners, RMS %.3f px, worst %.3f px, mean offset (%.3f, %.3f) px\n",
                who[dev], n, std::sqrt(sum2[dev] / nn), worst[dev], mean[dev][0] / nn, mean[dev][1] / nn);
  EXPECT_GT(n, 8u * 50u);
  EXPECT_LT(std::sqrt(sum2[0] / nn), 0.1);
  EXPECT_LT(worst[0], 0.3);
  EXPECT_LT(std::sqrt(sum2[1] / nn), 0.3);
  EXPECT_LT(worst[1], 1.0);
}

TEST_F(SimCalibration, RecoversTheRigConfig) {
  ASSERT_EQ(scanned_->views.size(), size_t{kPoses});
  auto r = calibrate(scanned_->views, kBoard, kProjW, kProjH);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  std::printf("%s", report_markdown(*r).c_str());
  for (const ViewReport& v : r->views) EXPECT_TRUE(v.used) << v.name << ": " << v.rejected_because;
  const nlohmann::json cfg = rig_config();
  const LensModel cam = lens_of(cfg["cameras"][0]["intrinsics"]);
  const LensModel proj = lens_of(cfg["projector"]["intrinsics"]);
  test::print_lens("camera", r->camera, cam);
  test::print_lens("projector", r->projector, proj);
  test::expect_intrinsics_within(r->camera, cam, 0.005, "camera");
  test::expect_intrinsics_within(r->projector, proj, 0.005, "projector");
  const double cam_field = test::distortion_field_error_px(*r, r->camera, cam, false);
  const double proj_field = test::distortion_field_error_px(*r, r->projector, proj, true);
  std::printf("distortion field error over the covered points: camera %.3f px, projector %.3f px\n", cam_field,
              proj_field);
  EXPECT_LT(cam_field, 0.5) << "camera lens model over the covered image";
  EXPECT_LT(proj_field, 0.5) << "projector lens model over the covered image";

  const auto& e = cfg["cameras"][0]["cam_from_proj"]["euler_deg"];
  const cv::Matx33d R_true = test::rot(e[0].get<double>(), e[1].get<double>(), e[2].get<double>());
  const auto& tt = cfg["cameras"][0]["cam_from_proj"]["translation_mm"];
  const cv::Vec3d t_true(tt[0].get<double>(), tt[1].get<double>(), tt[2].get<double>());
  const cv::Matx33d R(r->cam_from_proj_rotation.data());
  const cv::Vec3d t(r->cam_from_proj_translation_mm.data());
  std::printf("cam_from_proj: rotation off by %.4f deg, translation off by %.3f mm (t = %.2f %.2f %.2f)\n",
              test::angle_deg(R, R_true), cv::norm(t - t_true), t[0], t[1], t[2]);
  EXPECT_LT(test::angle_deg(R, R_true), 0.05) << "cam_from_proj rotation";
  EXPECT_LT(cv::norm(t - t_true), 0.5) << "cam_from_proj translation: " << t;
  EXPECT_LT(r->stereo_rms_px, 0.3);
  std::printf("squares triangulated: mean %.3f mm, RMS error %.3f mm (%zu pairs)\n", r->square.mean_mm,
              r->square.rms_error_mm, r->square.pairs);
  EXPECT_NEAR(r->square.mean_mm, kBoard.square_mm, 0.05);
  EXPECT_LT(r->square.rms_error_mm, 0.2);
}

}  // namespace
}  // namespace procam::calibration
