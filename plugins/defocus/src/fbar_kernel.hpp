// SPDX-License-Identifier: MIT
// Internals of the multi-focal hot path (fbar_depth_map in focus_measures.hpp):
// one row of fbar (thesis Eq. 2.9, Gaussian interpolation) + the table lookup,
// as a scalar kernel and its AVX2 twin (fbar_avx2.cpp) that gives
// bit-identical results (same float operations in the same order, no FMA);
// both are tested against each other and against the per-pixel reference
// (fbar_from_e3 + CalibrationTable::lookup) in focus_measures_test.cpp.
//
// Per pixel, in registers: the running argmax over the F settings (first
// maximum wins) with the values left and right of it, then Eq. 2.9 from the
// three, the validity tests of focus_measures.hpp, the saturation bit, and
// depth = table(fbar). One read of the F E-maps, the mean and the bits; no
// intermediate maps (the AVX2 kernel keeps 256 pixels of fbar in a stack
// buffer between its f-bar loop and its lookup loop, see fbar_avx2.cpp).
//
// Threads: the functions are reentrant; a FloatTable is read-only once built.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "procam/sdk/calibration_table.hpp"

namespace procam::defocus::detail {

// CalibrationTable::lookup in float, vectorisable: a uniform grid over x whose
// bins hold at most one breakpoint each, so x picks one of its bin's two
// lines with one compare (per 8 pixels in the AVX2 kernel: one 8-lane gather
// of thresholds and two 4-lane gathers of (y, slope) pairs).
// Thresholds are rounded so the float compares decide exactly as the double
// ones of CalibrationTable::lookup (x_f >= lo  <=>  double(x_f) >= x_min, and
// likewise at every breakpoint): validity and segment always agree with the
// reference; the value differs by float rounding only (|error| <~ 1e-7 x
// |depth|, tested at 2e-6).
struct FloatTable {
  bool usable = false;    // false: no table, or no grid <= kMaxBins separates its breakpoints
  float lo = 0, hi = 0;   // valid x range (see above)
  float x0 = 0, inv_dx = 0, dx = 0;
  int32_t last_bin = 0;   // bin(hi)
  std::vector<float> thr;         // per bin: x >= thr takes the second line
  // Per bin 2 lines, line i = 2 bin + side as the pair lines[2i] = y at the
  // bin's left edge xb = x0 + bin * dx, lines[2i + 1] = slope:
  // y = lines[2i] + (x - xb) * lines[2i + 1]. Pairs, not two arrays, so the
  // AVX2 kernel fetches both with one 64-bit gather element per pixel.
  std::vector<float> lines;
  static constexpr int32_t kMaxBins = 1 << 16;
  explicit FloatTable(const sdk::CalibrationTable* table);
  // The bin of x: the same float operations in both kernels.
  int32_t bin(float x) const noexcept;
  // NaN outside [lo, hi] or for NaN x; requires usable.
  float lookup(float x) const noexcept;
};

// One row: e[f] points at the row of E(f), f < F (F >= 1), except for
// f == fold_f when `fold` is set: that setting's E is folded here from its
// four int16 buckets (fold[b * fold_stride + x], E3Accumulator's deferred
// last fold) with e3_from_buckets' float operations.
struct RowArgs {
  const float* const* e;
  uint32_t F;
  const float* mean;
  const uint8_t* sat;   // saturation bits of the row (bit x % 8 of byte x / 8)
  float black, min_mod; // Validity in DN and as a fraction of the mean
  const FloatTable* table;  // null: no depth
  float* fbar;          // out: fbar, NaN where invalid
  float* depth;         // out (when table): depth, NaN where fbar is NaN or outside the table
  float* peak;          // out (optional): max_f E(f)
  uint8_t* valid;       // out (optional): 255 where depth (with table) or else fbar is finite, 0 elsewhere
  size_t* valid_count;  // with valid: incremented by the number of 255s written
  const int16_t* fold;  // null: every E(f) from e[f]
  size_t fold_stride;   // elements between buckets (width*height)
  uint32_t fold_f;
};

// Both write pixels [x_begin, x_end) and return how many got a finite fbar.
size_t fbar_row_scalar(const RowArgs& a, uint32_t x_begin, uint32_t x_end) noexcept;
// x_begin must be a multiple of 8 (one byte of saturation bits per step).
// Call only where sdk::cpu_has_avx2().
size_t fbar_row_avx2(const RowArgs& a, uint32_t x_begin, uint32_t x_end) noexcept;

}  // namespace procam::defocus::detail
