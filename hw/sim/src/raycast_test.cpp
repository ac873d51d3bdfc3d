// SPDX-License-Identifier: MIT
// Ray casting (through prepare_view) against analytic depths computed
// independently: planes, spheres, rotated boxes, half-ellipsoid bowls.
#include "procam/hw/sim/raycast.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "procam/hw/sim/renderer.hpp"
#include "test_util.hpp"

namespace procam::sim {
namespace {

// Camera with its principal point on a pixel centre, so pixel (cx, cy) looks
// straight down +z.
CameraCalibration test_camera() {
  CameraCalibration c;
  c.intrinsics = {321, 241, 400.0, 400.0, 160.0, 120.0};
  c.cam_from_proj.translation_mm = {150, 0, 0};
  return c;
}
ProjectorModel test_projector() {
  ProjectorModel p;
  p.intrinsics = {320, 200, 350.0, 350.0, 159.5, 99.5};
  p.aperture_mm = 0;
  return p;
}
Object make(Shape shape) {
  Object o;
  o.shape = std::move(shape);
  o.material.albedo = 0.5;
  return o;
}

TEST(Raycast, FrontoParallelPlaneDepthEverywhere) {
  Scene scene;
  Plane pl;
  pl.point_mm = {10, -20, 800};
  pl.normal = {0, 0, -1};
  scene.objects.push_back(make(pl));
  auto v = prepare_view(scene, test_projector(), test_camera());
  ASSERT_TRUE(v.ok()) << v.status().to_string();
  for (size_t i = 0; i < v->pixel_count(); ++i) ASSERT_NEAR(v->depth_mm[i], 800.0, 1e-3) << "pixel " << i;
  // Points reproject to their own pixel: x = (u - cx) z / fx.
  const size_t i = 37 * 321 + 250;
  EXPECT_NEAR(v->point_mm[3 * i], (250 - 160.0) * 800.0 / 400.0, 1e-3);
  EXPECT_NEAR(v->point_mm[3 * i + 1], (37 - 120.0) * 800.0 / 400.0, 1e-3);
  EXPECT_EQ(v->object[i], 0);
}

TEST(Raycast, SphereDepthMatchesQuadratic) {
  const Vec3 c{20, -10, 700};
  const double r = 90;
  Scene scene;
  scene.objects.push_back(make(Sphere{c, r}));
  const CameraCalibration cam = test_camera();
  auto v = prepare_view(scene, test_projector(), cam);
  ASSERT_TRUE(v.ok());
  // The pixel looking at the sphere centre along its ray: with c on the ray of
  // pixel (u, v), depth of the front point is c.z * (1 - r / |c|).
  {
    Scene s2;
    s2.objects.push_back(make(Sphere{{0, 0, 700}, r}));
    auto v2 = prepare_view(s2, test_projector(), cam);
    ASSERT_TRUE(v2.ok());
    EXPECT_NEAR(v2->depth_mm[120 * 321 + 160], 700.0 - r, 1e-3);
  }
  size_t hits = 0;
  for (uint32_t y = 0; y < 241; y += 3) {
    for (uint32_t x = 0; x < 321; x += 3) {
      const Vec3 d = cam.intrinsics.ray(x, y);
      // |s d - c|^2 = r^2 → s = (d·c - sqrt((d·c)^2 - |d|^2 (|c|^2 - r^2))) / |d|^2
      const double dd = dot(d, d), dc = dot(d, c), disc = dc * dc - dd * (dot(c, c) - r * r);
      const size_t i = size_t{y} * 321 + x;
      if (disc < 1e-3) {
        if (disc < -1e-3) {
          EXPECT_TRUE(std::isnan(v->depth_mm[i])) << x << "," << y;
        }
        continue;
      }
      const double s = (dc - std::sqrt(disc)) / dd;
      ASSERT_NEAR(v->depth_mm[i], s * d.z, 1e-3) << x << "," << y;
      // Normal = (X - c) / r, facing the camera.
      const Vec3 n = (d * s - c) / r;
      EXPECT_NEAR(v->normal[3 * i + 0], n.x, 1e-5);
      EXPECT_NEAR(v->normal[3 * i + 2], n.z, 1e-5);
      ++hits;
    }
  }
  EXPECT_GT(hits, 500u);
}

TEST(Raycast, RotatedBoxMatchesFacePlanes) {
  Box b;
  b.center_mm = {15, 5, 650};
  b.size_mm = {120, 90, 150};
  b.rotation = rotation_from_euler_deg(12, 35, -8);
  Plane back;
  back.point_mm = {0, 0, 900};
  back.normal = {0, 0, -1};
  Scene scene;
  scene.objects.push_back(make(back));
  scene.objects.push_back(make(b));
  const CameraCalibration cam = test_camera();
  auto v = prepare_view(scene, test_projector(), cam);
  ASSERT_TRUE(v.ok());
  const Vec3 half = b.size_mm * 0.5;
  size_t box_px = 0, faces_seen_mask = 0;
  for (uint32_t y = 0; y < 241; ++y) {
    for (uint32_t x = 0; x < 321; ++x) {
      const Vec3 d = cam.intrinsics.ray(x, y);
      Vec3 n;
      auto s = test::ref_ray_box({0, 0, 0}, d, b.center_mm, b.rotation, half, 1e-9, &n);
      const size_t i = size_t{y} * 321 + x;
      if (!s) {
        ASSERT_NEAR(v->depth_mm[i], 900.0, 1e-3) << x << "," << y;
        continue;
      }
      ASSERT_NEAR(v->depth_mm[i], *s * d.z, 1e-3) << x << "," << y;
      // Normal (outward face normal; visible faces face the camera).
      EXPECT_NEAR(v->normal[3 * i + 0], n.x, 1e-5);
      EXPECT_NEAR(v->normal[3 * i + 1], n.y, 1e-5);
      EXPECT_EQ(v->object[i], 1);
      ++box_px;
      for (int a = 0; a < 3; ++a)
        if (std::abs(dot(n, b.rotation * Vec3{a == 0 ? 1.0 : 0, a == 1 ? 1.0 : 0, a == 2 ? 1.0 : 0})) > 0.99)
          faces_seen_mask |= 1u << a;
    }
  }
  EXPECT_GT(box_px, 5000u);
  EXPECT_EQ(faces_seen_mask, 7u);  // three faces visible under this rotation
}

TEST(Raycast, FinitePlaneAndTracerDirect) {
  Plane p;
  p.point_mm = {0, 0, 500};
  p.normal = {0, 0, -1};
  p.finite = true;
  p.width_mm = 100;
  p.height_mm = 40;
  p.u_axis = {1, 0, 0};
  p.v_axis = cross(p.normal, p.u_axis);
  Scene scene;
  scene.objects.push_back(make(p));
  SceneTracer tracer(scene);
  Hit h;
  ASSERT_TRUE(tracer.first_hit({49, 19, 0}, {0, 0, 1}, 1e-9, h));
  EXPECT_NEAR(h.t, 500, 1e-9);
  EXPECT_EQ(h.object, 0);
  EXPECT_FALSE(tracer.first_hit({51, 0, 0}, {0, 0, 1}, 1e-9, h));
  EXPECT_FALSE(tracer.first_hit({0, 21, 0}, {0, 0, 1}, 1e-9, h));
  // Behind the origin: no hit.
  EXPECT_FALSE(tracer.first_hit({0, 0, 600}, {0, 0, 1}, 1e-9, h));
  // Sphere from inside: far root.
  Scene s2;
  s2.objects.push_back(make(Sphere{{0, 0, 0}, 10}));
  SceneTracer t2(s2);
  ASSERT_TRUE(t2.first_hit({0, 0, 0}, {1, 0, 0}, 1e-9, h));
  EXPECT_NEAR(h.t, 10, 1e-12);
}

// Bowl with depth_mm != radius_mm: a half-ellipsoid. Rays from the origin
// aimed at points of the analytic surface x = r sinθ, z = c + h cosθ enter
// through the opening and stop there, with the normal of the gradient
// (x / r², 0, (z − c) / h²); the outer half (z < c) is not part of the bowl;
// depth = radius is the hemisphere (sphere distance).
TEST(Raycast, HalfEllipsoidBowlMatchesImplicitSurface) {
  const double r = 80, depth = 120, cz = 700;
  Bowl b;
  b.center_mm = {0, 0, cz};
  b.radius_mm = r;
  b.depth_mm = depth;
  b.opening = {0, 0, -1};
  Scene scene;
  scene.objects.push_back(make(b));
  SceneTracer tracer(scene);
  for (double theta_deg : {0.0, 15.0, 40.0, 65.0, 80.0}) {
    const double th = theta_deg * M_PI / 180.0;
    const Vec3 q{r * std::sin(th), 0, cz + depth * std::cos(th)};
    Hit h;
    ASSERT_TRUE(tracer.first_hit({0, 0, 0}, q, 1e-9, h)) << theta_deg;
    EXPECT_NEAR(h.t, 1.0, 1e-9) << theta_deg;  // dir = q: the hit is q itself
    const Vec3 g = normalized(Vec3{q.x / (r * r), 0, (q.z - cz) / (depth * depth)});
    EXPECT_NEAR(std::abs(dot(h.normal, g)), 1.0, 1e-9) << theta_deg;
  }
  // A ray that only crosses the closed (outer) half misses: from the side,
  // above the rim plane (z < c).
  Hit h;
  EXPECT_FALSE(tracer.first_hit({-500, 0, cz - 10}, {1, 0, 0}, 1e-9, h));
  // Hemisphere: depth = radius gives the sphere's distance.
  b.depth_mm = r;
  Scene s2;
  s2.objects.push_back(make(b));
  SceneTracer t2(s2);
  ASSERT_TRUE(t2.first_hit({0, 0, 0}, {0.05, 0.02, 1}, 1e-9, h));
  EXPECT_NEAR(std::sqrt(dot(h.point_mm - b.center_mm, h.point_mm - b.center_mm)), r, 1e-9);
}

}  // namespace
}  // namespace procam::sim
