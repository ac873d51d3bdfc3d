// SPDX-License-Identifier: MIT
// Pattern generators that write into sdk::Plan frames: binary stripes (also
// Gaussian pre-filtered against aliasing),
// shifted periodic stripe series (thesis §2.2: period 24 px shifted one pixel
// at a time), sinusoids, checkerboards and shifted checkerboard series
// (thesis §2.5: 8x8 px checkers shifted 5 x 5 times by 3 px), and geometric
// exposure brackets.
//
// Coordinates: projector pixel (x, y), x to the right, y down; pixel centres
// at integers. "Vertical" stripes vary with x (column codes), "horizontal"
// ones with y. Values are intensities in [0, 1], written as U8 round(255 v),
// U16 round(65535 v) or F32 v, matching the frame's pixel type (Plan::add_frame).
// Shifts are in pixels and may be negative or exceed the period: a pattern
// shifted by s shows at x what the unshifted one shows at x - s.
// Errors: std::invalid_argument for a plugin bug (period or square size 0,
// amplitude/offset outside [0, 1], bad bracket range) and std::out_of_range
// for a frame index outside the plan; the SDK's ABI wrapper turns them into
// error codes. Thread-safety: the Plan is thread-bound (docs/threading.md); the functions are
// reentrant.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "procam/sdk/plan.hpp"

namespace procam::sdk {

enum class StripeAxis {
  vertical,    // stripes vary along x (a column pattern)
  horizontal,  // stripes vary along y (a row pattern)
};

// Sets every pixel of frame `i` to value(x, y) (clamped to [0, 1]) in the
// frame's pixel type.
template <class ValueFn>
void fill_pattern(Plan& plan, uint32_t i, ValueFn&& value) {
  const procam_image& img = plan.pattern(i);
  const uint32_t w = img.width, h = img.height;
  const auto clamp01 = [](double v) { return v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v); };
  switch (img.pixel_type) {
    case PROCAM_PIXEL_U8: {
      std::span<uint8_t> px = plan.pattern_u8(i);
      for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x)
          px[size_t{y} * w + x] = static_cast<uint8_t>(std::lround(255.0 * clamp01(value(x, y))));
      break;
    }
    case PROCAM_PIXEL_U16: {
      std::span<uint16_t> px = plan.pattern_u16(i);
      for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x)
          px[size_t{y} * w + x] = static_cast<uint16_t>(std::lround(65535.0 * clamp01(value(x, y))));
      break;
    }
    default: {
      std::span<float> px = plan.pattern_f32(i);
      for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x) px[size_t{y} * w + x] = static_cast<float>(clamp01(value(x, y)));
      break;
    }
  }
}

namespace detail {
// t mod m in [0, m) for any sign of t (m > 0).
inline int64_t floor_mod(int64_t t, int64_t m) noexcept {
  const int64_t r = t % m;
  return r < 0 ? r + m : r;
}
// floor(t / m) for any sign of t (m > 0).
inline int64_t floor_div(int64_t t, int64_t m) noexcept {
  return (t - floor_mod(t, m)) / m;
}
}  // namespace detail

// Binary stripes of `period_px` (>= 2): with t = x (vertical) or y
// (horizontal), a pixel is white (1) where (t - shift_px) mod period is below
// period / 2 — the first ceil(period / 2) pixels of each period — else black.
// So the unshifted pattern turns white at t = 0, period, 2 period, ...
inline void binary_stripes(Plan& plan, uint32_t i, StripeAxis axis, uint32_t period_px,
                           int64_t shift_px = 0) {
  if (period_px < 2) throw std::invalid_argument("binary_stripes: period must be >= 2 px");
  const int64_t p = period_px;
  fill_pattern(plan, i, [&](uint32_t x, uint32_t y) {
    const int64_t t = axis == StripeAxis::vertical ? int64_t{x} : int64_t{y};
    return 2 * detail::floor_mod(t - shift_px, p) < p ? 1.0 : 0.0;
  });
}

// binary_stripes (same period, shift and white pixels) blurred by a Gaussian
// of sigma_px projector pixels: the value at pixel centre t is the fraction of
// a Gaussian around t that falls on white, i.e. the sum over the white
// intervals [n·period + shift - 0.5, n·period + shift - 0.5 + ceil(period/2))
// of Φ((t - a)/σ) - Φ((t - b)/σ). A pre-filter against aliasing (thesis §2.4,
// footnote 5): harmonics k of the period are scaled by exp(-2π²σ²k²/period²)
// (of the continuous square wave; sampling at pixel centres adds aliases of
// harmonics k ± period, negligible for sigma >= 1).
// sigma_px 0 gives binary_stripes exactly. Requires period_px >= 2 and
// 0 <= sigma_px <= period_px.
inline void smoothed_stripes(Plan& plan, uint32_t i, StripeAxis axis, uint32_t period_px,
                             int64_t shift_px, double sigma_px) {
  if (period_px < 2) throw std::invalid_argument("smoothed_stripes: period must be >= 2 px");
  if (!(sigma_px >= 0.0) || !(sigma_px <= double(period_px)))
    throw std::invalid_argument("smoothed_stripes: sigma must be in [0, period] px");
  if (sigma_px == 0.0) {
    binary_stripes(plan, i, axis, period_px, shift_px);
    return;
  }
  const int64_t p = period_px;
  const double white = double((p + 1) / 2);
  // One period of values by phase m = (t - shift) mod period.
  std::vector<double> table(period_px);
  const auto phi = [&](double u) { return 0.5 * std::erfc(-u / (sigma_px * std::numbers::sqrt2)); };
  for (int64_t m = 0; m < p; ++m) {
    double v = 0;
    const int64_t reach = int64_t(std::ceil(6.0 * sigma_px / double(p))) + 1;  // periods within 6 sigma
    for (int64_t n = -reach; n <= reach; ++n) {
      const double a = double(n * p) - 0.5, b = a + white;
      v += phi(double(m) - a) - phi(double(m) - b);
    }
    table[size_t(m)] = v;
  }
  fill_pattern(plan, i, [&](uint32_t x, uint32_t y) {
    const int64_t t = axis == StripeAxis::vertical ? int64_t{x} : int64_t{y};
    return table[size_t(detail::floor_mod(t - shift_px, p))];
  });
}

// Appends `count` frames of width x height, frame k showing binary_stripes
// shifted by k * step_px, labelled "<label> shift <k>". Returns the index of
// the first. Thesis §2.2: period 24, count 24, step 1 (every phase once).
inline uint32_t add_shifted_stripes(Plan& plan, const std::string& label, uint32_t width,
                                    uint32_t height, StripeAxis axis, uint32_t period_px,
                                    uint32_t count, int64_t step_px = 1,
                                    procam_pixel_type type = PROCAM_PIXEL_U8) {
  const uint32_t first = plan.size();
  for (uint32_t k = 0; k < count; ++k) {
    const uint32_t i = plan.add_frame(label + " shift " + std::to_string(k), width, height, type);
    binary_stripes(plan, i, axis, period_px, int64_t{k} * step_px);
  }
  return first;
}

// Sinusoid offset + amplitude * cos(2 pi t / period_px - phase_rad), t = x
// (vertical) or y (horizontal): its maxima lie at t = period * phase / (2 pi)
// + n period. Requires period_px > 0, amplitude >= 0 and
// [offset - amplitude, offset + amplitude] inside [0, 1].
inline void sinusoid(Plan& plan, uint32_t i, StripeAxis axis, double period_px, double phase_rad,
                     double amplitude = 0.5, double offset = 0.5) {
  if (!(period_px > 0.0) || !std::isfinite(period_px))
    throw std::invalid_argument("sinusoid: period must be a positive number of px");
  if (!(amplitude >= 0.0) || !(offset - amplitude >= 0.0) || !(offset + amplitude <= 1.0) ||
      !std::isfinite(phase_rad))
    throw std::invalid_argument("sinusoid: offset +- amplitude must lie in [0, 1]");
  const double k = 2.0 * std::numbers::pi / period_px;
  fill_pattern(plan, i, [&](uint32_t x, uint32_t y) {
    const double t = axis == StripeAxis::vertical ? double(x) : double(y);
    return offset + amplitude * std::cos(k * t - phase_rad);
  });
}

// Checkerboard of square_px x square_px squares: pixel (x, y) is white where
// floor((x - shift_x) / s) + floor((y - shift_y) / s) is even, so the square
// whose top-left corner is (shift_x, shift_y) is white.
inline void checkerboard(Plan& plan, uint32_t i, uint32_t square_px, int64_t shift_x = 0,
                         int64_t shift_y = 0) {
  if (square_px == 0) throw std::invalid_argument("checkerboard: square size must be >= 1 px");
  const int64_t s = square_px;
  fill_pattern(plan, i, [&](uint32_t x, uint32_t y) {
    const int64_t q = detail::floor_div(int64_t{x} - shift_x, s) + detail::floor_div(int64_t{y} - shift_y, s);
    return detail::floor_mod(q, 2) == 0 ? 1.0 : 0.0;
  });
}

// Appends shifts x shifts checkerboards, shifted by (kx * step_px, ky * step_px)
// for ky, kx in [0, shifts) (row-major: kx fastest), labelled
// "<label> shift <kx>,<ky>". Returns the index of the first. Thesis §2.5:
// square 8, shifts 5, step 3 (25 frames; with step < square every pixel is
// lit in some frames and dark in others, so max/min give direct/global).
inline uint32_t add_shifted_checkerboards(Plan& plan, const std::string& label, uint32_t width,
                                          uint32_t height, uint32_t square_px, uint32_t shifts,
                                          int64_t step_px, procam_pixel_type type = PROCAM_PIXEL_U8) {
  const uint32_t first = plan.size();
  for (uint32_t ky = 0; ky < shifts; ++ky)
    for (uint32_t kx = 0; kx < shifts; ++kx) {
      const uint32_t i = plan.add_frame(
          label + " shift " + std::to_string(kx) + "," + std::to_string(ky), width, height, type);
      checkerboard(plan, i, square_px, int64_t{kx} * step_px, int64_t{ky} * step_px);
    }
  return first;
}

// Exposure bracket: `count` exposure times in µs from min_us to max_us in a
// geometric series (constant ratio (max/min)^(1/(count-1)); the first is
// min_us and the last max_us exactly). count 1 gives {min_us}. Requires
// 0 < min_us <= max_us (finite) and count >= 1. Assign them to frames with
// plan.settings(i).exposure_us.
inline std::vector<double> exposure_bracket(double min_us, double max_us, uint32_t count) {
  if (!(min_us > 0.0) || !(max_us >= min_us) || !std::isfinite(max_us) || count == 0)
    throw std::invalid_argument("exposure_bracket: needs 0 < min_us <= max_us and count >= 1");
  std::vector<double> e(count);
  for (uint32_t k = 0; k < count; ++k)
    e[k] = count == 1 ? min_us : min_us * std::pow(max_us / min_us, double(k) / double(count - 1));
  if (count > 1) e.back() = max_us;  // exact despite rounding of pow
  return e;
}

}  // namespace procam::sdk
