// SPDX-License-Identifier: MIT
// Column-plane triangulation over a whole column map (procam/sdk/triangulate.hpp):
// ray table, row kernel (baseline + AVX2 twin), row-ordered point compaction.
#include "procam/sdk/triangulate.hpp"

#include <immintrin.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>

#include "procam/sdk/parallel.hpp"

namespace procam::sdk {
namespace {

struct Coeffs {
  double a0, a1, a2, b0, b1, b2, at, bt, r20, r21, r22, r2t;
};

// One camera row: for each pixel, x, y, z of the point as floats; z is NaN
// where there is no point (rules in the header). Branch-free so the
// vectoriser turns it into packed double arithmetic; no reductions, so every
// lane does exactly the scalar operation sequence (bit-identical twins).
// Doubles throughout, like triangulate_column: the only rounding differences
// from it are the float ray table (2^-24 relative) and the re-associated
// plane normal (~1e-16 relative).
// The pointers never alias (__restrict lets the vectoriser rely on it).
__attribute__((always_inline)) inline void row_kernel(const Coeffs& k,
                                                      const float* __restrict col,
                                                      const float* __restrict rx,
                                                      const float* __restrict ry, uint32_t w,
                                                      float* __restrict X, float* __restrict Y,
                                                      float* __restrict Z) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  for (uint32_t x = 0; x < w; ++x) {
    const double c = static_cast<double>(col[x]);
    const double dx = static_cast<double>(rx[x]), dy = static_cast<double>(ry[x]);
    const double nx = k.a0 + c * k.b0, ny = k.a1 + c * k.b1, nz = k.a2 + c * k.b2;
    const double nd = nx * dx + ny * dy + nz;  // n.d, d = (dx, dy, 1)
    const double nn = nx * nx + ny * ny + nz * nz;
    const double dd = dx * dx + dy * dy + 1.0;
    const double s = (k.at + c * k.bt) / nd;  // ray parameter = z of the point
    const double pz = s * (k.r20 * dx + k.r21 * dy + k.r22) - k.r2t;  // z in projector frame
    const float fx = static_cast<float>(dx * s), fy = static_cast<float>(dy * s),
                fz = static_cast<float>(s);
    // |n.d| >= 1e-12 |n| |d|, compared squared (no square roots).
    const bool not_parallel = !(nd * nd < 1e-24 * nn * dd);
    const bool ok = (std::abs(c) <= DBL_MAX) & not_parallel & (s > 0.0) & (s <= DBL_MAX) &
                    (pz > 0.0) & (std::abs(fx) <= FLT_MAX) & (std::abs(fy) <= FLT_MAX) &
                    (fz <= FLT_MAX);
    X[x] = fx;
    Y[x] = fy;
    Z[x] = ok ? fz : kNaN;
  }
}

void row_baseline(const Coeffs& k, const float* col, const float* rx, const float* ry, uint32_t w,
                  float* X, float* Y, float* Z) {
  row_kernel(k, col, rx, ry, w, X, Y, Z);
}

// Same source for AVX2 (no FMA: contraction would change the rounding).
__attribute__((target("avx2"))) void row_avx2(const Coeffs& k, const float* col, const float* rx,
                                              const float* ry, uint32_t w, float* X, float* Y,
                                              float* Z) {
  row_kernel(k, col, rx, ry, w, X, Y, Z);
}

using RowFn = void (*)(const Coeffs&, const float*, const float*, const float*, uint32_t, float*,
                       float*, float*);

// Copies n floats to dst with non-temporal (streaming) stores where dst is
// 16-byte aligned: the maps are written once and read later by someone else,
// so bringing their lines into the cache first (a read for ownership per
// line, i.e. doubling the write traffic) is pure waste. The call is memory
// bound: that traffic is most of its time. Callers issue _mm_sfence() before
// other threads read dst (stream_fence below).
void stream_floats(float* __restrict dst, const float* __restrict src, size_t n) {
  size_t i = 0;
  while (i < n && (reinterpret_cast<uintptr_t>(dst + i) & 15u) != 0) {
    dst[i] = src[i];
    ++i;
  }
  for (; i + 4 <= n; i += 4) _mm_stream_ps(dst + i, _mm_loadu_ps(src + i));
  for (; i < n; ++i) dst[i] = src[i];
}
// Orders this thread's streaming stores before what follows (the pool's join).
void stream_fence() { _mm_sfence(); }

bool same(const Intrinsics& a, const Intrinsics& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy &&
         a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion;
}

}  // namespace

bool cpu_has_avx2() noexcept { return __builtin_cpu_supports("avx2") != 0; }

ColumnTriangulator::ColumnTriangulator(const CameraCalibration& cam, const Intrinsics& projector,
                                       uint32_t width, uint32_t height)
    : cam_(cam), projector_(projector), width_(width), height_(height) {
  const Mat3& R = cam.cam_from_proj.rotation;
  const Vec3& t = cam.cam_from_proj.translation_mm;
  const Vec3 r0{R(0, 0), R(1, 0), R(2, 0)}, r2{R(0, 2), R(1, 2), R(2, 2)};
  // n(c) = fx_p r0 - (c - cx_p) r2 = (fx_p r0 + cx_p r2) + c (-r2).
  const Vec3 a = r0 * projector.fx + r2 * projector.cx, b = r2 * -1.0;
  a_[0] = a.x, a_[1] = a.y, a_[2] = a.z;
  b_[0] = b.x, b_[1] = b.y, b_[2] = b.z;
  at_ = dot(a, t);
  bt_ = dot(b, t);
  r2_[0] = r2.x, r2_[1] = r2.y, r2_[2] = r2.z;
  r2t_ = dot(r2, t);
  // Pinhole camera: the ray of pixel (x, y) is ((x - cx) / fx, (y - cy) / fy,
  // 1), so its x depends on the column only and its y on the row only: two
  // short tables (the same floats a per-pixel table held) instead of 2 x
  // width x height floats to stream through memory on every call. A camera
  // with lens distortion needs the undistorted ray of every pixel: full tables.
  const Intrinsics& k = cam.intrinsics;
  per_pixel_rays_ = k.distorted();
  if (per_pixel_rays_) {
    const size_t n = size_t{width} * height;
    ray_x_.resize(n);
    ray_y_.resize(n);
    for (uint32_t y = 0; y < height; ++y)
      for (uint32_t x = 0; x < width; ++x) {
        const Vec3 d = k.ray(x, y);
        ray_x_[size_t{y} * width + x] = static_cast<float>(d.x);
        ray_y_[size_t{y} * width + x] = static_cast<float>(d.y);
      }
  } else {
    ray_x_.resize(width);
    ray_y_.resize(height);
    for (uint32_t x = 0; x < width; ++x) ray_x_[x] = static_cast<float>(k.ray(x, 0).x);
    for (uint32_t y = 0; y < height; ++y) ray_y_[y] = static_cast<float>(k.ray(0, y).y);
  }
}

bool ColumnTriangulator::matches(const CameraCalibration& cam, const Intrinsics& projector,
                                 uint32_t width, uint32_t height) const noexcept {
  return width == width_ && height == height_ && same(cam.intrinsics, cam_.intrinsics) &&
         same(projector, projector_) &&
         cam.cam_from_proj.rotation.m == cam_.cam_from_proj.rotation.m &&
         cam.cam_from_proj.translation_mm.x == cam_.cam_from_proj.translation_mm.x &&
         cam.cam_from_proj.translation_mm.y == cam_.cam_from_proj.translation_mm.y &&
         cam.cam_from_proj.translation_mm.z == cam_.cam_from_proj.translation_mm.z;
}

void ColumnTriangulator::run(const ColumnMap& map, uint32_t threads, DepthResult& out,
                             TriangulateIsa isa) const {
  if (map.col == nullptr) throw std::invalid_argument("triangulate: no column map");
  const uint32_t w = width_, h = height_;
  const size_t n = size_t{w} * h;
  const Coeffs k{a_[0], a_[1], a_[2], b_[0], b_[1], b_[2], at_, bt_, r2_[0], r2_[1], r2_[2], r2t_};
  const bool avx2 = isa == TriangulateIsa::avx2 ||
                    (isa == TriangulateIsa::automatic && cpu_has_avx2());
  const RowFn row = avx2 ? row_avx2 : row_baseline;
  // A distorted projector's column is not a plane; with the decoded row the
  // pixel's ideal (undistorted) column is known and its plane is exact.
  const bool correct_projector = projector_.distorted() && map.row != nullptr;
  out.depth_mm.resize(n);
  // Pass 1: an upper bound on each row's points (its finite columns), so each
  // row knows where its points go before they exist: no growing vectors.
  std::vector<uint64_t> first(size_t{h} + 1, 0);  // first[y]: row y's first slot
  std::vector<uint32_t> count(h, 0);              // points row y actually made
  parallel_rows(h, threads, [&](uint32_t y0, uint32_t y1) {
    for (uint32_t y = y0; y < y1; ++y) {
      const float* c = map.col + size_t{y} * w;
      uint32_t m = 0;
      for (uint32_t x = 0; x < w; ++x) m += std::abs(c[x]) <= FLT_MAX ? 1u : 0u;
      first[size_t{y} + 1] = m;
    }
  });
  for (uint32_t y = 0; y < h; ++y) first[size_t{y} + 1] += first[y];
  out.points.resize(first[h] * 4);
  float* const pts = out.points.data();
  // Pass 2: rays meet planes row by row; each row's points are compacted in
  // L1 scratch, then copied to the row's slots.
  parallel_rows(h, threads, [&](uint32_t y0, uint32_t y1) {
    std::vector<float> X(w), Y(w), Z(w), ry(w), cu(correct_projector ? w : 0), quad(size_t{w} * 4 + 4);
    for (uint32_t y = y0; y < y1; ++y) {
      const size_t i0 = size_t{y} * w;
      const float* rx_row = ray_x_.data();
      const float* ry_row = ry.data();
      if (per_pixel_rays_) {
        rx_row += i0;
        ry_row = ray_y_.data() + i0;
      } else {
        std::fill(ry.begin(), ry.end(), ray_y_[y]);  // this row's ray y (L1)
      }
      const float* col_row = map.col + i0;
      if (correct_projector) {  // the ideal column of each decoded (column, row)
        for (uint32_t x = 0; x < w; ++x) {
          const float c = col_row[x], r = map.row[i0 + x];
          if (!(std::abs(c) <= FLT_MAX) || !(std::abs(r) <= FLT_MAX)) {
            cu[x] = c;  // NaN stays invalid; a missing row keeps the column as decoded
            continue;
          }
          double xn, yn;
          projector_.undistort(c, r, xn, yn);
          cu[x] = static_cast<float>(projector_.fx * xn + projector_.cx);
        }
        col_row = cu.data();
      }
      row(k, col_row, rx_row, ry_row, w, X.data(), Y.data(), Z.data());
      stream_floats(out.depth_mm.data() + i0, Z.data(), w);
      const float* I = map.intensity != nullptr ? map.intensity + i0 : nullptr;
      float* q = quad.data();
      for (uint32_t x = 0; x < w; ++x) {  // branch-free: always write, advance if valid
        q[0] = X[x];
        q[1] = Y[x];
        q[2] = Z[x];
        q[3] = I != nullptr ? I[x] : 0.0f;
        q += std::isnan(Z[x]) ? 0 : 4;
      }
      const auto m = static_cast<size_t>(q - quad.data());
      stream_floats(pts + first[y] * 4, quad.data(), m);
      count[y] = static_cast<uint32_t>(m / 4);
    }
    stream_fence();
  });
  // Close the gaps of finite columns that made no point (rare: behind a
  // device, parallel rays); a no-op when every finite column made one.
  uint64_t total = 0;
  for (uint32_t y = 0; y < h; ++y) {
    if (total != first[y] && count[y] > 0)
      std::memmove(pts + total * 4, pts + first[y] * 4, size_t{count[y]} * 4 * sizeof(float));
    total += count[y];
  }
  out.points.resize(total * 4);
  out.point_count = total;
}

DepthResult ColumnTriangulator::run(const ColumnMap& map, uint32_t threads) const {
  DepthResult r;
  run(map, threads, r);
  return r;
}

DepthResult triangulate_columns(const CameraCalibration& cam, const Intrinsics& projector,
                                uint32_t width, uint32_t height, const float* col,
                                const float* intensity, uint32_t threads, const float* row) {
  static std::mutex mutex;
  static std::shared_ptr<const ColumnTriangulator> last;
  std::shared_ptr<const ColumnTriangulator> t;
  {
    const std::lock_guard<std::mutex> lock(mutex);
    if (!last || !last->matches(cam, projector, width, height))
      last = std::make_shared<const ColumnTriangulator>(cam, projector, width, height);
    t = last;
  }
  return t->run(ColumnMap{col, intensity, row}, threads);
}

}  // namespace procam::sdk
