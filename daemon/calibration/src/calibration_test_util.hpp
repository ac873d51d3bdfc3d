// SPDX-License-Identifier: MIT
// Test helpers shared by the calibration tests that compare a fitted model
// with known truth (closed-form views, the sim): rotations, angles, and the
// lens-model comparisons. Written with OpenCV, independently of geometric.cpp.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "procam/calibration/geometric.hpp"

namespace procam::calibration::test {

constexpr double kPi = 3.14159265358979323846;

// R = Rz Ry Rx of angles in degrees (the rig config's euler_deg).
inline cv::Matx33d rot(double rx_deg, double ry_deg, double rz_deg) {
  const double a = rx_deg * kPi / 180, b = ry_deg * kPi / 180, c = rz_deg * kPi / 180;
  const cv::Matx33d Rx(1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a));
  const cv::Matx33d Ry(std::cos(b), 0, std::sin(b), 0, 1, 0, -std::sin(b), 0, std::cos(b));
  const cv::Matx33d Rz(std::cos(c), -std::sin(c), 0, std::sin(c), std::cos(c), 0, 0, 0, 1);
  return Rz * Ry * Rx;
}

// Angle of the rotation A^T B, degrees.
inline double angle_deg(const cv::Matx33d& A, const cv::Matx33d& B) {
  const cv::Matx33d D = A.t() * B;
  const double c = std::clamp((D(0, 0) + D(1, 1) + D(2, 2) - 1) / 2, -1.0, 1.0);
  return std::acos(c) * 180 / kPi;
}

inline cv::Mat K_of(const LensModel& m) { return (cv::Mat_<double>(3, 3) << m.fx, 0, m.cx, 0, m.fy, m.cy, 0, 0, 1); }
inline cv::Mat D_of(const LensModel& m) {
  return (cv::Mat_<double>(1, 5) << m.distortion[0], m.distortion[1], m.distortion[2], m.distortion[3],
          m.distortion[4]);
}

// Distortion coefficients trade off against each other (k1, k2, k3), so
// compare what they do: the largest difference between the displacements the
// two models' distortion applies to the image points the used views covered
// (camera or projector corners), each model undistorting into its own pixel
// grid (so fx, cx errors, tested separately, are not counted twice). Pixels.
inline double distortion_field_error_px(const RigCalibration& r, const LensModel& got, const LensModel& truth,
                                        bool projector) {
  std::vector<cv::Point2f> pts, a, b;
  for (const ViewReport& v : r.views)
    for (const auto& c : projector ? v.proj_corners : v.cam_corners) pts.emplace_back(c[0], c[1]);
  if (pts.empty()) return 1e9;
  cv::undistortPoints(pts, a, K_of(got), D_of(got), cv::noArray(), K_of(got));
  cv::undistortPoints(pts, b, K_of(truth), D_of(truth), cv::noArray(), K_of(truth));
  double worst = 0;
  for (size_t i = 0; i < pts.size(); ++i)
    worst = std::max(worst, static_cast<double>(cv::norm((a[i] - pts[i]) - (b[i] - pts[i]))));
  return worst;
}

// fx, fy, cx, cy each within `rel` of the truth.
inline void expect_intrinsics_within(const LensModel& got, const LensModel& truth, double rel, const char* who) {
  EXPECT_NEAR(got.fx, truth.fx, rel * std::abs(truth.fx)) << who << " fx";
  EXPECT_NEAR(got.fy, truth.fy, rel * std::abs(truth.fy)) << who << " fy";
  EXPECT_NEAR(got.cx, truth.cx, rel * std::abs(truth.cx)) << who << " cx";
  EXPECT_NEAR(got.cy, truth.cy, rel * std::abs(truth.cy)) << who << " cy";
}

inline void print_lens(const char* who, const LensModel& got, const LensModel& truth) {
  std::printf("%-9s fx %.2f fy %.2f cx %.2f cy %.2f k [%.4f %.4f %.5f %.5f %.4f]\n", who, got.fx, got.fy, got.cx,
              got.cy, got.distortion[0], got.distortion[1], got.distortion[2], got.distortion[3], got.distortion[4]);
  std::printf("%-9s fx %.2f fy %.2f cx %.2f cy %.2f k [%.4f %.4f %.5f %.5f %.4f]  (truth)\n", "", truth.fx, truth.fy,
              truth.cx, truth.cy, truth.distortion[0], truth.distortion[1], truth.distortion[2], truth.distortion[3],
              truth.distortion[4]);
}

}  // namespace procam::calibration::test
