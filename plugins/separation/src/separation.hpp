// SPDX-License-Identifier: MIT
// Direct–global separation under projector defocus (thesis §2.5): the
// per-pixel equations and the map-level loops the sessions call at end_round.
//
// Model (thesis Eq. 2.11–2.14, Nayar et al. 2006): under a checkerboard with
// as many on as off pixels, at focus setting f,
//   e⁺(f) = β⁺(f) L_d + ½ L_g,   e⁻(f) = β⁻(f) L_d + ½ L_g,
// β± = max / min over the shifts of the defocused pattern at the pixel
// (β⁺ = 1, β⁻ = 0 in focus). L_d, L_g are the direct and global light under a
// full-white pattern.
//
// Projector black level and ambient light. A real (and the simulated)
// projector emits b > 0 of white for pattern value 0, and scene light that
// does not come from the projector adds to every frame. With one frame under
// an all-black pattern, k = b (L_d + L_g) + A, each signal is normalised as
//   s = (v − k) / (1 − b)                                        (N)
// which is exactly the e of the equations above (the light pattern value 1
// adds over value 0): b and A cancel. Without a black frame k = 0 and the
// black level is removed from the extrema by Nayar et al.'s correction
// (L_g = 2 (e⁻ − b e⁺) / (1 − b²)); ambient light then stays in L_g.
//
// Units: frame units (DN for integer frames; the stored value for F32).
// Outputs are F32 maps, NaN where invalid: saturated (an integer sample at
// full scale), too dark (peak signal below dark_fraction of full scale),
// non-finite input, no extremum inside the focus sweep (S2), depth outside
// the calibration table or contrast below min_contrast (S3). Estimates are
// clamped at 0 (radiance is non-negative; noise can push them below).
// Threads: the map functions are reentrant and use sdk::parallel_rows
// internally; the per-pixel functions are pure.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "extrema.hpp"
#include "procam/sdk/calibration_table.hpp"

namespace procam::separation {

inline constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

struct Components {
  float direct = kNaN;  // L_d, frame units
  float global = kNaN;  // L_g, frame units
  bool valid() const noexcept { return std::isfinite(direct) && std::isfinite(global); }
};

// Eq. 2.15–2.16 (with β⁺ = 1, β⁻ = 0 this is Nayar et al.'s L_d = max − min,
// L_g = 2 min): direct = ē⁺ − ē⁻, global = 2 ē⁻, from normalised extrema (N).
inline Components from_extrema(double s_max, double s_min) noexcept {
  if (!std::isfinite(s_max) || !std::isfinite(s_min)) return {};
  const double d = s_max - s_min, g = 2.0 * s_min;
  return {static_cast<float>(d > 0 ? d : 0.0), static_cast<float>(g > 0 ? g : 0.0)};
}

// Eq. 2.17–2.18: direct = (e⁺ − e⁻) / (β⁺ − β⁻), global = e − direct, where
// e is the full-white signal and `contrast` = β⁺ − β⁻ at the pixel's depth
// (from the calibration table, Eq. 2.19). Invalid when the contrast is not
// finite or below min_contrast (the denominator → 0 amplifies noise without
// bound).
inline Components from_contrast(double s_max, double s_min, double s_white, double contrast,
                                double min_contrast) noexcept {
  if (!std::isfinite(s_max) || !std::isfinite(s_min) || !std::isfinite(s_white) || !std::isfinite(contrast) ||
      !(contrast >= min_contrast) || !(min_contrast > 0))
    return {};
  double d = (s_max - s_min) / contrast;
  if (d < 0) d = 0;
  const double g = s_white - d;
  return {static_cast<float>(d), static_cast<float>(g > 0 ? g : 0.0)};
}

// Eq. 2.19: β⁺ − β⁻ = (e⁺ − e⁻) / e on a plane without global light. NaN
// when e is not positive.
inline double plane_contrast(double s_max, double s_min, double s_white) noexcept {
  if (!(s_white > 0) || !std::isfinite(s_max) || !std::isfinite(s_min)) return std::nan("");
  return (s_max - s_min) / s_white;
}

// The extremum of samples y[0..n) taken at equally spaced focus settings, by
// Gaussian interpolation (thesis §2.5.1, as Eq. 2.9's f̄ in §2.4.1): a
// parabola through ln y at the extreme sample k and its two neighbours,
//   ln y(k + t) ≈ L₀ + (L₊ − L₋) t / 2 + (L₊ − 2L₀ + L₋) t² / 2,
// whose vertex is at t = (L₋ − L₊) / (2 (L₊ − 2L₀ + L₋)), |t| ≤ ½, with value
// exp(L₀ − (L₊ − L₋)² / (8 (L₊ − 2L₀ + L₋))).
// `maximum` picks the largest (e⁺) or smallest (e⁻) sample. The extremum
// must lie inside the sweep: k is searched among the interior samples
// 1..n−2 only, and the result is invalid when an end sample beats y[k] by
// more than `tie` (a near-tie within `tie` counts as flat, i.e. inside; the
// curve is never extrapolated past its ends). With a flat or non-positive
// triple (denominator 0, ln undefined) the sample y[k] itself is returned.
struct Extremum {
  double value = std::nan("");
  double index = std::nan("");  // fractional setting index of the extremum
  bool valid = false;
};
Extremum gaussian_extremum(const float* y, size_t n, bool maximum, double tie) noexcept;

// What the map loops need besides the frames.
struct Settings {
  double black_level = 0;        // b, fraction of white the projector emits for pattern value 0
  double full_scale = 255;       // frame value of white (2^bits − 1; 1 for F32)
  bool integer_frames = true;    // saturation test (an integer sample at full_scale) applies
  double dark_fraction = 0.01;   // peak normalised signal below this × full_scale: too dark
  double tie_fraction = 0.005;   // S2: end sample beating the interior extremum by more: outside the sweep
  double min_contrast = 0.1;     // S3: smallest β⁺ − β⁻ accepted
  uint32_t threads = 1;
};

struct Maps {
  std::vector<float> direct, global;  // width*height, NaN invalid
  std::vector<float> best_focus;      // S2 only: fractional focus-setting index of max e⁺ (else empty)
  size_t valid = 0;                   // pixels with both components finite
};

// S1's per-row kernel (exposed for tests): direct/global of n pixels from the
// max, min and (optional, nullptr = none) black-frame rows, in float.
struct CheckerRowConstants {
  float b = 0, inv_1mb = 1, inv_1mb2 = 1;  // b, 1/(1 − b), 1/(1 − b²)
  float dark = 0;                          // smallest valid peak signal
  float saturation = INFINITY;             // raw max at or above: saturated (integer frames)
};
inline CheckerRowConstants checker_constants(const Settings& s) noexcept {
  CheckerRowConstants k;
  k.b = static_cast<float>(s.black_level);
  k.inv_1mb = static_cast<float>(1.0 / (1.0 - s.black_level));
  k.inv_1mb2 = static_cast<float>(1.0 / (1.0 - s.black_level * s.black_level));
  k.dark = static_cast<float>(s.dark_fraction * s.full_scale / (1.0 - s.black_level));
  k.saturation = s.integer_frames ? static_cast<float>(s.full_scale) : INFINITY;
  return k;
}
// Samples in the frames' own type (U8, U16 or F32); bk may be nullptr (no
// black frame). Returns the number of valid pixels.
template <class T>
size_t checker_row(const CheckerRowConstants& k, const T* mx, const T* mn, const T* bk, float* d, float* g,
                   uint32_t n) noexcept;
// The portable 8-bit kernel, for the SIMD-vs-scalar test.
size_t checker_row_scalar(const CheckerRowConstants& k, const uint8_t* mx, const uint8_t* mn, const uint8_t* bk,
                          float* d, float* g, uint32_t n) noexcept;

// S1 (Nayar et al. 2006; Eq. 2.15–2.16 with β⁺ = 1, β⁻ = 0). `black`: the
// all-black frame (count() == 1) or nullptr (see the header comment).
void separate_checker(const Extrema& checker, const Extrema* black, const Settings& s, Maps& out);

// S2 (§2.5.1, Eq. 2.15–2.16): per pixel, ē⁺ = Gaussian-interpolated maximum
// over f of e⁺(f), ē⁻ = minimum of e⁻(f); `per_focus[k]` holds the extrema of
// focus setting k (equally spaced, in order). Needs >= 3 settings.
void separate_multi_focal(std::span<const Extrema> per_focus, const Extrema* black, const Settings& s, Maps& out);

// S3 (§2.5.2, Eq. 2.17–2.18): one focus setting, the full-white frame and a
// depth map (mm, camera-sized, NaN unknown); `contrast_from_depth` maps depth
// (x, mm) to β⁺ − β⁻ (y) and returns NaN outside its range.
void separate_one_focal(const Extrema& checker, const Extrema& white, const Extrema* black,
                        std::span<const float> depth_mm, const sdk::CalibrationTable& contrast_from_depth,
                        const Settings& s, Maps& out);

// Calibration (Eq. 2.19): per valid pixel of a plane without global light,
// the pair (depth mm, β⁺ − β⁻), NaN where invalid; fit with
// sdk::fit_monotonic(depths, contrasts, ...). β⁺ − β⁻ also depends on where
// the pixel falls on the checker grid (the best of the shifts is 0–1.5 px
// off a square's centre); on an inclined plane that phase runs with depth and
// would ripple the table, so the contrast is averaged over a window of
// `window_px` × `window_px` camera pixels (one pattern period) first.
void plane_contrast_samples(const Extrema& checker, const Extrema& white, const Extrema* black,
                            std::span<const float> depth_mm, const Settings& s, uint32_t window_px,
                            std::vector<float>& depths, std::vector<float>& contrasts);

// In-place mean of the finite values of a w×h map over a window × window box
// centred on each pixel (summed-area tables); pixels that were NaN stay NaN.
void box_mean_finite(std::vector<float>& v, uint32_t w, uint32_t h, uint32_t window);

}  // namespace procam::separation
