// SPDX-License-Identifier: MIT
// Tests of procam::sdk triangulation: against geometry computed here (a plane at
// known depth; each pixel's true column from projecting the plane point into
// the projector, x_p = R^T (X - t)), and against a reference that runs the
// per-pixel procam::triangulate_column (procam/base/calibration.hpp) the way
// the former procam::sl::triangulate_columns did, on hard cases.
#include "procam/sdk/triangulate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace procam::sdk {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

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

// The former implementation, per pixel and single-threaded: the reference.
DepthResult reference(const Geometry& g, uint32_t w, uint32_t h, const float* col,
                      const float* intensity) {
  DepthResult r;
  r.depth_mm.assign(size_t{w} * h, kNaN);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t i = size_t{y} * w + x;
      if (!std::isfinite(col[i])) continue;
      const auto p = triangulate_column(g.cam, g.proj, x, y, static_cast<double>(col[i]));
      if (!p) continue;
      const auto X = static_cast<float>(p->x), Y = static_cast<float>(p->y),
                 Z = static_cast<float>(p->z);
      if (!std::isfinite(X) || !std::isfinite(Y) || !std::isfinite(Z)) continue;
      r.depth_mm[i] = Z;
      r.points.insert(r.points.end(), {X, Y, Z, intensity != nullptr ? intensity[i] : 0.0f});
    }
  r.point_count = r.points.size() / 4;
  return r;
}

// Condition number |n||d| / |n.d| of pixel (u, v) against column c: how much
// the float ray table's rounding (2^-24 relative) is amplified in the point.
double condition(const Geometry& g, double u, double v, double c) {
  const Vec3 d = g.cam.intrinsics.ray(u, v);
  const Vec3 n = g.cam.cam_from_proj.rotation * Vec3{g.proj.fx, 0.0, -(c - g.proj.cx)};
  return norm(n) * norm(d) / std::abs(dot(n, d));
}

// Same pixels get a point, in the same (row-major) order, with the same
// intensity; coordinates agree within kRel * condition * |p|. kRel: the ray
// table holds float rays (relative error <= 2^-24 = 6e-8 per component) and
// the outputs are floats (another 2^-24); the ray error reaches s amplified by
// at most the condition number, so 1e-6 leaves a margin of ~8 over the worst
// case while still catching any real formula error (those are >= 1e-3).
constexpr double kRel = 1e-6;
// worst (optional): the largest |got - want| / tolerance seen.
void expect_matches_reference(const Geometry& g, uint32_t w, uint32_t h,
                              const std::vector<float>& col, const float* intensity,
                              const DepthResult& got, const std::string& what,
                              double* worst = nullptr) {
  const DepthResult want = reference(g, w, h, col.data(), intensity);
  ASSERT_EQ(got.point_count, want.point_count) << what;
  ASSERT_EQ(got.points.size(), want.points.size()) << what;
  ASSERT_EQ(got.depth_mm.size(), want.depth_mm.size()) << what;
  size_t p = 0;
  for (size_t i = 0; i < col.size(); ++i) {
    ASSERT_EQ(std::isnan(got.depth_mm[i]), std::isnan(want.depth_mm[i])) << what << " pixel " << i;
    if (std::isnan(want.depth_mm[i])) continue;
    const double cond = condition(g, static_cast<double>(i % w), static_cast<double>(i / w),
                                  static_cast<double>(col[i]));
    const double scale = std::hypot(want.points[4 * p], want.points[4 * p + 1], want.points[4 * p + 2]);
    const double tol = kRel * std::max(1.0, cond) * scale;
    for (size_t k = 0; k < 3; ++k) {
      ASSERT_NEAR(got.points[4 * p + k], want.points[4 * p + k], tol) << what << " pixel " << i;
      if (worst != nullptr)
        *worst = std::max(*worst, std::abs(static_cast<double>(got.points[4 * p + k]) -
                                           static_cast<double>(want.points[4 * p + k])) /
                                      tol);
    }
    ASSERT_EQ(got.points[4 * p + 3], want.points[4 * p + 3]) << what << " pixel " << i;
    ASSERT_EQ(got.depth_mm[i], got.points[4 * p + 2]) << what << " pixel " << i;
    ++p;
  }
}

// The kernels this CPU can run: the portable twin, and AVX2 where present.
std::vector<TriangulateIsa> kernels_here() {
  std::vector<TriangulateIsa> k{TriangulateIsa::baseline};
  if (cpu_has_avx2()) k.push_back(TriangulateIsa::avx2);
  return k;
}

// n random columns uniform in [lo, hi), a fraction `invalid` of them NaN, and
// random intensities in [0, 1).
void random_columns(size_t n, uint32_t seed, float lo, float hi, float invalid,
                    std::vector<float>& col, std::vector<float>& intensity) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> cols(lo, hi), pick(0.0f, 1.0f);
  col.resize(n);
  intensity.resize(n);
  for (size_t i = 0; i < n; ++i) {
    col[i] = pick(rng) < invalid ? kNaN : cols(rng);
    intensity[i] = pick(rng);
  }
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
    col[5] = kNaN;
    col[w * 100 + 50] = kNaN;
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
    expect_matches_reference(g, w, h, col, intensity.data(), r, "plane");
  }
}

// Lens distortion in both devices: a plane at known depth seen through a
// distorted camera and lit by a distorted projector. Truth per pixel: its
// undistorted ray (checked independently: distorting it back gives the pixel)
// meets the plane; the point projected into the distorted projector gives
// the decoded (column, row).
TEST(Triangulate, LensDistortionOfCameraAndProjector) {
  Geometry g = make_geometry();
  g.cam.intrinsics.distortion = {-0.18, 0.09, 0.0012, -0.0007, 0.0};
  g.proj.distortion = {0.06, -0.03, 0.0008, 0.0004, 0.0};
  const uint32_t w = g.cam.intrinsics.width, h = g.cam.intrinsics.height;
  std::vector<float> col(size_t{w} * h), row(col.size());
  std::vector<Vec3> truth(col.size());
  const double z0 = 450.0, slope = 0.2;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t i = size_t{y} * w + x;
      const Vec3 d = g.cam.intrinsics.ray(x, y);
      double u, v;
      g.cam.intrinsics.project(d, u, v);  // forward model: must land on the pixel
      ASSERT_NEAR(u, x, 1e-6);
      ASSERT_NEAR(v, y, 1e-6);
      const double s = z0 / (1.0 - slope * d.x);
      truth[i] = d * s;
      const Vec3 xp = g.cam.cam_from_proj.rotation.transposed() * (truth[i] - g.cam.cam_from_proj.translation_mm);
      double c, r;
      g.proj.project(xp, c, r);
      col[i] = static_cast<float>(c);
      row[i] = static_cast<float>(r);
    }
  auto worst_error = [&](const DepthResult& res) {
    double worst = 0;
    size_t p = 0;
    for (size_t i = 0; i < col.size(); ++i) {
      if (std::isnan(res.depth_mm[i])) continue;
      worst = std::max(worst, norm(Vec3{res.points[4 * p], res.points[4 * p + 1], res.points[4 * p + 2]} - truth[i]));
      ++p;
    }
    return worst;
  };
  const DepthResult with_rows = triangulate_columns(g.cam, g.proj, w, h, col.data(), nullptr, 2, row.data());
  ASSERT_EQ(with_rows.point_count, col.size());
  EXPECT_LT(worst_error(with_rows), 0.05) << "both lenses modelled";
  // What each correction is worth: without the row map the projector's
  // columns are bent; a pinhole camera model bends every ray.
  const DepthResult no_rows = triangulate_columns(g.cam, g.proj, w, h, col.data(), nullptr, 2);
  EXPECT_GT(worst_error(no_rows), 1.0);
  Geometry pinhole = g;
  pinhole.cam.intrinsics.distortion = {};
  const DepthResult bent = triangulate_columns(pinhole.cam, g.proj, w, h, col.data(), nullptr, 2, row.data());
  EXPECT_GT(worst_error(bent), 5.0);
}

TEST(Triangulate, DistortionJsonRoundTripAndErrors) {
  Intrinsics k{320, 240, 400.0, 401.0, 159.5, 119.5};
  nlohmann::json j = k;
  EXPECT_FALSE(j.contains("distortion")) << "a pinhole writes no distortion";
  k.distortion = {-0.1, 0.02, 0.001, 0.0, 0.003};
  j = k;
  const Intrinsics back = j.get<Intrinsics>();
  EXPECT_EQ(back.distortion, k.distortion);
  j["distortion"] = {0.1, 0.2, 0.0, 0.0};  // four coefficients: k3 = 0
  EXPECT_EQ(j.get<Intrinsics>().distortion[4], 0.0);
  j["distortion"] = {0.1, 0.2};
  EXPECT_THROW(j.get<Intrinsics>(), nlohmann::json::exception);
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
      col[size_t{y} * w + x] = (x + y) % 5 == 0 ? kNaN : std::round(static_cast<float>(c));
    }
  const DepthResult a = triangulate_columns(g.cam, g.proj, w, h, col.data(), nullptr, 1);
  const DepthResult b = triangulate_columns(g.cam, g.proj, w, h, col.data(), nullptr, 5);
  ASSERT_EQ(a.points, b.points);
  ASSERT_EQ(a.point_count, b.point_count);
  for (size_t i = 0; i < col.size(); ++i)
    ASSERT_TRUE(a.depth_mm[i] == b.depth_mm[i] ||
                (std::isnan(a.depth_mm[i]) && std::isnan(b.depth_mm[i])));
  expect_matches_reference(g, w, h, col, nullptr, a, "rounded columns");
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

// A projector in front of the camera, 100 mm to the right, facing it (turned
// 180 degrees about y): x_cam = 100 - x_p, z_cam = t_z - z_p. Column cx_p is
// the plane x_cam = 100. Camera pixel x of a 3x1 image (fx 4, cx 0) has the
// ray d = (x / 4, 0, 1): x = 0 runs parallel to the plane, x = 1 meets it at
// z = 400, x = 2 at z = 200 (x = 100 mm).
TEST(Triangulate, BehindTheProjectorGivesNoPoint) {
  Geometry g;
  g.cam.intrinsics = {3, 1, 4.0, 100.0, 0.0, 0.0};
  g.proj = {100, 100, 100.0, 100.0, 50.0, 50.0};
  g.cam.cam_from_proj.rotation = Mat3{{-1, 0, 0, 0, 1, 0, 0, 0, -1}};
  g.cam.cam_from_proj.translation_mm = {100.0, 0.0, 500.0};
  const std::vector<float> col = {50.0f, 50.0f, 50.0f};
  const DepthResult r =
      ColumnTriangulator(g.cam, g.proj, 3, 1).run(ColumnMap{col.data(), nullptr}, 1);
  EXPECT_TRUE(std::isnan(r.depth_mm[0]));
  EXPECT_FLOAT_EQ(r.depth_mm[1], 400.0f);  // z_p = 500 - 400 = 100 > 0
  EXPECT_FLOAT_EQ(r.depth_mm[2], 200.0f);
  // Projector at z 300: the z = 400 point is now behind it (z_p = -100).
  g.cam.cam_from_proj.translation_mm.z = 300.0;
  const DepthResult r2 =
      ColumnTriangulator(g.cam, g.proj, 3, 1).run(ColumnMap{col.data(), nullptr}, 1);
  EXPECT_TRUE(std::isnan(r2.depth_mm[0]));
  EXPECT_TRUE(std::isnan(r2.depth_mm[1]));
  EXPECT_FLOAT_EQ(r2.depth_mm[2], 200.0f);
  ASSERT_EQ(r2.point_count, 1u);
  EXPECT_FLOAT_EQ(r2.points[0], 100.0f);
  expect_matches_reference(g, 3, 1, col, nullptr, r2, "behind projector");
  // Projector at z 400: the z = 400 point lies on its z = 0 plane (z_p = 0,
  // the float tier's undecidable case): no point, as in the reference.
  g.cam.cam_from_proj.translation_mm.z = 400.0;
  for (const TriangulateIsa isa : kernels_here()) {
    DepthResult r3;
    ColumnTriangulator(g.cam, g.proj, 3, 1).run(ColumnMap{col.data(), nullptr}, 1, r3, isa);
    EXPECT_TRUE(std::isnan(r3.depth_mm[1]));
    EXPECT_FLOAT_EQ(r3.depth_mm[2], 200.0f);
    expect_matches_reference(g, 3, 1, col, nullptr, r3, "on the projector plane");
  }
}

// Exactly parallel ray and plane: identity rotation, fx = fx_p = 512 and
// u - cx = c - cx_p = 32, so n.d = 512 * 0.0625 - 32 = 0 in any precision.
TEST(Triangulate, RayParallelToPlaneGivesNoPoint) {
  Geometry g;
  g.cam.intrinsics = {64, 1, 512.0, 512.0, 0.0, 0.0};
  g.proj = {256, 256, 512.0, 512.0, 100.0, 128.0};
  g.cam.cam_from_proj.translation_mm = {100.0, 0.0, 0.0};
  std::vector<float> col(64, 132.0f);  // c - cx_p = 32: parallel at u = 32
  const DepthResult r = ColumnTriangulator(g.cam, g.proj, 64, 1).run(ColumnMap{col.data(), nullptr}, 1);
  EXPECT_TRUE(std::isnan(r.depth_mm[32]));
  EXPECT_FALSE(std::isnan(r.depth_mm[40]));  // its neighbours meet the plane (x > 32 in front)
  expect_matches_reference(g, 64, 1, col, nullptr, r, "parallel");
}

// Random columns over a wide range (far outside the projector too), with NaN,
// +-inf, the edge columns -0.5 and W - 0.5, and whole invalid rows: same
// points, order and count as the reference, and the gap closing exercised
// (finite columns that make no point in the middle of rows).
TEST(Triangulate, MatchesPerPixelReferenceOnHardMaps) {
  const Geometry g = make_geometry();
  const uint32_t w = g.cam.intrinsics.width, h = g.cam.intrinsics.height;
  const auto W = static_cast<float>(g.proj.width);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> wide(-3000.0f, 4000.0f), pick(0.0f, 1.0f);
  std::vector<float> col(size_t{w} * h), intensity(col.size());
  size_t finite_without_point = 0;
  for (size_t i = 0; i < col.size(); ++i) {
    const float u = pick(rng);
    col[i] = u < 0.1f   ? kNaN
             : u < 0.12f ? std::numeric_limits<float>::infinity()
             : u < 0.14f ? -std::numeric_limits<float>::infinity()
             : u < 0.2f  ? -0.5f
             : u < 0.26f ? W - 0.5f
                         : wide(rng);
    intensity[i] = pick(rng);
  }
  for (uint32_t x = 0; x < w; ++x) col[size_t{17} * w + x] = kNaN;  // an empty row
  const DepthResult want = reference(g, w, h, col.data(), intensity.data());
  for (size_t i = 0; i < col.size(); ++i)
    finite_without_point += std::isfinite(col[i]) && std::isnan(want.depth_mm[i]) ? 1u : 0u;
  ASSERT_GT(finite_without_point, 1000u);  // the hard cases are really there
  ASSERT_GT(want.point_count, 10000u);
  ColumnTriangulator t(g.cam, g.proj, w, h);
  DepthResult reused;
  for (uint32_t threads : {1u, 2u, 3u}) {
    t.run(ColumnMap{col.data(), intensity.data()}, threads, reused);
    expect_matches_reference(g, w, h, col, intensity.data(), reused,
                             "threads " + std::to_string(threads));
  }
  // Edge columns on their own: -0.5 and W - 0.5 triangulate (they are
  // projector pixel edges, not outside it).
  std::vector<float> edges(col.size());
  for (size_t i = 0; i < edges.size(); ++i) edges[i] = i % 2 == 0 ? -0.5f : W - 0.5f;
  t.run(ColumnMap{edges.data(), nullptr}, 2, reused);  // reuses (shrinks) the storage
  EXPECT_GT(reused.point_count, 0u);
  expect_matches_reference(g, w, h, edges, nullptr, reused, "edges");
}

// Both kernels (the AVX2 one, whose fast tier divides in float and refines
// the quotient to ~2^-47 in float pairs, and the portable double twin)
// against the reference on random maps: same validity, count and order, and
// identical points: both round the same double value to float, so a
// coordinate may differ (by 1 ulp) only where that value lies within ~2^-46
// of a rounding boundary (expected: about one coordinate in 10^7; allowed
// here: 1 in 10^4).
TEST(Triangulate, BothKernelsMatchReference) {
  const Geometry g = make_geometry();
  const uint32_t w = g.cam.intrinsics.width, h = g.cam.intrinsics.height;
  std::vector<float> col, intensity;
  random_columns(size_t{w} * h, 11, -1000.0f, 1700.0f, 0.1f, col, intensity);
  const ColumnTriangulator t(g.cam, g.proj, w, h);
  for (const TriangulateIsa isa : kernels_here()) {
    DepthResult got;
    t.run(ColumnMap{col.data(), intensity.data()}, 2, got, isa);
    ASSERT_GT(got.point_count, 10000u);
    expect_matches_reference(g, w, h, col, intensity.data(), got,
                             isa == TriangulateIsa::avx2 ? "avx2" : "baseline");
    const DepthResult want = reference(g, w, h, col.data(), intensity.data());
    size_t differ = 0;
    for (size_t i = 0; i < want.points.size(); ++i) {
      const float a = got.points[i], b = want.points[i];
      if (a == b) continue;
      ++differ;
      ASSERT_TRUE(a == std::nextafter(b, INFINITY) || a == std::nextafter(b, -INFINITY)) << i;
    }
    EXPECT_LE(differ, want.points.size() / 10000) << "coordinates not identical";
  }
}

// The hardest conditions the geometry allows, for both kernels: a projector
// turned 75 degrees (its column planes graze the camera rays: condition
// numbers up to ~1e6 and more), a 2 mm baseline (points metres to km away),
// 16-bit column values (a 65536-column projector, columns 0..65535 and far
// outside), columns around the epipole (n.t -> 0: points at the camera) and
// around the plane through the camera's rays (n.d -> 0: parallel).
TEST(Triangulate, GrazingFarAnd16BitColumnsMatchReference) {
  Geometry g;
  g.cam.intrinsics = {256, 160, 300.0, 300.0, 127.5, 79.5};
  g.proj = {65536, 40000, 30000.0, 30000.0, 32767.5, 19999.5};
  const double a = 75.0 * M_PI / 180.0;
  g.cam.cam_from_proj.rotation = Mat3{{std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0,
                                       std::cos(a)}};
  g.cam.cam_from_proj.translation_mm = {2.0, 0.3, 0.5};
  const uint32_t w = g.cam.intrinsics.width, h = g.cam.intrinsics.height;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> pick(0.0f, 1.0f), u16(0.0f, 65535.0f),
      wide(-4e6f, 4e6f);
  // The column whose plane contains the camera centre (n(c).t = 0).
  const Vec3 r0{std::cos(a), 0, -std::sin(a)}, r2{std::sin(a), 0, std::cos(a)};
  const Vec3& tt = g.cam.cam_from_proj.translation_mm;
  const double c_epi = g.proj.cx + g.proj.fx * dot(r0, tt) / dot(r2, tt);
  std::vector<float> col(size_t{w} * h);
  size_t grazing = 0;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const float u = pick(rng);
      // The column whose plane contains this pixel's ray (n(c).d = 0).
      const Vec3 d = g.cam.intrinsics.ray(x, y);
      const double c_par = g.proj.cx + g.proj.fx * dot(r0, d) / dot(r2, d);
      float c = u < 0.3f   ? std::round(u16(rng))
                : u < 0.5f ? wide(rng)
                : u < 0.7f ? static_cast<float>(c_par + (static_cast<double>(pick(rng)) - 0.5) * 1e-3 * g.proj.fx)
                : u < 0.8f ? static_cast<float>(c_par)
                : u < 0.9f ? static_cast<float>(c_epi + (static_cast<double>(pick(rng)) - 0.5) * 20.0)
                           : u16(rng);
      col[size_t{y} * w + x] = c;
      grazing += condition(g, x, y, c) > 1e3 ? 1u : 0u;
    }
  ASSERT_GT(grazing, 5000u);  // the grazing cases are really there
  const ColumnTriangulator t(g.cam, g.proj, w, h);
  for (const TriangulateIsa isa : kernels_here()) {
    DepthResult got;
    t.run(ColumnMap{col.data(), nullptr}, 2, got, isa);
    ASSERT_GT(got.point_count, 5000u);
    double worst = 0;
    expect_matches_reference(g, w, h, col, nullptr, got,
                             isa == TriangulateIsa::avx2 ? "avx2" : "baseline", &worst);
    EXPECT_LT(worst, 0.5);
  }
}

// Widths that are not a multiple of the AVX2 kernel's 8 pixels (nor of its
// 128-pixel chunks), with per-pixel (distorted) and separable (pinhole)
// rays: the padded tail block and every chunk boundary, both kernels.
TEST(Triangulate, OddWidthsMatchReference) {
  for (const bool distorted : {false, true}) {
    Geometry g = make_geometry();
    if (distorted) g.cam.intrinsics.distortion = {-0.12, 0.05, 0.001, -0.0005, 0.0};
    for (const uint32_t w : {1u, 7u, 9u, 135u, 203u}) {
      const uint32_t h = 5;
      g.cam.intrinsics.width = w;
      g.cam.intrinsics.height = h;
      std::vector<float> col, intensity;
      random_columns(size_t{w} * h, w, -200.0f, 900.0f, 0.2f, col, intensity);
      const ColumnTriangulator t(g.cam, g.proj, w, h);
      for (const TriangulateIsa isa : kernels_here()) {
        DepthResult got;
        t.run(ColumnMap{col.data(), intensity.data()}, 2, got, isa);
        expect_matches_reference(g, w, h, col, intensity.data(), got,
                                 "w " + std::to_string(w) + (distorted ? " distorted" : ""));
      }
    }
  }
}

TEST(Triangulate, CachedTriangulatorFollowsCalibrationChanges) {
  Geometry g = make_geometry();
  const uint32_t w = g.cam.intrinsics.width, h = g.cam.intrinsics.height;
  std::vector<float> col(size_t{w} * h, 300.0f);
  const DepthResult a = triangulate_columns(g.cam, g.proj, w, h, col.data(), nullptr, 2);
  g.cam.cam_from_proj.translation_mm.x = 250.0;  // longer baseline: every point moves
  const DepthResult b = triangulate_columns(g.cam, g.proj, w, h, col.data(), nullptr, 2);
  expect_matches_reference(g, w, h, col, nullptr, b, "after change");
  ASSERT_EQ(a.point_count, b.point_count);
  EXPECT_NE(a.points[2], b.points[2]);
}

TEST(Triangulate, AddDepthOutputsWritesMapsAndPoints) {
  std::optional<DepthResult> depth = DepthResult{{1.0f, kNaN}, {0.5f, 0.25f, 1.0f, 0.75f}, 1};
  Outputs out;
  add_depth_outputs(out, depth, 2, 1);
  ASSERT_EQ(out.size(), 2u);
  const procam_output* o = out.view();
  EXPECT_STREQ(o[0].name, "depth_mm");
  EXPECT_STREQ(o[0].unit, "mm");
  EXPECT_STREQ(o[0].description, "z of the triangulated point, camera frame (NaN: none)");
  EXPECT_EQ(static_cast<const float*>(o[0].image.data)[0], 1.0f);
  EXPECT_STREQ(o[1].name, "points");
  EXPECT_STREQ(o[1].point_fields, "x,y,z,intensity");
  EXPECT_STREQ(o[1].description,
               "triangulated points, camera frame; intensity = white / full scale");
  EXPECT_EQ(o[1].point_count, 1u);
  EXPECT_EQ(o[1].points[3], 0.75f);
  // No depth: no outputs.
  std::optional<DepthResult> none;
  Outputs out2;
  add_depth_outputs(out2, none, 2, 1);
  EXPECT_EQ(out2.size(), 0u);
}

}  // namespace
}  // namespace procam::sdk
