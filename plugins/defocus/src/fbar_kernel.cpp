// SPDX-License-Identifier: MIT
// The multi-focal hot path after the last frame (see fbar_kernel.hpp): fbar
// (thesis Eq. 2.9 with Gaussian interpolation) and the table lookup for a
// whole image, one fused pass per row. This file holds the scalar kernel, the
// float table and the driver, which runs the AVX2 twin (fbar_avx2.cpp) where
// the CPU has it.
#include "fbar_kernel.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "focus_measures.hpp"
#include "procam/sdk/simd.hpp"

namespace procam::defocus {
namespace detail {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Natural log for x > 0 (finite, normal): x = m 2^e with m in [sqrt(1/2), sqrt(2)),
// ln m = 2 atanh(t), t = (m - 1)/(m + 1), |t| < 0.172: four odd terms leave
// |error| < 3e-8. Branch-free; the caller masks x <= 0.
inline float fast_ln(float x) {
  uint32_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  int32_t e = static_cast<int32_t>((bits >> 23) & 0xffu) - 127;
  uint32_t mbits = (bits & 0x007fffffu) | 0x3f800000u;  // m in [1, 2)
  float m;
  std::memcpy(&m, &mbits, sizeof m);
  const bool big = m > 1.41421356f;
  m = big ? 0.5f * m : m;
  e = big ? e + 1 : e;
  const float t = (m - 1.f) / (m + 1.f), t2 = t * t;
  const float series = t * (2.f + t2 * (2.f / 3.f + t2 * (2.f / 5.f + t2 * (2.f / 7.f))));
  return static_cast<float>(e) * 0.69314718f + series;
}

// Uniform-grid index over a table's x range (double, any spacing): bin b
// holds the last sample k with x_k <= x0 + b dx, so a lookup starts there and
// steps forward. The fallback when no FloatTable grid separates the
// breakpoints (samples closer than range / 2^16).
struct TableIndex {
  const sdk::CalibrationTable* table = nullptr;
  double x0 = 0, inv_dx = 0;
  std::vector<uint32_t> start;
  explicit TableIndex(const sdk::CalibrationTable* t) : table(t) {
    if (t == nullptr || t->samples.size() < 2) return;
    const size_t bins = 4 * t->samples.size();
    x0 = t->x_min();
    inv_dx = double(bins) / (t->x_max() - x0);
    start.resize(bins + 1);
    size_t k = 0;
    for (size_t b = 0; b <= bins; ++b) {
      const double xb = x0 + double(b) / inv_dx;
      while (k + 2 < t->samples.size() && t->samples[k + 1].first <= xb) ++k;
      start[b] = static_cast<uint32_t>(k);
    }
  }
  // CalibrationTable::lookup: linear between samples, NaN outside [x_min, x_max].
  float lookup(float xf) const {
    const auto& s = table->samples;
    const double x = xf;
    if (!(x >= s.front().first) || !(x <= s.back().first)) return kNaN;
    auto b = static_cast<size_t>((x - x0) * inv_dx);
    b = std::min(b, start.size() - 1);
    size_t k = start[b];
    while (k + 2 < s.size() && s[k + 1].first <= x) ++k;
    const auto& lo = s[k];
    const auto& hi = s[k + 1];
    const double t = (x - lo.first) / (hi.first - lo.first);
    return static_cast<float>(lo.second + t * (hi.second - lo.second));
  }
};

// The smallest float >= v (v finite): then float x >= result <=> double(x) >= v.
float float_at_or_above(double v) {
  auto f = static_cast<float>(v);
  if (double(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}
// The largest float <= v.
float float_at_or_below(double v) {
  auto f = static_cast<float>(v);
  if (double(f) > v) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

}  // namespace

FloatTable::FloatTable(const sdk::CalibrationTable* table) {
  if (table == nullptr || table->samples.size() < 2) return;
  const auto& s = table->samples;
  const size_t n = s.size();
  lo = float_at_or_above(s.front().first);
  hi = float_at_or_below(s.back().first);
  if (!(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi)) return;
  // step_x[k]: the float threshold of the breakpoint (sample k + 1) between
  // segments k and k + 1; +inf after the last segment.
  std::vector<float> step_x(n - 1);
  double min_gap = s.back().first - s.front().first;
  for (size_t k = 0; k + 1 < n; ++k) {
    step_x[k] = k + 2 < n ? float_at_or_above(s[k + 1].first) : std::numeric_limits<float>::infinity();
    min_gap = std::min(min_gap, s[k + 1].first - s[k].first);
  }
  // Bins of about half the smallest gap; grow until no two breakpoints share
  // a bin under the float bin() the kernels use.
  double bins = std::ceil(2.0 * (double(hi) - double(lo)) / min_gap);
  std::vector<int32_t> breakpoint_bin(n - 2);
  for (; bins <= kMaxBins; bins *= 2) {
    x0 = lo;
    inv_dx = static_cast<float>(bins / (double(hi) - double(lo)));
    dx = static_cast<float>((double(hi) - double(lo)) / bins);
    const float top = (hi - x0) * inv_dx;  // bin(hi), unclamped
    if (!(top >= 0.f) || !(top <= float(2 * kMaxBins))) continue;
    last_bin = static_cast<int32_t>(top);
    bool separated = true;
    for (size_t k = 0; k + 2 < n && separated; ++k) {
      const float v = (step_x[k] - x0) * inv_dx;
      breakpoint_bin[k] = v <= top ? static_cast<int32_t>(v) : last_bin + 1;
      separated = breakpoint_bin[k] <= last_bin && (k == 0 || breakpoint_bin[k] > breakpoint_bin[k - 1]);
    }
    if (!separated) continue;
    // Per bin b: its first segment k = the number of breakpoints in lower bins,
    // the threshold of the next breakpoint, and both lines (k and k + 1) as
    // y at the bin's left edge xb + slope (the lines are the table's own,
    // evaluated in double at the float xb the kernels compute).
    const auto nb = size_t(last_bin) + 1;
    thr.resize(nb);
    lines.resize(4 * nb);
    size_t k = 0;
    for (size_t b = 0; b < nb; ++b) {
      while (k < breakpoint_bin.size() && breakpoint_bin[k] < int32_t(b)) ++k;
      thr[b] = step_x[k];
      const float xb = x0 + static_cast<float>(b) * dx;
      for (size_t side = 0; side < 2; ++side) {
        const size_t seg = std::min(k + side, n - 2);
        const auto& p = s[seg];
        const auto& q = s[seg + 1];
        const double slope = (q.second - p.second) / (q.first - p.first);
        const size_t i = 2 * b + side;
        lines[2 * i] = static_cast<float>(p.second + (double(xb) - p.first) * slope);
        lines[2 * i + 1] = static_cast<float>(slope);
      }
    }
    usable = true;
    return;
  }
}

int32_t FloatTable::bin(float x) const noexcept {
  const float v = (x - x0) * inv_dx;
  // Out of range and NaN: clamped (the caller masks those lanes anyway).
  if (!(v >= 0.f)) return 0;
  if (!(v < float(last_bin))) return last_bin;
  return static_cast<int32_t>(v);
}

float FloatTable::lookup(float x) const noexcept {
  if (!(x >= lo) || !(x <= hi)) return kNaN;
  const int32_t b = bin(x);
  const size_t i = 2 * size_t(b) + (x >= thr[size_t(b)] ? 1u : 0u);
  const float xb = x0 + static_cast<float>(b) * dx;
  return lines[2 * i] + (x - xb) * lines[2 * i + 1];
}

size_t fbar_row_scalar(const RowArgs& a, uint32_t x_begin, uint32_t x_end) noexcept {
  const auto last = static_cast<int32_t>(a.F) - 1;
  size_t count = 0;
  for (uint32_t x = x_begin; x < x_end; ++x) {
    // Running argmax (first maximum wins, as fbar_from_e3) with the values
    // left and right of it.
    auto e_at = [&](uint32_t f) {
      if (a.fold != nullptr && f == a.fold_f) {
        const int16_t* d = a.fold + x;
        return e3_from_buckets(static_cast<float>(d[0]), static_cast<float>(d[a.fold_stride]),
                               static_cast<float>(d[2 * a.fold_stride]), static_cast<float>(d[3 * a.fold_stride]));
      }
      return a.e[f][x];
    };
    float b = e_at(0), l = 0.f, r = 0.f, prev = b;
    int32_t k = 0;
    for (uint32_t f = 1; f < a.F; ++f) {
      const float e = e_at(f);
      const bool better = e > b;
      const bool right_of_best = !better && k == static_cast<int32_t>(f) - 1;
      r = right_of_best ? e : r;
      l = better ? prev : l;
      b = better ? e : b;
      k = better ? static_cast<int32_t>(f) : k;
      prev = e;
    }
    // Eq. 2.9, Gaussian interpolation: offset = (ln l - ln r) / (2 (ln l - 2 ln b + ln r)),
    // with the logs taken of l/b and r/b in (0, 1].
    const float mean = a.mean[x];
    const float floor = a.min_mod * mean;
    const bool inner = (k > 0) & (k < last);
    const bool strong = (l >= floor) & (r >= floor) & (b >= floor) & (l > 0.f) & (r > 0.f);
    const bool lit = mean >= a.black;
    const float bb = b > 0.f ? b : 1.f;
    const float lm = fast_ln(strong ? l / bb : 1.f), lp = fast_ln(strong ? r / bb : 1.f);
    const float curv = lm + lp;  // <= 0; < 0 unless flat
    const bool curved = curv < -1e-9f;
    const float off = 0.5f * (lm - lp) / (curved ? curv : -1.f);
    const bool saturated = (a.sat[x / 8] >> (x % 8)) & 1u;
    const bool ok = inner & strong & lit & curved & (std::fabs(off) <= 0.5f + 1e-4f) & !saturated;
    const float clamped = off < -0.5f ? -0.5f : (off > 0.5f ? 0.5f : off);
    const float fbar = ok ? static_cast<float>(k) + clamped : kNaN;
    a.fbar[x] = fbar;
    count += ok ? 1u : 0u;
    if (a.peak != nullptr) a.peak[x] = b;
    const float out = a.table != nullptr ? (ok ? a.table->lookup(fbar) : kNaN) : fbar;
    if (a.table != nullptr) a.depth[x] = out;
    if (a.valid != nullptr) {
      const bool finite = std::fabs(out) < std::numeric_limits<float>::infinity();
      a.valid[x] = finite ? 255 : 0;
      *a.valid_count += finite ? 1u : 0u;
    }
  }
  return count;
}

}  // namespace detail

size_t fbar_depth_map(const E3Accumulator& acc, const Validity& rule, const sdk::CalibrationTable* table,
                      uint32_t threads, std::vector<float>& fbar, std::vector<float>* depth_mm, std::vector<float>* peak,
                      std::vector<uint8_t>* valid, size_t* valid_count) {
  const uint32_t w = acc.width(), h = acc.height(), F = acc.focus_count();
  const size_t n = size_t{w} * h;
  fbar.resize(n);
  if (depth_mm != nullptr) depth_mm->resize(n);
  if (peak != nullptr) peak->resize(n);
  if (valid != nullptr) valid->resize(n);
  const bool want_depth = depth_mm != nullptr;
  const detail::FloatTable ftable(want_depth ? table : nullptr);
  // Tables whose breakpoints no float grid separates: the double path after the pass.
  const detail::TableIndex index(want_depth && !ftable.usable ? table : nullptr);
  const bool avx2 = sdk::cpu_has_avx2();
  // A deferred last fold (E3Accumulator::defer_final_fold): its E is made from the buckets in the pass.
  const E3Accumulator::PendingBuckets pending = acc.pending_buckets();
  std::vector<size_t> counts(h, 0), valid_counts(h, 0);
  sdk::parallel_rows(h, threads, [&](uint32_t y0, uint32_t y1) {
    std::vector<const float*> e(F);
    for (uint32_t y = y0; y < y1; ++y) {
      const size_t row = size_t{y} * w;
      for (uint32_t f = 0; f < F; ++f)
        e[f] = pending.d != nullptr && f == pending.focus ? nullptr : acc.e3(f).data() + row;
      const bool fallback = want_depth && !ftable.usable;
      detail::RowArgs a{e.data(), F, acc.mean().data() + row, acc.saturation_row(y),
                        static_cast<float>(rule.black_dn), static_cast<float>(rule.min_modulation),
                        ftable.usable ? &ftable : nullptr, fbar.data() + row,
                        want_depth ? depth_mm->data() + row : nullptr, peak != nullptr ? peak->data() + row : nullptr,
                        valid != nullptr && !fallback ? valid->data() + row : nullptr, &valid_counts[y],
                        pending.d != nullptr ? pending.d + row : nullptr, n, pending.focus};
      counts[y] = avx2 ? detail::fbar_row_avx2(a, 0, w) : detail::fbar_row_scalar(a, 0, w);
      if (fallback) {
        float* d = depth_mm->data() + row;
        const float* fb = fbar.data() + row;
        if (index.start.empty())
          std::fill(d, d + w, detail::kNaN);
        else
          for (uint32_t x = 0; x < w; ++x) d[x] = std::isnan(fb[x]) ? detail::kNaN : index.lookup(fb[x]);
        if (valid != nullptr) {
          uint8_t* v = valid->data() + row;
          for (uint32_t x = 0; x < w; ++x) {
            const bool finite = std::fabs(d[x]) < std::numeric_limits<float>::infinity();
            v[x] = finite ? 255 : 0;
            valid_counts[y] += finite ? 1u : 0u;
          }
        }
      }
    }
  });
  size_t total = 0, total_valid = 0;
  for (size_t c : counts) total += c;
  for (size_t c : valid_counts) total_valid += c;
  if (valid_count != nullptr) *valid_count = total_valid;
  return total;
}

}  // namespace procam::defocus
