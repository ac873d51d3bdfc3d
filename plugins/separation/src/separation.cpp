// SPDX-License-Identifier: MIT
// Direct–global separation: per-pixel equations and map loops (see separation.hpp).
#include "separation.hpp"

#include <algorithm>
#include <atomic>
#include <type_traits>

#include "procam/sdk/simd.hpp"
#include <memory>

namespace procam::separation {

Extremum gaussian_extremum(const float* y, size_t n, bool maximum, double tie) noexcept {
  Extremum r;
  if (n < 3) return r;
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(y[i])) return r;
  const auto better = [maximum](double a, double b) { return maximum ? a > b : a < b; };
  size_t k = 1;
  for (size_t i = 2; i + 1 < n; ++i)
    if (better(y[i], y[k])) k = i;
  const double yk = y[k];
  // An end sample beating the interior extremum by more than `tie`: the
  // extremum lies outside the sweep; never extrapolate.
  for (double end : {double(y[0]), double(y[n - 1])})
    if (maximum ? end > yk + tie : end < yk - tie) return r;
  r.valid = true;
  r.value = yk;
  r.index = double(k);
  const double a = y[k - 1], c = y[k + 1];
  if (!(a > 0) || !(yk > 0) || !(c > 0)) return r;  // ln undefined: keep the sample
  const double lm = std::log(a), l0 = std::log(yk), lp = std::log(c);
  const double curv = lp - 2.0 * l0 + lm;  // < 0 at a maximum, > 0 at a minimum
  // Flat or wrongly curved triple (possible only through near-ties with an
  // end-excluded neighbour): the sample itself.
  if (maximum ? !(curv < -1e-12) : !(curv > 1e-12)) return r;
  const double t = std::clamp((lm - lp) / (2.0 * curv), -0.5, 0.5);
  r.index = double(k) + t;
  r.value = std::exp(l0 - (lp - lm) * (lp - lm) / (8.0 * curv));
  return r;
}

namespace {

// Per-row scratch for the map loops: one float row per input map.
struct Rows {
  explicit Rows(size_t maps, uint32_t width) : data(maps * width), w(width) {}
  float* operator[](size_t i) { return data.data() + i * w; }
  std::vector<float> data;
  size_t w;
};

// Output maps from the plugin's map cache (stale contents: every loop below
// writes every pixel).
void size_maps(Maps& out, size_t n, bool best_focus) {
  sdk::take_map(out.direct, n);
  sdk::take_map(out.global, n);
  if (best_focus)
    sdk::take_map(out.best_focus, n);
  else
    out.best_focus.clear();
  out.valid = 0;
}

// Normalisation (N) of separation.hpp for one pixel.
struct Normaliser {
  explicit Normaliser(const Settings& settings) : s(settings), inv(1.0 / (1.0 - settings.black_level)) {}
  const Settings& s;
  double inv;
  double inv_1mb() const { return inv; }
  bool saturated(float raw_max) const { return s.integer_frames && double(raw_max) >= s.full_scale; }
  // (N): the signal v over the black frame k.
  double operator()(float v, float k) const { return (double(v) - double(k)) * inv_1mb(); }
  double dark_limit() const { return s.dark_fraction * s.full_scale * inv_1mb(); }
};

// Runs fn(y, rows) -> valid pixels of row y, over row bands; returns the total.
template <class Fn>
size_t for_rows(uint32_t width, uint32_t height, uint32_t threads, size_t maps, Fn&& fn) {
  std::atomic<size_t> valid{0};
  sdk::parallel_rows(height, std::max(1u, threads), [&](uint32_t y0, uint32_t y1) {
    Rows rows(maps, width);
    size_t v = 0;
    for (uint32_t y = y0; y < y1; ++y) v += fn(y, rows);
    valid.fetch_add(v, std::memory_order_relaxed);
  });
  return valid.load();
}

size_t count_valid(const float* d, const float* g, uint32_t n) {
  size_t v = 0;
  for (uint32_t x = 0; x < n; ++x) v += (std::isfinite(d[x]) && std::isfinite(g[x])) ? 1u : 0u;
  return v;
}

}  // namespace

namespace {
template <class T, bool kBlack>
size_t checker_row_impl(const CheckerRowConstants& k, const T* __restrict mx, const T* __restrict mn,
                        const T* __restrict bk, float* __restrict d, float* __restrict g, uint32_t n) noexcept {
  // Branch-free, constants in locals and restrict pointers, so the compiler
  // vectorises it. (N) with a black frame; Nayar et al.'s black-level
  // correction without (e⁻ − b e⁺ = ½ (1 + b)(1 − b) L_g). NaN input fails
  // every comparison and yields NaN.
  const float b = k.b, inv = k.inv_1mb, inv2 = k.inv_1mb2, dark = k.dark, sat = k.saturation;
  uint32_t valid = 0;
  for (uint32_t x = 0; x < n; ++x) {
    const float hi = static_cast<float>(mx[x]), lo = static_cast<float>(mn[x]);
    const float dd = (hi - lo) * inv;  // Eq. 2.15 − 2.16: L_d = ē⁺ − ē⁻
    const float sm = kBlack ? (lo - static_cast<float>(bk[x])) * inv : (lo - b * hi) * inv2;  // ē⁻
    const bool ok = (dd + sm >= dark) & (hi < sat);
    // max(v, 0) written as the SIMD kernel's max_ps(v, 0): v > 0 ? v : 0.
    d[x] = ok ? (dd > 0.f ? dd : 0.f) : kNaN;
    const float g2 = 2.f * sm;
    g[x] = ok ? (g2 > 0.f ? g2 : 0.f) : kNaN;  // Eq. 2.16: L_g = 2 ē⁻
    valid += ok ? 1u : 0u;
  }
  return valid;
}
}  // namespace

#ifdef PROCAM_SDK_X86
// The default 8-bit path (with a black frame) in AVX2, 8 pixels at a time: the
// same float operations in the same order as checker_row_impl, so results
// are bit-identical (checked by separation_test).
__attribute__((target("avx2"))) size_t checker_row_u8_avx2(const CheckerRowConstants& k, const uint8_t* mx,
                                                            const uint8_t* mn, const uint8_t* bk, float* d, float* g,
                                                            uint32_t n) noexcept {
  const __m256 inv = _mm256_set1_ps(k.inv_1mb), dark = _mm256_set1_ps(k.dark), sat = _mm256_set1_ps(k.saturation);
  const __m256 nan = _mm256_set1_ps(kNaN), zero = _mm256_setzero_ps(), two = _mm256_set1_ps(2.f);
  size_t valid = 0;
  uint32_t x = 0;
  for (; x + 8 <= n; x += 8) {
    const __m256 hi = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(mx + x))));
    const __m256 lo = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(mn + x))));
    const __m256 b = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(bk + x))));
    const __m256 dd = _mm256_mul_ps(_mm256_sub_ps(hi, lo), inv);
    const __m256 sm = _mm256_mul_ps(_mm256_sub_ps(lo, b), inv);
    const __m256 ok = _mm256_and_ps(_mm256_cmp_ps(_mm256_add_ps(dd, sm), dark, _CMP_GE_OQ),
                                    _mm256_cmp_ps(hi, sat, _CMP_LT_OQ));
    _mm256_storeu_ps(d + x, _mm256_blendv_ps(nan, _mm256_max_ps(dd, zero), ok));
    _mm256_storeu_ps(g + x, _mm256_blendv_ps(nan, _mm256_max_ps(_mm256_mul_ps(two, sm), zero), ok));
    valid += static_cast<size_t>(__builtin_popcount(static_cast<unsigned>(_mm256_movemask_ps(ok))));
  }
  return valid + checker_row_impl<uint8_t, true>(k, mx + x, mn + x, bk + x, d + x, g + x, n - x);
}
#endif

template <class T>
size_t checker_row(const CheckerRowConstants& k, const T* mx, const T* mn, const T* bk, float* d, float* g,
                   uint32_t n) noexcept {
#ifdef PROCAM_SDK_X86
  if constexpr (std::is_same_v<T, uint8_t>)
    if (bk != nullptr && sdk::cpu_has_avx2()) return checker_row_u8_avx2(k, mx, mn, bk, d, g, n);
#endif
  return bk != nullptr ? checker_row_impl<T, true>(k, mx, mn, bk, d, g, n)
                       : checker_row_impl<T, false>(k, mx, mn, bk, d, g, n);
}

size_t checker_row_scalar(const CheckerRowConstants& k, const uint8_t* mx, const uint8_t* mn, const uint8_t* bk,
                          float* d, float* g, uint32_t n) noexcept {
  return bk != nullptr ? checker_row_impl<uint8_t, true>(k, mx, mn, bk, d, g, n)
                       : checker_row_impl<uint8_t, false>(k, mx, mn, bk, d, g, n);
}
template size_t checker_row<uint8_t>(const CheckerRowConstants&, const uint8_t*, const uint8_t*, const uint8_t*,
                                     float*, float*, uint32_t) noexcept;
template size_t checker_row<uint16_t>(const CheckerRowConstants&, const uint16_t*, const uint16_t*, const uint16_t*,
                                      float*, float*, uint32_t) noexcept;
template size_t checker_row<float>(const CheckerRowConstants&, const float*, const float*, const float*, float*,
                                   float*, uint32_t) noexcept;

void separate_checker(const Extrema& checker, const Extrema* black, const Settings& s, Maps& out) {
  const uint32_t w = checker.width(), h = checker.height();
  size_maps(out, size_t{w} * h, false);
  const CheckerRowConstants k = checker_constants(s);
  const auto run = [&](auto sample) {
    using T = decltype(sample);
    return for_rows(w, h, s.threads, 0, [&](uint32_t y, Rows&) {
      return checker_row<T>(k, checker.max_data<T>(y), checker.min_data<T>(y),
                            black != nullptr ? black->max_data<T>(y) : nullptr, out.direct.data() + size_t{y} * w,
                            out.global.data() + size_t{y} * w, w);
    });
  };
  switch (checker.pixel_type()) {
    case PROCAM_PIXEL_U8: out.valid = run(uint8_t{}); break;
    case PROCAM_PIXEL_U16: out.valid = run(uint16_t{}); break;
    default: out.valid = run(0.f); break;
  }
}

void separate_multi_focal(std::span<const Extrema> per_focus, const Extrema* black, const Settings& s, Maps& out) {
  const size_t nf = per_focus.size();
  const uint32_t w = per_focus.empty() ? 0 : per_focus[0].width(), h = per_focus.empty() ? 0 : per_focus[0].height();
  size_maps(out, size_t{w} * h, true);
  if (nf < 3) {
    std::fill(out.direct.begin(), out.direct.end(), kNaN);
    std::fill(out.global.begin(), out.global.end(), kNaN);
    std::fill(out.best_focus.begin(), out.best_focus.end(), kNaN);
    return;
  }
  const Normaliser nz(s);
  const double k1 = nz.inv_1mb(), dark = nz.dark_limit(), tie = s.tie_fraction * s.full_scale * k1;
  out.valid = for_rows(w, h, s.threads, 2 * nf + 1, [&](uint32_t y, Rows& r) {
    float* bk = r[2 * nf];
    std::vector<float> ep(nf), em(nf);  // e⁺(f), e⁻(f) of one pixel
    for (size_t f = 0; f < nf; ++f) {
      per_focus[f].max_row(y, r[f]);
      per_focus[f].min_row(y, r[nf + f]);
    }
    if (black != nullptr)
      black->max_row(y, bk);
    else
      std::fill(bk, bk + w, 0.f);
    for (uint32_t x = 0; x < w; ++x) {
      bool bad = false;
      for (size_t f = 0; f < nf; ++f) {
        const float raw = r[f][x];
        bad |= nz.saturated(raw);
        ep[f] = static_cast<float>(nz(raw, bk[x]));  // (N)
        em[f] = static_cast<float>(nz(r[nf + f][x], bk[x]));
      }
      Components c;  // NaN: invalid
      float best = kNaN;
      if (!bad) {
        const Extremum hi = gaussian_extremum(ep.data(), nf, true, tie);   // ē⁺, Eq. 2.15
        const Extremum lo = gaussian_extremum(em.data(), nf, false, tie);  // ē⁻, Eq. 2.16
        if (hi.valid && lo.valid && hi.value >= dark) {
          c = from_extrema(hi.value, lo.value);
          best = static_cast<float>(hi.index);
        }
      }
      out.direct[size_t{y} * w + x] = c.direct;
      out.global[size_t{y} * w + x] = c.global;
      out.best_focus[size_t{y} * w + x] = c.valid() ? best : kNaN;
    }
    return count_valid(out.direct.data() + size_t{y} * w, out.global.data() + size_t{y} * w, w);
  });
}

void separate_one_focal(const Extrema& checker, const Extrema& white, const Extrema* black,
                        std::span<const float> depth_mm, const sdk::CalibrationTable& contrast_from_depth,
                        const Settings& s, Maps& out) {
  const uint32_t w = checker.width(), h = checker.height();
  size_maps(out, size_t{w} * h, false);
  if (depth_mm.size() != size_t{w} * h) {
    std::fill(out.direct.begin(), out.direct.end(), kNaN);
    std::fill(out.global.begin(), out.global.end(), kNaN);
    return;
  }
  const Normaliser nz(s);
  const double dark = nz.dark_limit();
  out.valid = for_rows(w, h, s.threads, 4, [&](uint32_t y, Rows& r) {
    float *mx = r[0], *mn = r[1], *wh = r[2], *bk = r[3];
    checker.max_row(y, mx);
    checker.min_row(y, mn);
    white.max_row(y, wh);
    if (black != nullptr)
      black->max_row(y, bk);
    else
      std::fill(bk, bk + w, 0.f);
    for (uint32_t x = 0; x < w; ++x) {
      Components c;  // NaN: invalid
      const double sw = nz(wh[x], bk[x]);  // (N)
      if (!nz.saturated(mx[x]) && !nz.saturated(wh[x]) && sw >= dark) {
        const double contrast = contrast_from_depth.lookup(depth_mm[size_t{y} * w + x]);  // Eq. 2.19 table
        c = from_contrast(nz(mx[x], bk[x]), nz(mn[x], bk[x]), sw, contrast, s.min_contrast);
      }
      out.direct[size_t{y} * w + x] = c.direct;
      out.global[size_t{y} * w + x] = c.global;
    }
    return count_valid(out.direct.data() + size_t{y} * w, out.global.data() + size_t{y} * w, w);
  });
}

void plane_contrast_samples(const Extrema& checker, const Extrema& white, const Extrema* black,
                            std::span<const float> depth_mm, const Settings& s, uint32_t window_px,
                            std::vector<float>& depths, std::vector<float>& contrasts) {
  const uint32_t w = checker.width(), h = checker.height();
  const size_t n = size_t{w} * h;
  depths.assign(n, kNaN);
  contrasts.assign(n, kNaN);
  if (depth_mm.size() != n) return;
  const Normaliser nz(s);
  const double dark = nz.dark_limit();
  sdk::parallel_rows(h, std::max(1u, s.threads), [&](uint32_t y0, uint32_t y1) {
    Rows r(4, w);
    for (uint32_t y = y0; y < y1; ++y) {
      checker.max_row(y, r[0]);
      checker.min_row(y, r[1]);
      white.max_row(y, r[2]);
      if (black != nullptr)
        black->max_row(y, r[3]);
      else
        std::fill(r[3], r[3] + w, 0.f);
      for (uint32_t x = 0; x < w; ++x) {
        const size_t i = size_t{y} * w + x;
        if (nz.saturated(r[0][x]) || nz.saturated(r[2][x]) || !std::isfinite(depth_mm[i])) continue;
        const double sw = nz(r[2][x], r[3][x]);
        if (!(sw >= dark)) continue;
        const double c = plane_contrast(nz(r[0][x], r[3][x]), nz(r[1][x], r[3][x]), sw);
        if (!std::isfinite(c)) continue;
        depths[i] = depth_mm[i];
        contrasts[i] = static_cast<float>(c);
      }
    }
  });
  box_mean_finite(contrasts, w, h, window_px);
}

void box_mean_finite(std::vector<float>& v, uint32_t w, uint32_t h, uint32_t window) {
  if (window <= 1 || v.size() != size_t{w} * h) return;
  // Summed-area tables of the finite values and of their count, (w+1)×(h+1).
  const size_t W = size_t{w} + 1;
  std::vector<double> sum(W * (size_t{h} + 1), 0.0), cnt(W * (size_t{h} + 1), 0.0);
  for (uint32_t y = 0; y < h; ++y) {
    double row_s = 0, row_c = 0;
    for (uint32_t x = 0; x < w; ++x) {
      const float f = v[size_t{y} * w + x];
      if (std::isfinite(f)) {
        row_s += double(f);
        row_c += 1;
      }
      sum[(y + 1) * W + x + 1] = sum[y * W + x + 1] + row_s;
      cnt[(y + 1) * W + x + 1] = cnt[y * W + x + 1] + row_c;
    }
  }
  const uint32_t lo = window / 2, hi = window - lo;  // box [x - lo, x + hi)
  for (uint32_t y = 0; y < h; ++y) {
    const size_t y0 = y >= lo ? y - lo : 0, y1 = std::min<size_t>(h, size_t{y} + hi);
    for (uint32_t x = 0; x < w; ++x) {
      float& out = v[size_t{y} * w + x];
      if (!std::isfinite(out)) continue;
      const size_t x0 = x >= lo ? x - lo : 0, x1 = std::min<size_t>(w, size_t{x} + hi);
      const double c = cnt[y1 * W + x1] - cnt[y0 * W + x1] - cnt[y1 * W + x0] + cnt[y0 * W + x0];
      const double t = sum[y1 * W + x1] - sum[y0 * W + x1] - sum[y1 * W + x0] + sum[y0 * W + x0];
      out = static_cast<float>(t / c);  // c >= 1: the pixel itself is finite
    }
  }
}

}  // namespace procam::separation
