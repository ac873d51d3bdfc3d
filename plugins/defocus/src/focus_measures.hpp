// SPDX-License-Identifier: MIT
// Per-pixel depth cues from the E(3, f) maps of e3_accumulator.hpp:
//   - focus_sweep_mm: the focus settings (uniform in inverse depth);
//   - fbar (thesis Eq. 2.9): the focus index where E(f) peaks, refined by
//     Gaussian interpolation through the peak and its two neighbours;
//   - omega (Eq. 2.10): E(f2) / E(f1);
//   - modulation (Zhang & Nayar 2006, the single-focal baseline): E(f0) / mean;
//   - g_ratio (Eq. 2.8): E_i(f) / E_j(f) for a pixel pair of equal depth.
//
// Validity (every cue): a pixel is invalid (NaN) when it saturated in any
// frame, its mean is below `black_dn` (unlit or black), or the E values the
// cue divides by or takes logarithms of are below `min_modulation` x mean
// (no measurable pattern: noise would decide). fbar is also invalid when the
// peak is the first or last setting (no peak inside the sweep: never
// extrapolated) or the three values around it are flat.
//
// Units: E and mean in DN; fbar in focus-index units (0 .. F-1, fractional);
// omega and modulation are ratios. Threads: functions are reentrant; the map
// functions use `threads` workers of the calling thread's pool.
#pragma once

#include <cstdint>
#include <vector>

#include "e3_accumulator.hpp"
#include "procam/sdk/calibration_table.hpp"

namespace procam::defocus {

struct Validity {
  double black_dn = 5;           // mean below this: black / unlit
  double min_modulation = 0.02;  // E below this fraction of the mean: no pattern
};

// `count` >= 1 focus distances (mm) from near_mm to far_mm, equally spaced in
// 1/f (a thin lens's blur is linear in 1/f - 1/z, so E(f) is the same
// Gaussian-like curve at every depth in this index). count 1: {near_mm}.
// Requires 0 < near_mm < far_mm (or count 1). Throws std::invalid_argument.
std::vector<double> focus_sweep_mm(double near_mm, double far_mm, uint32_t count);

// Offset in [-0.5, 0.5] of the peak of the Gaussian through (-1, em), (0, e0),
// (+1, ep) where e0 >= em, ep > 0 (Eq. 2.9's interpolation: a parabola
// through the logarithms); NaN when the logs are flat (no curvature) or a
// value is not positive.
float gaussian_peak_offset(float em, float e0, float ep) noexcept;

// fbar for one pixel from its E(f), f = 0..F-1 (F >= 3); NaN as above.
float fbar_from_e3(const float* e, uint32_t F, float floor) noexcept;

// Maps over an accumulator's finished sweep. `out` is resized to
// width*height; NaN where invalid. Return the number of valid pixels.
size_t fbar_map(const E3Accumulator& acc, const Validity& rule, uint32_t threads, std::vector<float>& out);
size_t omega_map(const E3Accumulator& acc, uint32_t f1, uint32_t f2, const Validity& rule, uint32_t threads,
                 std::vector<float>& out);
size_t modulation_map(const E3Accumulator& acc, uint32_t f, const Validity& rule, uint32_t threads,
                      std::vector<float>& out);

// The `valid` output map: valid[i] = 255 where a[i] is finite (and b[i] too
// when b is not null), else 0, on `threads` row bands of `rows` rows (a.size()
// must be a multiple of rows; b, when given, a.size() elements). `valid` is
// resized to a.size(); every element is written. Returns the count of 255s.
// Finite is tested on the bits (exponent not all ones), so the loop vectorises.
size_t valid_where_finite(const std::vector<float>& a, const std::vector<float>* b, uint32_t rows, uint32_t threads,
                          std::vector<uint8_t>& valid);

// Whether pixel (x, y) passes the saturation / black tests (not the E tests).
bool usable(const E3Accumulator& acc, uint32_t x, uint32_t y, const Validity& rule) noexcept;

// fbar_map and, when `table` and `depth_mm` are not null, depth_mm =
// table->lookup(fbar) in the same pass, and when `peak` is not null
// peak = max_f E(3, f) (the multi-focal hot path: one read of the E maps,
// per pixel in registers; AVX2 where the CPU has it, see fbar_kernel.hpp).
// Same results as fbar_from_e3 per pixel up to the fast logarithm
// (|error| < 2e-5 in fbar, tested) and as CalibrationTable::lookup up to
// float rounding (same validity, |error| <~ 1e-7 x depth). When `valid` is
// not null it gets the `valid` output map in the same pass: 255 where
// depth_mm (when asked for; else fbar) is finite, else 0 - what
// valid_where_finite would give from that map - and *valid_count (when not
// null) its count of 255s. A fold that `acc` deferred
// (E3Accumulator::defer_final_fold) is done per pixel inside the pass, with
// the same bits as the fold itself; the accumulator keeps it pending.
// Returns the number of valid fbar values.
size_t fbar_depth_map(const E3Accumulator& acc, const Validity& rule, const sdk::CalibrationTable* table,
                      uint32_t threads, std::vector<float>& fbar, std::vector<float>* depth_mm,
                      std::vector<float>* peak = nullptr, std::vector<uint8_t>* valid = nullptr,
                      size_t* valid_count = nullptr);

}  // namespace procam::defocus
