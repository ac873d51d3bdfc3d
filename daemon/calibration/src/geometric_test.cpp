// SPDX-License-Identifier: MIT
// Geometric calibration against known truth: views rendered here in closed
// form (closed_form_views.hpp: distorted camera and projector, known pose,
// a chessboard here), so every fitted parameter has a true value.
// Tolerances (issue 16 item 1): intrinsics within 0.5 %, cam_from_proj within
// 0.5 mm and 0.05 degrees; the board's squares triangulate to their size.
#include "procam/calibration/geometric.hpp"

#include "closed_form_views.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace procam::calibration {
namespace {

using test::angle_deg;
using test::kCamH;
using test::kCamW;
using test::kProjH;
using test::kProjW;
using test::Truth;
const BoardSpec kBoard{9, 7, 30.0};

// Reflectance of the board: checkers over the inner-corner grid plus one
// square, a white quiet zone of one square, dark background.
float reflectance(double bx, double by) {
  const double S = kBoard.square_mm;
  const bool board = bx >= -S && bx < kBoard.cols * S && by >= -S && by < kBoard.rows * S;
  const bool margin = bx >= -2 * S && bx < (kBoard.cols + 1) * S && by >= -2 * S && by < (kBoard.rows + 1) * S;
  if (board) {
    const auto i = static_cast<long>(std::floor(bx / S)), j = static_cast<long>(std::floor(by / S));
    return ((i + j) & 1) == 0 ? 30.f : 220.f;
  }
  return margin ? 220.f : 60.f;
}

// Poses: board origin (first inner corner) so that the board's centre sits
// near (0, 0, z) in the camera frame, tilted in different directions.
std::vector<View> views(const Truth& T) {
  const double S = kBoard.square_mm;
  const test::BoardLook look{reflectance, -2 * S, (kBoard.cols + 1) * S, -2 * S, (kBoard.rows + 1) * S};
  const test::Pose poses[] = {{0, 0, 0, 0, 0, 650},      {25, 0, 5, -20, 10, 620},  {-20, 15, 0, 15, -10, 700},
                              {0, 28, -6, 10, 5, 640},   {12, -25, 3, -10, 0, 600}, {-18, -15, 10, 0, 15, 720}};
  std::vector<View> out;
  uint32_t seed = 1;
  for (const test::Pose& p : poses) {
    cv::Matx33d Rb;
    cv::Vec3d tb;
    test::pose_of(p, cv::Vec3d(4 * S, 3 * S, 0), Rb, tb);
    out.push_back(test::render(T, look, Rb, tb, "pose" + std::to_string(seed), seed));
    ++seed;
  }
  return out;
}

class GeometricCalibration : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { views_ = new std::vector<View>(views(Truth{})); }
  static void TearDownTestSuite() { delete views_; }
  static std::vector<View>* views_;
};
std::vector<View>* GeometricCalibration::views_ = nullptr;

TEST_F(GeometricCalibration, RecoversKnownIntrinsicsDistortionAndPose) {
  const Truth T;
  auto r = calibrate(*views_, kBoard, kProjW, kProjH);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  std::printf("%s", report_markdown(*r).c_str());
  for (const ViewReport& v : r->views) EXPECT_TRUE(v.used) << v.name << ": " << v.rejected_because;
  test::expect_intrinsics_within(r->camera, T.cam, 0.005, "camera");
  test::expect_intrinsics_within(r->projector, T.proj, 0.005, "projector");
  EXPECT_LT(test::distortion_field_error_px(*r, r->camera, T.cam, false), 0.5) << "camera lens model over the covered image";
  EXPECT_LT(test::distortion_field_error_px(*r, r->projector, T.proj, true), 0.5)
      << "projector lens model over the covered image";
  const cv::Matx33d R(r->cam_from_proj_rotation.data());
  const cv::Vec3d t(r->cam_from_proj_translation_mm.data());
  EXPECT_LT(angle_deg(R, T.R), 0.05) << "cam_from_proj rotation";
  EXPECT_LT(cv::norm(t - T.t), 0.5) << "cam_from_proj translation: " << t;
  EXPECT_LT(r->stereo_rms_px, 0.3);
  EXPECT_NEAR(r->square.mean_mm, kBoard.square_mm, 0.05);
  EXPECT_LT(r->square.rms_error_mm, 0.2);
  // The rig JSON carries what a rig config needs.
  const nlohmann::json j = to_rig_json(*r);
  EXPECT_EQ(j["cameras"][0]["intrinsics"]["distortion"].size(), 5u);
  EXPECT_EQ(j["cameras"][0]["cam_from_proj"]["rotation"].size(), 9u);
  EXPECT_DOUBLE_EQ(j["projector"]["intrinsics"]["fx"].get<double>(), r->projector.fx);
}

TEST_F(GeometricCalibration, RejectsBadViewsSayingWhyAndFitsTheRest) {
  std::vector<View> vs = *views_;
  View blank = vs[0];
  blank.name = "no-board";
  std::fill(blank.white.begin(), blank.white.end(), uint8_t{128});
  View dark = vs[1];
  dark.name = "projector-off";
  std::fill(dark.proj_col.begin(), dark.proj_col.end(), NAN);
  vs.push_back(blank);
  vs.push_back(dark);
  auto r = calibrate(vs, kBoard, kProjW, kProjH);
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  ASSERT_EQ(r->views.size(), 8u);
  EXPECT_FALSE(r->views[6].used);
  EXPECT_NE(r->views[6].rejected_because.find("not found"), std::string::npos) << r->views[6].rejected_because;
  EXPECT_FALSE(r->views[7].used);
  EXPECT_NE(r->views[7].rejected_because.find("0 of 63 corners"), std::string::npos) << r->views[7].rejected_because;
  EXPECT_LT(r->stereo_rms_px, 0.3);
}

TEST_F(GeometricCalibration, TooFewViewsIsAClearError) {
  std::vector<View> vs(views_->begin(), views_->begin() + 2);
  auto r = calibrate(vs, kBoard, kProjW, kProjH);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::failed_precondition);
  EXPECT_NE(r.status().message().find("usable views, need 3"), std::string::npos) << r.status().to_string();
  auto bad = calibrate(vs, BoardSpec{2, 7, 30}, kProjW, kProjH);
  EXPECT_FALSE(bad.ok());
  View wrong = (*views_)[0];
  wrong.proj_row.resize(10);
  auto sizes = calibrate({wrong, (*views_)[1], (*views_)[2]}, kBoard, kProjW, kProjH);
  ASSERT_FALSE(sizes.ok());
  EXPECT_NE(sizes.status().message().find("mismatched sizes"), std::string::npos);
}

}  // namespace
}  // namespace procam::calibration
