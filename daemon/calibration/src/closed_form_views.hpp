// SPDX-License-Identifier: MIT
// Test helper: calibration views rendered in closed form from a chosen
// camera, projector (both with lens distortion) and pose, so every fitted
// parameter has a true value. Shared by the chessboard and ChArUco tests.
//  - white image: the board seen through the distorted camera, 2x2
//    supersampled, sensor noise sigma 2 DN; the board's reflectance (grey
//    levels 0..255 at board point (bx, by) mm, corner 0 at the origin) is the
//    caller's;
//  - proj_col / proj_row: each camera pixel's board point (inside the board's
//    extent) projected into the distorted projector and rounded to integers,
//    as a Gray-code decode gives.
// Written with OpenCV, independently of geometric.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "calibration_test_util.hpp"
#include "procam/calibration/geometric.hpp"

namespace procam::calibration::test {

constexpr uint32_t kCamW = 800, kCamH = 640, kProjW = 640, kProjH = 480;

struct Truth {
  LensModel cam{kCamW, kCamH, 1100, 1098, 405, 318, {-0.15, 0.08, 0.001, -0.0008, 0.0}};
  LensModel proj{kProjW, kProjH, 760, 762, 322, 300, {0.04, -0.02, 0.0005, 0.0003, 0.0}};
  cv::Matx33d R = rot(3, -15, 1);  // cam_from_proj: x_cam = R x_proj + t
  cv::Vec3d t{200, -10, 30};
};

// What the renderer needs of a board: reflectance at a board point, and the
// board's extent (mm, [x0, x1) x [y0, y1)) where the projector maps are set.
struct BoardLook {
  std::function<float(double, double)> reflectance;
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  float background = 60.f;  // camera rays that miss the board plane
};

// Undistorted normalised rays of camera points (iterated to 1e-10).
inline std::vector<cv::Point2f> rays(const std::vector<cv::Point2f>& px, const Truth& T) {
  std::vector<cv::Point2f> n;
  cv::undistortPoints(px, n, K_of(T.cam), D_of(T.cam), cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-10));
  return n;
}

// Board coordinates (mm) where camera ray (x, y, 1) meets the board at pose
// (Rb, tb) (board -> camera); false when it misses in front.
inline bool board_hit(cv::Point2f r, const cv::Matx33d& Rb, const cv::Vec3d& tb, cv::Vec3d& P, double& bx,
                      double& by) {
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

inline View render(const Truth& T, const BoardLook& look, const cv::Matx33d& Rb, const cv::Vec3d& tb,
                   const std::string& name, uint32_t seed) {
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
      sum += board_hit(sub_rays[4 * i + k], Rb, tb, P, bx, by) ? look.reflectance(bx, by) : look.background;
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
  for (size_t i = 0; i < n; ++i) {
    cv::Vec3d P;
    double bx, by;
    if (!board_hit(centre_rays[i], Rb, tb, P, bx, by)) continue;
    if (bx < look.x0 || bx >= look.x1 || by < look.y0 || by >= look.y1) continue;
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

// A board pose: rotation (degrees, Rz Ry Rx) and where the board point
// `centre_b` (mm) lands in the camera frame.
struct Pose {
  double rx, ry, rz, x, y, z;
};
inline void pose_of(const Pose& p, const cv::Vec3d& centre_b, cv::Matx33d& Rb, cv::Vec3d& tb) {
  Rb = rot(p.rx, p.ry, p.rz);
  tb = cv::Vec3d(p.x, p.y, p.z) - Rb * centre_b;
}

}  // namespace procam::calibration::test
