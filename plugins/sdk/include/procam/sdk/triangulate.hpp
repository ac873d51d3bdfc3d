// SPDX-License-Identifier: MIT
// Column-plane triangulation of a decoded projector-column map into a depth map
// and a point cloud (each camera ray meets the plane of its projector column),
// fast: cached camera rays, closed-form column planes, vectorised rows.
//
// Model (the one of procam::triangulate_column, procam/base/calibration.hpp):
// camera with optional lens distortion (the ray of a pixel is its undistorted
// direction), pixel centres at integer coordinates; projector column c
// (continuous, column centres at integers, so the edges are -0.5 and W-0.5) is
// the plane through the projector centre with normal n_p(c) = (fx_p, 0,
// -(c - cx_p)) in the projector frame. In the camera frame that normal is
//   n(c) = R n_p(c) = (fx_p R_0 + cx_p R_2) + c (-R_2) = a + c b
// (R_k: column k of R = cam_from_proj.rotation), linear in c, and the plane
// passes through t, so n(c).t = a.t + c b.t. The camera ray x = s d of pixel
// (u, v) meets it at s = n(c).t / n(c).d. A fractional column therefore costs
// four multiply-adds — no per-column table is needed. The point is rejected
// (NaN depth, no point) when the ray is parallel to the plane (|n.d| <
// 1e-12 |n| |d|), when s is not positive and finite (behind the camera), when
// it lies behind the projector (z of R^T (x - t) not > 0) or when a float
// coordinate is not finite — exactly the rules of triangulate_column.
//
// Units: mm, camera frame (x right, y down, z forward). Thread-safety: a
// ColumnTriangulator is immutable after construction; run() is reentrant and
// uses `threads` worker threads (sdk::parallel_rows). Errors: std::bad_alloc
// and std::invalid_argument (no column map) only; call inside the SDK's ABI
// wrapper, which turns them into error codes. Storage: `col` and `intensity`
// are borrowed for the call and must hold width*height floats each.
#pragma once

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "procam/base/calibration.hpp"
#include "procam/sdk/outputs.hpp"

namespace procam::sdk {

struct DepthResult {
  std::vector<float> depth_mm;  // width*height, z of the point, NaN where no point
  std::vector<float> points;    // rows of x, y, z (mm), intensity; row-major pixel order
  uint64_t point_count = 0;
};

// The inputs of one triangulation, width*height each, row-major.
// (A decoded projector-row map would be a further field here; the column-plane
// model does not use it, so there is none yet.)
struct ColumnMap {
  const float* col = nullptr;        // projector column per pixel; NaN (or inf): invalid
  const float* intensity = nullptr;  // stored as the points' 4th field; null: 0
  // Decoded projector row per pixel (optional). Used only when the projector
  // has lens distortion: (column, row) is undistorted to the ideal column,
  // whose plane is exact. Without it a distorted projector's columns are
  // taken as planes (error grows with the distortion toward the image edge).
  const float* row = nullptr;
};

// Which row kernel run() uses: the portable double-precision twin (baseline
// x86-64), or the AVX2+FMA kernel (chosen at run time when the CPU has both;
// `avx2` forces it: only where cpu_has_avx2()). The AVX2 kernel divides in
// float and refines the quotient in float pairs (~2^-47 relative), so both
// give the same points as procam::triangulate_column (a coordinate may differ
// by 1 ulp only where the double value lies within ~2^-46 of a float rounding
// boundary) and the same validity decisions (tested against it).
enum class TriangulateIsa { automatic, baseline, avx2 };

// True when this CPU can run the AVX2 kernel (AVX2 and FMA).
bool cpu_has_avx2() noexcept;

class ColumnTriangulator {
 public:
  // Builds the camera-ray tables (pinhole: d = ((u-cx)/fx, (v-cy)/fy, 1),
  // x by column and y by row, in double and float; lens distortion: the
  // undistorted ray per pixel, float) and the column-plane coefficients.
  // width/height: the camera image the maps come from.
  ColumnTriangulator(const CameraCalibration& cam, const Intrinsics& projector, uint32_t width,
                     uint32_t height);

  // Triangulates `map` into `out`, reusing out's storage (a caller that keeps
  // its DepthResult between scans pays no page faults for it). out.depth_mm
  // becomes width*height, out.points point_count*4 floats.
  void run(const ColumnMap& map, uint32_t threads, DepthResult& out,
           TriangulateIsa isa = TriangulateIsa::automatic) const;
  DepthResult run(const ColumnMap& map, uint32_t threads) const;

  // True when this object was built for exactly these parameters.
  bool matches(const CameraCalibration& cam, const Intrinsics& projector, uint32_t width,
               uint32_t height) const noexcept;
  uint32_t width() const noexcept { return width_; }
  uint32_t height() const noexcept { return height_; }

 private:
  CameraCalibration cam_;
  Intrinsics projector_;
  uint32_t width_ = 0, height_ = 0;
  // Camera ray directions (z = 1): the only place the camera model enters.
  // Pinhole: x of the ray by column (width floats), y by row (height floats).
  // With lens distortion the undistorted ray depends on both: per-pixel
  // tables (per_pixel_rays_), passed to the same row kernel row by row.
  std::vector<float> ray_x_, ray_y_;
  // Pinhole: the same rays in double (exact: the reference's rays), which
  // n.d, n.t and the parallel test use; the float tables serve the float
  // products x = s dx, y = s dy.
  std::vector<double> ray_xd_, ray_yd_;
  std::vector<float> ray_x_lo_;  // ray_xd_ - ray_x_ (the float x's remainder)
  bool per_pixel_rays_ = false;
  float ray_max_ = 0;  // largest |x| or |y| of any ray (bounds the point's x, y by s)
  // Plane coefficients n(c) = a + c b, n(c).t = at + c bt; r2 = R_2 (the
  // projector's z axis in the camera frame) and r2t = R_2.t for the
  // behind-the-projector test.
  double a_[3]{}, b_[3]{}, at_ = 0, bt_ = 0, r2_[3]{}, r2t_ = 0;
};

// One-shot form with the contract of the former procam::sl::triangulate_columns:
// `col` holds width*height projector columns (NaN = invalid pixel);
// `intensity` the per-pixel 4th point field (may be null: 0). Keeps the last
// ColumnTriangulator built (process-wide, mutex-guarded) and reuses it while
// the calibration and size stay the same.
// `row` (optional): the decoded projector row map, used to undistort a
// distorted projector's columns (ColumnMap::row).
DepthResult triangulate_columns(const CameraCalibration& cam, const Intrinsics& projector,
                                uint32_t width, uint32_t height, const float* col,
                                const float* intensity, uint32_t threads, const float* row = nullptr);

// Writes depth_mm (F32 map, mm, NaN: none) and points (x,y,z,intensity) when
// `depth` holds a result (moving its storage out); nothing otherwise.
// (valid_fraction is a standard output: sdk::add_standard_outputs.)
inline void add_depth_outputs(Outputs& out, std::optional<DepthResult>& depth, uint32_t w, uint32_t h) {
  if (depth) {
    out.add_image("depth_mm", "mm", "z of the triangulated point, camera frame (NaN: none)", w, h,
                  std::move(depth->depth_mm));
    out.add_points("points", "triangulated points, camera frame; intensity = white / full scale",
                   "x,y,z,intensity", 4, std::move(depth->points));
  }
}

}  // namespace procam::sdk
