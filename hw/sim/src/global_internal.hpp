// SPDX-License-Identifier: MIT
// Helpers shared by the global transport models (global_*.cpp): view access, filters, the dense solver.
//
// Internal to procam_sim (not installed). All functions are pure or write only
// their output arguments; `threads` parallelises inside one call.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "procam/base/geometry.hpp"
#include "procam/hw/sim/renderer.hpp"

namespace procam::sim::detail {

inline Vec3 view_point(const PreparedView& v, size_t i) {
  return {static_cast<double>(v.point_mm[3 * i]), static_cast<double>(v.point_mm[3 * i + 1]),
          static_cast<double>(v.point_mm[3 * i + 2])};
}
inline Vec3 view_normal(const PreparedView& v, size_t i) {
  return {static_cast<double>(v.normal[3 * i]), static_cast<double>(v.normal[3 * i + 1]),
          static_cast<double>(v.normal[3 * i + 2])};
}

// Footprint of camera pixel i on its surface, mm²: z²/(fx·fy) / cosθ_c, with
// cosθ_c clamped at 0.1 (grazing pixels).
inline double pixel_area(const PreparedView& v, size_t i) {
  const Vec3 p = view_point(v, i);
  const Vec3 n = view_normal(v, i);
  const double cos_c = std::max(0.1, std::abs(dot(n, p)) / norm(p));
  return p.z * p.z / (v.camera.intrinsics.fx * v.camera.intrinsics.fy) / cos_c;
}

// Solves X = A⁻¹·R in place (R becomes X) for A strictly diagonally dominant
// by rows (no pivoting needed). Both N×N row-major doubles. (global_solver.cpp)
void solve_dense(std::vector<double>& A, std::vector<double>& R, size_t n, int threads);

// Blur-stack level k of σ (σ_k ≤ σ < σ_{k+1}, clamped to the top) and the
// variance-matching weight of level k + 1 (renderer.cpp).
std::pair<uint8_t, float> blur_level(double sigma);
// ---- filters (global_filters.cpp) ----

// Gaussian of σ sampled at integers, truncated at 3σ (rounded up; at least
// 1), normalised.
std::vector<float> gaussian_kernel(double sigma);

// Separable blur of a w×h grid with `kernel` (zero outside): out = K ∗ in.
// Both passes run along rows as one saxpy per tap (vectorised), rows split
// over threads. `tmp` is scratch of w·h floats.
void blur_separable(const float* in, float* out, float* tmp, uint32_t w, uint32_t h,
                    const std::vector<float>& kernel, int threads);

// Level l+1 of a pyramid: sums of 2×2 cells of level l (cells past the edge are 0).
void sum_2x2(const float* fine, uint32_t fw, uint32_t fh, float* coarse, uint32_t cw, uint32_t ch);

// fine += bilinear 2× upsampling of coarse (cell centres: fine i ↔ coarse
// i/2 − ¼, i.e. weights ¾ / ¼ to the nearer / farther coarse cell; clamped).
void add_upsampled_2x(const float* coarse, uint32_t cw, uint32_t ch, float* fine, uint32_t fw, uint32_t fh);

}  // namespace procam::sim::detail
