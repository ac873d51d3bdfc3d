// SPDX-License-Identifier: MIT
// ChArUco calibration end to end against the sim's truth (issue 16 item 1).
// The board bitmap is drawn here by OpenCV (cv::aruco::CharucoBoard::draw:
// 10 x 8 squares of 30 mm, 20 mm DICT_4X4_50 markers (5 mm margins keep
// the corner refinement window off the markers' edges), 10 bitmap px per mm so
// square edges fall on bitmap pixel boundaries) inside a 30 mm white border,
// and printed on the eight calibration plates as an image texture
// (hw/sim/SCENES.md "image"; the sim itself does not link OpenCV). Two more
// poses, plates 1 and 2 moved, show only part of the board: a ChArUco view
// is used with the corners it shows. The distorted sim rig scans
// every pose (sim_scan_util.hpp) and the calibration is compared with the
// rig config that rendered the frames. Tolerances (issue 16): intrinsics
// within 0.5 %, cam_from_proj within 0.5 mm and 0.05 degrees.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <array>
#include <filesystem>
#include <fstream>
#include <map>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/core.hpp>

#include "calibration_test_util.hpp"
#include "sim_scan_util.hpp"
#include "procam/calibration/geometric.hpp"
#include "procam/hw/sim/scene.hpp"

namespace procam::calibration {
namespace {
namespace fs = std::filesystem;

constexpr int kPoses = 10;  // the eight calibration plates, then 1 and 2 again, moved (kShift)
constexpr int kPxPerMm = 10;
constexpr double kSquare = 30, kMarker = 20, kBorder = 30;  // mm
// 10 x 8 squares = 9 x 7 inner corners.
BoardSpec charuco_board(const std::string& dict = "DICT_4X4_50") {
  BoardSpec b;
  b.type = BoardType::charuco;
  b.cols = 9;
  b.rows = 7;
  b.square_mm = kSquare;
  b.marker_mm = kMarker;
  b.dictionary = dict;
  return b;
}
// Poses 8 and 9: plates 1 and 2 with their centres moved (mm, camera frame)
// so that part of the board leaves the camera's view.
const std::map<int, std::array<double, 2>> kShift = {{8, {170, 0}}, {9, {0, 140}}};
int plate_of(int pose) { return pose < 8 ? pose : pose - 7; }

// OpenCV's ChArUco drawing, framed by a white border, as a binary PGM.
void write_board_pgm(const std::string& path) {
  const auto board = cv::aruco::CharucoBoard::create(10, 8, static_cast<float>(kSquare), static_cast<float>(kMarker),
                                                      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50));
  cv::Mat img;
  board->draw(cv::Size(10 * 30 * kPxPerMm, 8 * 30 * kPxPerMm), img, 0, 1);
  const int b = static_cast<int>(kBorder) * kPxPerMm;
  cv::copyMakeBorder(img, img, b, b, b, b, cv::BORDER_CONSTANT, cv::Scalar(255));
  std::ofstream out(path, std::ios::binary);
  out << "P5\n" << img.cols << " " << img.rows << "\n255\n";
  for (int r = 0; r < img.rows; ++r) out.write(reinterpret_cast<const char*>(img.ptr(r)), img.cols);
}

// configs/scenes/calib/board-k.json with the image texture (and kShift).
std::string write_scenes(const std::string& dir) {
  fs::create_directories(dir + "/calib");
  write_board_pgm(dir + "/calib/charuco.pgm");
  for (int k = 0; k < kPoses; ++k) {
    const std::string name = "board-" + std::to_string(k);
    std::ifstream in(PROCAM_SOURCE_DIR "/configs/scenes/calib/board-" + std::to_string(plate_of(k)) + ".json");
    nlohmann::json j = nlohmann::json::parse(in);
    auto& o = j["objects"][0];
    o["texture"] = {{"type", "image"}, {"file", "charuco.pgm"}, {"size_mm", {360, 300}}, {"dark", 0.08},
                    {"light", 0.85}};
    if (auto s = kShift.find(k); s != kShift.end()) {
      o["point_mm"][0] = o["point_mm"][0].get<double>() + s->second[0];
      o["point_mm"][1] = o["point_mm"][1].get<double>() + s->second[1];
    }
    std::ofstream(dir + "/calib/" + name + ".json") << j.dump(1);
  }
  return dir;
}

class CharucoSimCalibration : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scenes_ = (fs::temp_directory_path() / ("procam_charuco_scenes_" + std::to_string(::getpid()))).string();
    write_scenes(scenes_);
    std::vector<std::string> names;
    for (int k = 0; k < kPoses; ++k) names.push_back("calib/board-" + std::to_string(k));
    scanned_ = new test::Scanned(test::scan_sim_poses(scenes_, names, "charuco16"));
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(scanned_->dir, ec);
    fs::remove_all(scenes_, ec);
    delete scanned_;
  }
  static test::Scanned* scanned_;
  static std::string scenes_;
};
test::Scanned* CharucoSimCalibration::scanned_ = nullptr;
std::string CharucoSimCalibration::scenes_;

// Every measured corner lies where the scene's geometry and the lenses put
// the nearest true inner corner (a = (c - 4) 30 mm, b = (r - 3) 30 mm on the
// plate: the bitmap's squares are centred like the chessboard texture's).
TEST_F(CharucoSimCalibration, CornersMatchTheSceneGeometry) {
  ASSERT_EQ(scanned_->views.size(), size_t{kPoses});
  const BoardSpec board = charuco_board();
  if (const char* dbg = std::getenv("PROCAM_CHARUCO_DUMP")) {  // debugging aid: the white images as PGM
    for (const View& v : scanned_->views) {
      std::ofstream out(std::string(dbg) + "/" + v.name + ".pgm", std::ios::binary);
      out << "P5\n" << v.width << " " << v.height << "\n255\n";
      out.write(reinterpret_cast<const char*>(v.white.data()), static_cast<std::streamsize>(v.white.size()));
    }
  }
  auto r = calibrate(scanned_->views, board, test::kSimProjW, test::kSimProjH);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const nlohmann::json cfg = test::sim_rig_config();
  Intrinsics K, Kp;
  from_json(cfg["cameras"][0]["intrinsics"], K);
  from_json(cfg["projector"]["intrinsics"], Kp);
  Rigid3 cam_from_proj;
  from_json(cfg["cameras"][0]["cam_from_proj"], cam_from_proj);
  const Rigid3 proj_from_cam = cam_from_proj.inverse();
  double sum2[2] = {0, 0}, worst[2] = {0, 0};
  size_t n = 0;
  for (int k = 0; k < kPoses; ++k) {
    auto scene = sim::load_scene(scenes_ + "/calib/board-" + std::to_string(k) + ".json", {});
    ASSERT_TRUE(scene.ok()) << scene.status().to_string();
    const auto& plane = std::get<sim::Plane>(scene->objects[0].shape);
    std::vector<std::array<double, 4>> truth;  // camera u, v; projector u, v
    for (int rr = 0; rr < board.rows; ++rr)
      for (int c = 0; c < board.cols; ++c) {
        const Vec3 X = plane.point_mm + plane.u_axis * ((c - 4) * kSquare) + plane.v_axis * ((rr - 3) * kSquare);
        std::array<double, 4> t{};
        K.project(X, t[0], t[1]);
        Kp.project(proj_from_cam * X, t[2], t[3]);
        truth.push_back(t);
      }
    const ViewReport& v = r->views[static_cast<size_t>(k)];
    for (size_t i = 0; i < v.cam_corners.size(); ++i) {
      const double cu = static_cast<double>(v.cam_corners[i][0]), cv_ = static_cast<double>(v.cam_corners[i][1]);
      const double pu = static_cast<double>(v.proj_corners[i][0]), pv = static_cast<double>(v.proj_corners[i][1]);
      size_t best = 0;
      for (size_t j = 1; j < truth.size(); ++j)
        if (std::hypot(cu - truth[j][0], cv_ - truth[j][1]) < std::hypot(cu - truth[best][0], cv_ - truth[best][1]))
          best = j;
      const double e[2] = {std::hypot(cu - truth[best][0], cv_ - truth[best][1]),
                           std::hypot(pu - truth[best][2], pv - truth[best][3])};
      for (int dev = 0; dev < 2; ++dev) {
        sum2[dev] += e[dev] * e[dev];
        worst[dev] = std::max(worst[dev], e[dev]);
      }
      ++n;
    }
  }
  const double nn = static_cast<double>(n);
  std::printf("ChArUco corners vs truth: %zu corners; camera RMS %.3f px, worst %.3f px; projector RMS %.3f px, "
              "worst %.3f px\n",
              n, std::sqrt(sum2[0] / nn), worst[0], std::sqrt(sum2[1] / nn), worst[1]);
  EXPECT_GT(n, 6u * 50u);
  EXPECT_LT(std::sqrt(sum2[0] / nn), 0.1);
  EXPECT_LT(worst[0], 0.3);
  EXPECT_LT(std::sqrt(sum2[1] / nn), 0.3);
  EXPECT_LT(worst[1], 1.0);
}

TEST_F(CharucoSimCalibration, RecoversTheRigConfigFromPartialViews) {
  ASSERT_EQ(scanned_->views.size(), size_t{kPoses});
  // A ninth view with the board nowhere in sight: rejected with the reason.
  std::vector<View> views = scanned_->views;
  View blank = views[0];
  blank.name = "blank";
  std::fill(blank.white.begin(), blank.white.end(), uint8_t{200});
  views.push_back(blank);
  const BoardSpec board = charuco_board();
  auto r = calibrate(views, board, test::kSimProjW, test::kSimProjH);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  std::printf("%s", report_markdown(*r).c_str());
  for (int k = 0; k < kPoses; ++k) {
    const ViewReport& v = r->views[static_cast<size_t>(k)];
    EXPECT_TRUE(v.used) << v.name << ": " << v.rejected_because;
    if (kShift.count(k)) {
      EXPECT_LT(v.corners, 63 * 9 / 10) << v.name << " should show only part of the board";
    }
  }
  EXPECT_FALSE(r->views.back().used);
  EXPECT_NE(r->views.back().rejected_because.find("0 corners found (need >= 6"), std::string::npos)
      << r->views.back().rejected_because;

  const nlohmann::json cfg = test::sim_rig_config();
  const LensModel cam = test::lens_of(cfg["cameras"][0]["intrinsics"]);
  const LensModel proj = test::lens_of(cfg["projector"]["intrinsics"]);
  test::print_lens("camera", r->camera, cam);
  test::print_lens("projector", r->projector, proj);
  test::expect_intrinsics_within(r->camera, cam, 0.005, "camera");
  test::expect_intrinsics_within(r->projector, proj, 0.005, "projector");
  const double cam_field = test::distortion_field_error_px(*r, r->camera, cam, false);
  const double proj_field = test::distortion_field_error_px(*r, r->projector, proj, true);
  std::printf("distortion field error over the covered points: camera %.3f px, projector %.3f px\n", cam_field,
              proj_field);
  EXPECT_LT(cam_field, 0.5);
  EXPECT_LT(proj_field, 0.5);
  const auto& e = cfg["cameras"][0]["cam_from_proj"]["euler_deg"];
  const cv::Matx33d R_true = test::rot(e[0].get<double>(), e[1].get<double>(), e[2].get<double>());
  const auto& tt = cfg["cameras"][0]["cam_from_proj"]["translation_mm"];
  const cv::Vec3d t_true(tt[0].get<double>(), tt[1].get<double>(), tt[2].get<double>());
  const cv::Matx33d R(r->cam_from_proj_rotation.data());
  const cv::Vec3d t(r->cam_from_proj_translation_mm.data());
  std::printf("cam_from_proj: rotation off by %.4f deg, translation off by %.3f mm (t = %.2f %.2f %.2f)\n",
              test::angle_deg(R, R_true), cv::norm(t - t_true), t[0], t[1], t[2]);
  EXPECT_LT(test::angle_deg(R, R_true), 0.05);
  EXPECT_LT(cv::norm(t - t_true), 0.5) << t;
  std::printf("squares triangulated: mean %.3f mm, RMS error %.3f mm (%zu pairs)\n", r->square.mean_mm,
              r->square.rms_error_mm, r->square.pairs);
  EXPECT_NEAR(r->square.mean_mm, kSquare, 0.05);
}

// A board given with the wrong dictionary finds no corners anywhere: every
// view is rejected with a reason naming the dictionary, and the calibration
// fails saying so.
TEST_F(CharucoSimCalibration, WrongDictionaryRejectsEveryView) {
  ASSERT_EQ(scanned_->views.size(), size_t{kPoses});
  auto r = calibrate(scanned_->views, charuco_board("DICT_6X6_50"), test::kSimProjW, test::kSimProjH);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("DICT_6X6_50"), std::string::npos) << r.status().to_string();
}

}  // namespace
}  // namespace procam::calibration
