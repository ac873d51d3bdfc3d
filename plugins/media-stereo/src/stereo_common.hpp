// SPDX-License-Identifier: MIT
// Small numeric helpers shared by the binocular and Helmholtz matchers:
// bilinear image sampling, a NaN-propagating box sum over a cost volume, the
// sub-sample parabola, and a symmetric 3x3 eigen-solver.
// Threads: pure functions.
#pragma once

#include <cstdint>
#include <vector>

#include "procam/base/geometry.hpp"

namespace procam::media_stereo {

// Depth hypotheses z_k = z_min + k·z_step, k = 0..count()-1, and the window.
struct DepthSearch {
  double z_min_mm = 380, z_max_mm = 700, z_step_mm = 2;
  int window = 7;                // odd, pixels (box aggregation of the cost)
  double saturation = 1e30;      // image value at/above which a sample is saturated
  double min_signal = 0;         // a pixel's signal (I - B) at/below this is invalid
  uint32_t count() const;
};

// Unit world directions of every pixel of `cam` (row-major); `lengths`, if
// given, receives |ray_world| (so depth z is distance / length).
struct PinholeCamera;
std::vector<Vec3> unit_rays(const PinholeCamera& cam, std::vector<double>* lengths = nullptr);

// Bilinear sample of a row-major w×h image at (u, v); NaN outside
// [0, w-1]×[0, h-1] or if any of the four neighbours is >= saturation.
double sample_bilinear(const std::vector<float>& img, uint32_t w, uint32_t h, double u, double v,
                       double saturation = 1e30);

// The four bilinear taps (index, weight) of (u, v); false outside the image.
bool bilinear_taps(uint32_t w, uint32_t h, double u, double v, size_t idx[4], double wt[4]);

// In-place box sum over a (2r+1)² window of each of `slices` w×h slices
// (slice-major). A NaN anywhere in a window makes its sum NaN; windows are
// clipped at the image border.
void box_sum(std::vector<float>& vol, uint32_t w, uint32_t h, uint32_t slices, int r);

// Argmin over k of cost[k·stride] (finite values only) refined by a parabola
// through the neighbours; returns NaN if no finite value or the minimum lies
// on the first/last hypothesis (depth out of the searched range).
double refined_argmin(const float* cost, size_t stride, uint32_t count);

// Eigen-decomposition of a symmetric 3x3 matrix (Jacobi): eigenvalues in
// ascending order, eigenvectors[i] unit, for eigenvalues[i].
void symmetric_eigen3(const double a[3][3], double eigenvalues[3], Vec3 eigenvectors[3]);

}  // namespace procam::media_stereo
