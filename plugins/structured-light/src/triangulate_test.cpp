// SPDX-License-Identifier: MIT
// Triangulation tests against geometry computed here independently: a plane
// at known depth seen by the camera; each pixel's true projector column comes
// from projecting the plane point into the projector (x_p = R^T (X - t)).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "triangulate.hpp"

namespace procam::sl {
namespace {

struct Geometry {
  CameraCalibration cam;
  Intrinsics proj;
};

Geometry make_geometry() {
  Geometry g;
  g.cam.intrinsics = {320, 240, 400.0, 400.0, 159.5, 119.5};
  g.proj = {640, 400, 700.0, 700.0, 319.5, 199.5};
  // Projector 200 mm to the right of the camera, turned 20 degrees toward it.
  const double a = -20.0 * M_PI / 180.0;
  g.cam.cam_from_proj.rotation = Mat3{{std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0,
                                       std::cos(a)}};
  g.cam.cam_from_proj.translation_mm = {200.0, 0.0, 0.0};
  return g;
}

// Independent forward model: the camera ray of pixel (u, v) meets the plane
// z = z0 + slope * x (camera frame); returns the point and its continuous
// projector column.
void plane_point(const Geometry& g, double u, double v, double z0, double slope, Vec3& X,
                 double& col) {
  const double dx = (u - g.cam.intrinsics.cx) / g.cam.intrinsics.fx;
  const double dy = (v - g.cam.intrinsics.cy) / g.cam.intrinsics.fy;
  const double s = z0 / (1.0 - slope * dx);  // z = s, x = s dx on the plane
  X = {s * dx, s * dy, s};
  const Mat3& R = g.cam.cam_from_proj.rotation;
  const Vec3 d = X - g.cam.cam_from_proj.translation_mm;
  const Vec3 xp = R.transposed() * d;
  col = g.proj.fx * xp.x / xp.z + g.proj.cx;
}

TEST(Triangulate, PlaneAtKnownDepthExactColumns) {
  const Geometry g = make_geometry();
  const uint32_t w = g.cam.intrinsics.width, h = g.cam.intrinsics.height;
  for (double slope : {0.0, 0.3}) {
    std::vector<float> col(size_t{w} * h), intensity(col.size());
    std::vector<Vec3> truth(col.size());
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) {
        const size_t i = size_t{y} * w + x;
        double c;
        plane_point(g, x, y, 400.0, slope, truth[i], c);
        col[i] = static_cast<float>(c);
        intensity[i] = static_cast<float>(i % 7) / 7.0f;
      }
    // Some invalid pixels.
    col[5] = std::numeric_limits<float>::quiet_NaN();
    col[w * 100 + 50] = std::numeric_limits<float>::quiet_NaN();
    const DepthResult r = triangulate_columns(g.cam, g.proj, w, h, col.data(), intensity.data(), 2);
    ASSERT_EQ(r.depth_mm.size(), col.size());
    ASSERT_EQ(r.point_count, col.size() - 2);
    ASSERT_EQ(r.points.size(), r.point_count * 4);
    EXPECT_TRUE(std::isnan(r.depth_mm[5]));
    EXPECT_TRUE(std::isnan(r.depth_mm[w * 100 + 50]));
    // Float column storage (~3e-5 px) bounds the error far below 0.5 mm.
    size_t p = 0;
    double worst = 0;
    for (size_t i = 0; i < col.size(); ++i) {
      if (std::isnan(col[i])) continue;
      worst = std::max(worst, std::abs(static_cast<double>(r.depth_mm[i]) - truth[i].z));
      ASSERT_NEAR(r.points[4 * p + 0], truth[i].x, 0.05) << i;
      ASSERT_NEAR(r.points[4 * p + 1], truth[i].y, 0.05) << i;
      ASSERT_NEAR(r.points[4 * p + 2], truth[i].z, 0.05) << i;
      ASSERT_EQ(r.points[4 * p + 3], intensity[i]);
      ++p;
    }
    EXPECT_LT(worst, 0.05) << "slope " << slope;
  }
}

TEST(Triangulate, ThreadCountDoesNotChangeResult) {
  const Geometry g = make_geometry();
  const uint32_t w = g.cam.intrinsics.width, h = g.cam.intrinsics.height;
  std::vector<float> col(size_t{w} * h);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      Vec3 X;
      double c;
      plane_point(g, x, y, 350.0, 0.1, X, c);
      col[size_t{y} * w + x] = (x + y) % 5 == 0 ? NAN : std::round(static_cast<float>(c));
    }
  const DepthResult a = triangulate_columns(g.cam, g.proj, w, h, col.data(), nullptr, 1);
  const DepthResult b = triangulate_columns(g.cam, g.proj, w, h, col.data(), nullptr, 5);
  ASSERT_EQ(a.points, b.points);
  ASSERT_EQ(a.point_count, b.point_count);
  for (size_t i = 0; i < col.size(); ++i)
    ASSERT_TRUE(a.depth_mm[i] == b.depth_mm[i] ||
                (std::isnan(a.depth_mm[i]) && std::isnan(b.depth_mm[i])));
}

TEST(Triangulate, BehindTheDevicesGivesNoPoint) {
  const Geometry g = make_geometry();
  // Column plane that only meets this ray behind the camera: column far to
  // the projector's left of the camera's optical axis intersection.
  std::vector<float> col = {static_cast<float>(g.proj.cx + 5000.0)};
  const DepthResult r = triangulate_columns(g.cam, g.proj, 1, 1, col.data(), nullptr, 1);
  EXPECT_TRUE(std::isnan(r.depth_mm[0]));
  EXPECT_EQ(r.point_count, 0u);
}

}  // namespace
}  // namespace procam::sl
