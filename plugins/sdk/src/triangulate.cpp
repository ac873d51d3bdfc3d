// SPDX-License-Identifier: MIT
// Column-plane triangulation over a whole column map (procam/sdk/triangulate.hpp):
// ray tables, the portable row kernel (the AVX2 one: triangulate_avx2.cpp),
// band-ordered point slots, streaming stores.
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
#include "triangulate_kernels.hpp"

namespace procam::sdk {
namespace detail {

// Portable twin: plain double arithmetic (the compiler may contract a*b+c to
// FMA only where the target has it; the baseline x86-64 target does not).
// The math loop is branch-free with no loop-carried state, so the vectoriser
// turns it into packed double arithmetic; the compaction is a second loop.
// kPerPixel: ry holds each pixel's ray y, else ry0 is the row's; dx comes
// from k.ray_x (pinhole, double) or rx (per-pixel, float).
namespace {
template <bool kPerPixel>
void row_portable_math(const Coeffs& k, const float* __restrict col, const float* __restrict rx,
                       const float* __restrict ry, double ry0, uint32_t w, float* __restrict X,
                       float* __restrict Y, float* __restrict depth) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  const RowTerms r0 = row_terms(k, ry0);
  const double* __restrict rxd = k.ray_x;
  for (uint32_t x = 0; x < w; ++x) {
    const double c = static_cast<double>(col[x]);
    const double dx = kPerPixel ? static_cast<double>(rx[x]) : rxd[x];
    const double dy = kPerPixel ? static_cast<double>(ry[x]) : ry0;
    const RowTerms rt = kPerPixel ? row_terms(k, dy) : r0;
    const double P = k.a0 * dx + rt.p, Q = k.b0 * dx + rt.q;
    const double D = P + c * Q, N = k.at + c * k.bt;
    const double s = N / D;
    const double pz = s * (k.r20 * dx + rt.rz) - k.r2t;
    const double dd = dx * dx + rt.dd, cm = c - k.cx, nn = cm * cm + k.fx2;
    const float fx = static_cast<float>(s * dx), fy = static_cast<float>(s * dy),
                fz = static_cast<float>(s);
    const bool ok = (std::abs(col[x]) <= FLT_MAX) & (D * D >= 1e-24 * (nn * dd)) & (s > 0.0) &
                    (s <= DBL_MAX) & (pz > 0.0) & (std::abs(fx) <= FLT_MAX) &
                    (std::abs(fy) <= FLT_MAX) & (fz <= FLT_MAX);
    X[x] = fx;
    Y[x] = fy;
    depth[x] = ok ? fz : kNaN;
  }
}

}  // namespace

uint32_t row_portable(const Coeffs& k, const float* col, const float* rx, const float* ry,
                      double ry0, const float* I, uint32_t w, float* depth, float* quads) {
  thread_local std::vector<float> X, Y;  // this thread's row scratch
  X.resize(w);
  Y.resize(w);
  if (ry != nullptr)
    row_portable_math<true>(k, col, rx, ry, ry0, w, X.data(), Y.data(), depth);
  else
    row_portable_math<false>(k, col, rx, ry, ry0, w, X.data(), Y.data(), depth);
  float* q = quads;
  for (uint32_t x = 0; x < w; ++x) {  // branch-free: always write, advance if valid
    q[0] = X[x];
    q[1] = Y[x];
    q[2] = depth[x];
    q[3] = I != nullptr ? I[x] : 0.0f;
    q += std::isnan(depth[x]) ? 0 : 4;
  }
  return static_cast<uint32_t>((q - quads) / 4);
}

// Finite entries of v[0, n) (the upper bound of the points they can make).
uint64_t count_finite_portable(const float* v, size_t n) {
  uint64_t m = 0;
  for (size_t i = 0; i < n; ++i) m += std::abs(v[i]) <= FLT_MAX ? 1u : 0u;
  return m;
}

}  // namespace detail

namespace {

using detail::Coeffs;
using detail::count_finite_avx2;
using detail::count_finite_portable;
using detail::row_avx2;
using detail::row_portable;
using detail::RowFn;

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

bool cpu_has_avx2_fma() noexcept {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0 && __builtin_cpu_supports("fma") != 0;
  }();
  return has;
}

}  // namespace

bool cpu_has_avx2() noexcept { return cpu_has_avx2_fma(); }

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
  // short tables instead of 2 x width x height floats to stream through
  // memory on every call. A camera with lens distortion needs the
  // undistorted ray of every pixel: full tables.
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
    ray_xd_.resize(width);
    ray_x_lo_.resize(width);
    ray_yd_.resize(height);
    ray_x_.resize(width);
    ray_y_.resize(height);
    for (uint32_t x = 0; x < width; ++x) {
      ray_xd_[x] = k.ray(x, 0).x;
      ray_x_[x] = static_cast<float>(ray_xd_[x]);
      ray_x_lo_[x] = static_cast<float>(ray_xd_[x] - static_cast<double>(ray_x_[x]));
    }
    for (uint32_t y = 0; y < height; ++y) {
      ray_yd_[y] = k.ray(0, y).y;
      ray_y_[y] = static_cast<float>(ray_yd_[y]);
    }
  }
  for (const float v : ray_x_) ray_max_ = std::max(ray_max_, std::abs(v));
  for (const float v : ray_y_) ray_max_ = std::max(ray_max_, std::abs(v));
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
  const Coeffs k{a_[0], a_[1],  a_[2],  b_[0],  b_[1],  b_[2], at_, bt_, r2_[0], r2_[1], r2_[2],
                 r2t_,  projector_.fx * projector_.fx, projector_.cx,
                 static_cast<double>(FLT_MAX) / 4.0 / std::max(1.0, static_cast<double>(ray_max_)),
                 per_pixel_rays_ ? nullptr : ray_xd_.data(),
                 per_pixel_rays_ ? nullptr : ray_x_lo_.data()};
  const bool avx2 = isa == TriangulateIsa::avx2 ||
                    (isa == TriangulateIsa::automatic && cpu_has_avx2_fma());
  const RowFn row = avx2 ? row_avx2 : row_portable;
  // A distorted projector's column is not a plane; with the decoded row the
  // pixel's ideal (undistorted) column is known and its plane is exact.
  const bool correct_projector = projector_.distorted() && map.row != nullptr;
  out.depth_mm.resize(n);
  // Bands of contiguous rows, one per thread; band b's points follow those of
  // bands 0..b-1 in row-major order.
  const uint32_t bands = std::clamp<uint32_t>(threads, 1u, std::max(h, 1u));
  const auto band_row = [&](uint32_t b) { return static_cast<uint32_t>(uint64_t{h} * b / bands); };
  // Pass 1: an upper bound on each band's points (its finite columns), so
  // each band knows where its points go before they exist: no growing vectors.
  std::vector<uint64_t> first(size_t{bands} + 1, 0);  // first[b]: band b's first slot
  std::vector<uint64_t> made(bands, 0);                // points band b actually made
  parallel_rows(bands, bands, [&](uint32_t b0, uint32_t b1) {
    for (uint32_t b = b0; b < b1; ++b)
      first[size_t{b} + 1] = (avx2 ? count_finite_avx2 : count_finite_portable)(
          map.col + size_t{band_row(b)} * w, size_t{band_row(b + 1) - band_row(b)} * w);
  });
  for (uint32_t b = 0; b < bands; ++b) first[size_t{b} + 1] += first[b];
  out.points.resize(first[bands] * 4);
  float* const pts = out.points.data();
  // Pass 2: rays meet planes row by row; each row's depth and packed points
  // go to L1 scratch, then stream to their places.
  parallel_rows(bands, bands, [&](uint32_t b0, uint32_t b1) {
    std::vector<float> depth(w), quads(size_t{w} * 4 + 32), cu(correct_projector ? w : 0);
    for (uint32_t b = b0; b < b1; ++b) {
      uint64_t m = 0;
      for (uint32_t y = band_row(b); y < band_row(b + 1); ++y) {
        const size_t i0 = size_t{y} * w;
        const float* rx = ray_x_.data() + (per_pixel_rays_ ? i0 : 0);
        const float* ry = per_pixel_rays_ ? ray_y_.data() + i0 : nullptr;
        const double ry0 = per_pixel_rays_ ? 0.0 : ray_yd_[y];
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
        const float* I = map.intensity != nullptr ? map.intensity + i0 : nullptr;
        const uint32_t got = row(k, col_row, rx, ry, ry0, I, w, depth.data(), quads.data());
        stream_floats(out.depth_mm.data() + i0, depth.data(), w);
        stream_floats(pts + (first[b] + m) * 4, quads.data(), size_t{got} * 4);
        m += got;
      }
      made[b] = m;
    }
    stream_fence();
  });
  // Close the gaps of finite columns that made no point (rare: behind a
  // device, parallel rays); a no-op when every finite column made one.
  uint64_t total = 0;
  for (uint32_t b = 0; b < bands; ++b) {
    if (total != first[b] && made[b] > 0)
      std::memmove(pts + total * 4, pts + first[b] * 4, made[b] * 4 * sizeof(float));
    total += made[b];
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
