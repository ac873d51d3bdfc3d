// SPDX-License-Identifier: MIT
// Private to the toolkit: the row kernels of ColumnTriangulator::run
// (triangulate.cpp: the portable twin; triangulate_avx2.cpp: AVX2 + FMA) and
// what they share. Thread-safety: pure functions of their arguments.
#pragma once

#include <cstddef>
#include <cstdint>

namespace procam::sdk::detail {

// The ray-plane intersection of the header (the camera ray x = s d meets the
// plane n(c).(x - t) = 0 at s = n(c).t / n(c).d; the thesis takes this
// column-plane triangulation as given, e.g. the light-plane geometry of its
// Fig. 5.7a, and has no equation number for it), with
// d = (dx, dy, 1) and n(c) = a + c b split by what each term depends on:
//   D = n(c).d = P + c Q,  P = a0 dx + (a1 dy + a2),  Q = b0 dx + (b1 dy + b2)
//   N = n(c).t = at + c bt
//   s = N / D;  point (s dx, s dy, s)
//   z in the projector frame: pz = s Rz - r2t,  Rz = r20 dx + (r21 dy + r22)
//   parallel test |D| < 1e-12 |n||d|, squared: D^2 < 1e-24 nn dd with
//   nn = |n(c)|^2 = |n_p(c)|^2 = fx_p^2 + (c - cx_p)^2 (R is a rotation) and
//   dd = |d|^2 = dx^2 + (dy^2 + 1).
// The bracketed terms depend on the row only (pinhole camera): computed once
// per row, so a pixel costs four FMAs for P, Q, Rz, dd, two for D and N, one
// division, one FMA for pz and two multiplies for x and y.
struct Coeffs {
  double a0, a1, a2, b0, b1, b2, at, bt, r20, r21, r22, r2t, fx2, cx;
  double smax;  // FLT_MAX / 4 / max(1, |ray x|, |ray y|): s below it cannot overflow x, y
  // Pinhole camera: the rays' x by column in double (the reference's exact
  // rays, so n.d and the parallel test match it to ~1e-16); null with
  // per-pixel (lens-distortion) rays, which are float tables.
  const double* ray_x;
  const float* ray_x_lo;  // ray_x - float(ray_x), as floats (pinhole; else null)
};

// The per-row terms of a ray with y component dy.
struct RowTerms {
  double p, q, rz, dd;
};
inline RowTerms row_terms(const Coeffs& k, double dy) {
  return {k.a1 * dy + k.a2, k.b1 * dy + k.b2, k.r21 * dy + k.r22, dy * dy + 1.0};
}

// One row's output: depth (w floats, NaN: no point) and the row's points
// packed as x, y, z, intensity quads; returns the number of points.
// col, rx: w floats (rx: the rays' x as floats; k.ray_x, when set, the same
// in double); ry: w floats (per-pixel rays) or null (ry0 for the row);
// I: w floats or null (intensity 0). depth must hold w floats, quads w*4 + 32.
using RowFn = uint32_t (*)(const Coeffs&, const float* col, const float* rx, const float* ry,
                           double ry0, const float* I, uint32_t w, float* depth, float* quads);

// The portable twin (double arithmetic, any x86-64) and the AVX2 + FMA
// kernel (only where cpu_has_avx2()), both RowFn.
uint32_t row_portable(const Coeffs& k, const float* col, const float* rx, const float* ry,
                      double ry0, const float* I, uint32_t w, float* depth, float* quads);
uint32_t row_avx2(const Coeffs& k, const float* col, const float* rx, const float* ry,
                  double ry0, const float* I, uint32_t w, float* depth, float* quads);

// Finite entries of v[0, n) (the upper bound of the points they can make);
// the AVX2 one only where cpu_has_avx2().
uint64_t count_finite_portable(const float* v, size_t n);
uint64_t count_finite_avx2(const float* v, size_t n);

}  // namespace procam::sdk::detail
