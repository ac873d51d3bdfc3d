// SPDX-License-Identifier: MIT
// Geometric calibration against known truth: views rendered here in closed
// form from a chosen camera, projector (both with lens distortion) and pose,
// so every fitted parameter has a true value.
//  - white image: the chessboard seen through the distorted camera, 2x2
//    supersampled, sensor noise sigma 2 DN;
//  - proj_col / proj_row: each camera pixel's board point projected into the
//    distorted projector and rounded to integers, as a Gray-code decode gives.
// Tolerances (issue 16 item 1): intrinsics within 0.5 %, cam_from_proj within
// 0.5 mm and 0.05 degrees; the board's squares triangulate to their size.
#include "procam/calibration/geometric.hpp"

#include "calibration_test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace procam::calibration {
namespace {

using test::angle_deg;
using test::D_of;
using test::K_of;
using test::kPi;
using test::rot;
constexpr uint32_t kCamW = 800, kCamH = 640, kProjW = 640, kProjH = 480;
const BoardSpec kBoard{9, 7, 30.0};

struct Truth {
  LensModel cam{kCamW, kCamH, 1100, 1098, 405, 318, {-0.15, 0.08, 0.001, -0.0008, 0.0}};
  LensModel proj{kProjW, kProjH, 760, 762, 322, 300, {0.04, -0.02, 0.0005, 0.0003, 0.0}};
  cv::Matx33d R = rot(3, -15, 1);  // cam_from_proj: x_cam = R x_proj + t
  cv::Vec3d t{200, -10, 30};
};

// Undistorted normalised rays of camera points (iterated to 1e-10).
std::vector<cv::Point2f> rays(const std::vector<cv::Point2f>& px, const Truth& T) {
  std::vector<cv::Point2f> n;
  cv::undistortPoints(px, n, K_of(T.cam), D_of(T.cam), cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-10));
  return n;
}

// Board coordinates (mm) where camera ray (x, y, 1) meets the board at pose
// (Rb, tb) (board -> camera); false when it misses in front.
bool board_hit(cv::Point2f r, const cv::Matx33d& Rb, const cv::Vec3d& tb, cv::Vec3d& P, double& bx, double& by) {
  const cv::Vec3d d(r.x, r.y, 1.0), n(Rb(0, 2), Rb(1, 2), Rb(2, 2));
  const double den = n.dot(d);
  if (std::abs(den) < 1e-12) return false;
  const double s = n.dot(tb) / den;
  if (!(s > 0)) return false;
  P = d * s;
  const cv::Vec3d b = Rb.t() * (P - tb);
  bx = b[0], by = b[1];
  return true;
}

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

View render(const Truth& T, const cv::Matx33d& Rb, const cv::Vec3d& tb, const std::string& name, uint32_t seed) {
  View v;
  v.name = name;
  v.width = kCamW;
  v.height = kCamH;
  const size_t n = size_t{kCamW} * kCamH;
  // White: 2x2 samples per pixel.
  std::vector<cv::Point2f> sub;
  sub.reserve(4 * n);
  for (uint32_t y = 0; y < kCamH; ++y)
    for (uint32_t x = 0; x < kCamW; ++x)
      for (float oy : {-0.25f, 0.25f})
        for (float ox : {-0.25f, 0.25f}) sub.emplace_back(static_cast<float>(x) + ox, static_cast<float>(y) + oy);
  const std::vector<cv::Point2f> sub_rays = rays(sub, T);
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, 2.f);
  v.white.resize(n);
  for (size_t i = 0; i < n; ++i) {
    float sum = 0;
    for (size_t k = 0; k < 4; ++k) {
      cv::Vec3d P;
      double bx, by;
      sum += board_hit(sub_rays[4 * i + k], Rb, tb, P, bx, by) ? reflectance(bx, by) : 60.f;
    }
    v.white[i] = static_cast<uint8_t>(std::clamp(sum / 4 + noise(rng), 0.f, 255.f));
  }
  // Projector maps at pixel centres.
  std::vector<cv::Point2f> centres;
  centres.reserve(n);
  for (uint32_t y = 0; y < kCamH; ++y)
    for (uint32_t x = 0; x < kCamW; ++x) centres.emplace_back(static_cast<float>(x), static_cast<float>(y));
  const std::vector<cv::Point2f> centre_rays = rays(centres, T);
  std::vector<cv::Point3f> in_proj;
  std::vector<size_t> idx;
  const double S = kBoard.square_mm;
  for (size_t i = 0; i < n; ++i) {
    cv::Vec3d P;
    double bx, by;
    if (!board_hit(centre_rays[i], Rb, tb, P, bx, by)) continue;
    if (bx < -2 * S || bx >= (kBoard.cols + 1) * S || by < -2 * S || by >= (kBoard.rows + 1) * S) continue;
    const cv::Vec3d q = T.R.t() * (P - T.t);  // projector frame
    if (!(q[2] > 0)) continue;
    in_proj.emplace_back(static_cast<float>(q[0]), static_cast<float>(q[1]), static_cast<float>(q[2]));
    idx.push_back(i);
  }
  std::vector<cv::Point2f> pp;
  cv::projectPoints(in_proj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K_of(T.proj), D_of(T.proj), pp);
  v.proj_col.assign(n, NAN);
  v.proj_row.assign(n, NAN);
  for (size_t k = 0; k < idx.size(); ++k) {
    const float c = std::round(pp[k].x), r = std::round(pp[k].y);
    if (c < 0 || r < 0 || c > kProjW - 1 || r > kProjH - 1) continue;
    v.proj_col[idx[k]] = c;
    v.proj_row[idx[k]] = r;
  }
  return v;
}

// Poses: board origin (first inner corner) so that the board's centre sits
// near (0, 0, z) in the camera frame, tilted in different directions.
std::vector<View> views(const Truth& T) {
  const double S = kBoard.square_mm;
  const cv::Vec3d centre_b(4 * S, 3 * S, 0);
  struct Pose {
    double rx, ry, rz, x, y, z;
  };
  const Pose poses[] = {{0, 0, 0, 0, 0, 650},      {25, 0, 5, -20, 10, 620},  {-20, 15, 0, 15, -10, 700},
                        {0, 28, -6, 10, 5, 640},   {12, -25, 3, -10, 0, 600}, {-18, -15, 10, 0, 15, 720}};
  std::vector<View> out;
  uint32_t seed = 1;
  for (const Pose& p : poses) {
    const cv::Matx33d Rb = rot(p.rx, p.ry, p.rz);
    const cv::Vec3d tb = cv::Vec3d(p.x, p.y, p.z) - Rb * centre_b;
    out.push_back(render(T, Rb, tb, "pose" + std::to_string(seed), seed));
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
