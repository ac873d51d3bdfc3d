// SPDX-License-Identifier: MIT
// Per-pixel depth cues from E(3, f) (see focus_measures.hpp).
#include "focus_measures.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace procam::defocus {
namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
}  // namespace

std::vector<double> focus_sweep_mm(double near_mm, double far_mm, uint32_t count) {
  if (count == 0) throw std::invalid_argument("focus_sweep_mm: count must be >= 1");
  if (count == 1) return {near_mm};
  if (!(near_mm > 0) || !(far_mm > near_mm) || !std::isfinite(far_mm))
    throw std::invalid_argument("focus_sweep_mm: needs 0 < near_mm < far_mm");
  std::vector<double> f(count);
  const double a = 1.0 / near_mm, b = 1.0 / far_mm;
  for (uint32_t k = 0; k < count; ++k) f[k] = 1.0 / (a + (b - a) * double(k) / double(count - 1));
  f.front() = near_mm;
  f.back() = far_mm;
  return f;
}

// Eq. 2.9 refined: ln E is a parabola near the peak for a Gaussian blur
// (E = exp(-c (1/f - 1/z)^2) in the index of a sweep uniform in 1/f), so the
// vertex of the parabola through the three logs is the peak:
//   offset = (l- - l+) / (2 (l- - 2 l0 + l+)).
float gaussian_peak_offset(float em, float e0, float ep) noexcept {
  if (!(em > 0.f) || !(e0 > 0.f) || !(ep > 0.f)) return kNaN;
  const double lm = std::log(double(em)), l0 = std::log(double(e0)), lp = std::log(double(ep));
  const double curvature = lm - 2.0 * l0 + lp;
  if (!(curvature < -1e-9)) return kNaN;  // flat or a minimum: no peak to interpolate
  const double off = 0.5 * (lm - lp) / curvature;
  // |off| <= 0.5 when e0 is the maximum; an exact tie e0 == em or e0 == ep
  // gives +-0.5 up to rounding, which is kept (clamped), not rejected.
  if (!(std::abs(off) <= 0.5 + 1e-4)) return kNaN;  // e0 was not the maximum
  return static_cast<float>(std::clamp(off, -0.5, 0.5));
}

float fbar_from_e3(const float* e, uint32_t F, float floor) noexcept {
  if (F < 3) return kNaN;
  uint32_t k = 0;
  for (uint32_t j = 1; j < F; ++j)
    if (e[j] > e[k]) k = j;
  if (k == 0 || k + 1 == F) return kNaN;  // peak at the edge: outside the sweep, never extrapolated
  if (!(e[k] >= floor) || !(e[k - 1] >= floor) || !(e[k + 1] >= floor)) return kNaN;
  const float off = gaussian_peak_offset(e[k - 1], e[k], e[k + 1]);
  return std::isnan(off) ? kNaN : static_cast<float>(k) + off;
}

bool usable(const E3Accumulator& acc, uint32_t x, uint32_t y, const Validity& rule) noexcept {
  return !acc.saturated(x, y) &&
         static_cast<double>(acc.mean()[size_t{y} * acc.width() + x]) >= rule.black_dn;
}

namespace {
// out[i] = value(i) over the usable pixels (NaN elsewhere and where value is
// NaN), on `threads` row bands; returns the count of finite results.
template <class ValueFn>
size_t map_pixels(const E3Accumulator& acc, const Validity& rule, uint32_t threads, std::vector<float>& out,
                  ValueFn&& value) {
  const uint32_t w = acc.width();
  out.assign(size_t{w} * acc.height(), kNaN);
  std::vector<size_t> counts(acc.height(), 0);
  sdk::parallel_rows(acc.height(), threads, [&](uint32_t y0, uint32_t y1) {
    for (uint32_t y = y0; y < y1; ++y) {
      size_t c = 0;
      for (uint32_t x = 0; x < w; ++x) {
        const size_t i = size_t{y} * w + x;
        if (!usable(acc, x, y, rule)) continue;
        const float v = value(i);
        out[i] = v;
        c += std::isfinite(v) ? 1u : 0u;
      }
      counts[y] = c;
    }
  });
  size_t total = 0;
  for (size_t c : counts) total += c;
  return total;
}
}  // namespace

size_t valid_where_finite(const std::vector<float>& a, const std::vector<float>* b, uint32_t rows, uint32_t threads,
                          std::vector<uint8_t>& valid) {
  valid.resize(a.size());
  if (rows == 0 || a.empty()) return 0;
  const size_t w = a.size() / rows;
  std::vector<size_t> counts(rows, 0);
  const float* pa = a.data();
  const float* pb = b ? b->data() : nullptr;
  uint8_t* pv = valid.data();
  // Finite <=> the exponent bits are not all ones (inf and NaN have them).
  auto finite_bits = [](const float* p, size_t i) {
    uint32_t u;
    std::memcpy(&u, p + i, sizeof u);
    return (u & 0x7f800000u) != 0x7f800000u;
  };
  sdk::parallel_rows(rows, threads, [&](uint32_t y0, uint32_t y1) {
    for (uint32_t y = y0; y < y1; ++y) {
      const size_t i0 = size_t{y} * w, i1 = i0 + w;
      size_t c = 0;
      if (pb) {
        for (size_t i = i0; i < i1; ++i) {
          const bool ok = finite_bits(pa, i) & finite_bits(pb, i);
          pv[i] = ok ? 255 : 0;
          c += ok;
        }
      } else {
        for (size_t i = i0; i < i1; ++i) {
          const bool ok = finite_bits(pa, i);
          pv[i] = ok ? 255 : 0;
          c += ok;
        }
      }
      counts[y] = c;
    }
  });
  size_t total = 0;
  for (size_t c : counts) total += c;
  return total;
}

size_t fbar_map(const E3Accumulator& acc, const Validity& rule, uint32_t threads, std::vector<float>& out) {
  return fbar_depth_map(acc, rule, nullptr, threads, out, nullptr);
}

// Eq. 2.10: Omega = E(f2) / E(f1); both must carry a measurable pattern (the
// denominator especially: E(f1) -> 0 would make any noise a huge ratio).
size_t omega_map(const E3Accumulator& acc, uint32_t f1, uint32_t f2, const Validity& rule, uint32_t threads,
                 std::vector<float>& out) {
  const float* e1 = acc.e3(f1).data();
  const float* e2 = acc.e3(f2).data();
  return map_pixels(acc, rule, threads, out, [&](size_t i) {
    const float floor = static_cast<float>(rule.min_modulation) * acc.mean()[i];
    if (!(e1[i] >= floor) || !(e2[i] >= floor) || !(e1[i] > 0.f)) return kNaN;
    return e2[i] / e1[i];
  });
}

// Zhang & Nayar 2006: the blur at one focus setting, measured as the 3rd
// harmonic's amplitude over the mean (albedo and fall-off cancel). Global
// light raises the mean and lowers E: this is what the thesis corrects.
size_t modulation_map(const E3Accumulator& acc, uint32_t f, const Validity& rule, uint32_t threads,
                      std::vector<float>& out) {
  const float* e = acc.e3(f).data();
  return map_pixels(acc, rule, threads, out, [&](size_t i) {
    const float m = acc.mean()[i];
    if (!(m > 0.f) || !(e[i] >= static_cast<float>(rule.min_modulation) * m)) return kNaN;
    return e[i] / m;
  });
}

}  // namespace procam::defocus
