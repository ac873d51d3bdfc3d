// SPDX-License-Identifier: MIT
// The multi-focal hot path after the last frame: fbar (thesis Eq. 2.9 with
// Gaussian interpolation) and the table lookup for a whole image, written for
// the vectoriser: per row, the argmax over focus settings runs setting by
// setting over the row (branch-free selects), the interpolation uses a
// polynomial logarithm, and only the table lookup is scalar (through a
// uniform-grid index of the table's segments: O(1) per pixel, same result as
// CalibrationTable::lookup).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "focus_measures.hpp"

namespace procam::defocus {
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

#if defined(__SSE2__)
inline __m128 select_ps(__m128 m, __m128 a, __m128 b) { return _mm_or_ps(_mm_and_ps(m, a), _mm_andnot_ps(m, b)); }

// fast_ln on 4 lanes (same arithmetic, so the same results up to rounding order).
inline __m128 fast_ln_ps(__m128 x) {
  const __m128i bits = _mm_castps_si128(x);
  __m128i e = _mm_sub_epi32(_mm_and_si128(_mm_srli_epi32(bits, 23), _mm_set1_epi32(0xff)), _mm_set1_epi32(127));
  __m128 m = _mm_castsi128_ps(
      _mm_or_si128(_mm_and_si128(bits, _mm_set1_epi32(0x007fffff)), _mm_set1_epi32(0x3f800000)));
  const __m128 big = _mm_cmpgt_ps(m, _mm_set1_ps(1.41421356f));
  m = select_ps(big, _mm_mul_ps(m, _mm_set1_ps(0.5f)), m);
  e = _mm_sub_epi32(e, _mm_castps_si128(big));  // big lanes are -1: e + 1
  const __m128 one = _mm_set1_ps(1.f);
  const __m128 t = _mm_div_ps(_mm_sub_ps(m, one), _mm_add_ps(m, one)), t2 = _mm_mul_ps(t, t);
  __m128 p = _mm_add_ps(_mm_set1_ps(2.f / 5.f), _mm_mul_ps(t2, _mm_set1_ps(2.f / 7.f)));
  p = _mm_add_ps(_mm_set1_ps(2.f / 3.f), _mm_mul_ps(t2, p));
  p = _mm_add_ps(_mm_set1_ps(2.f), _mm_mul_ps(t2, p));
  return _mm_add_ps(_mm_mul_ps(_mm_cvtepi32_ps(e), _mm_set1_ps(0.69314718f)), _mm_mul_ps(t, p));
}
#endif

// Uniform-grid index over a table's x range: bin b holds the last sample k
// with x_k <= x0 + b dx, so a lookup starts there and steps at most a few
// samples forward.
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

}  // namespace

size_t fbar_depth_map(const E3Accumulator& acc, const Validity& rule, const sdk::CalibrationTable* table,
                      uint32_t threads, std::vector<float>& fbar, std::vector<float>* depth_mm) {
  const uint32_t w = acc.width(), h = acc.height(), F = acc.focus_count();
  const size_t n = size_t{w} * h;
  fbar.resize(n);
  if (depth_mm != nullptr) depth_mm->resize(n);
  const TableIndex index(table);
  std::vector<size_t> counts(h, 0);
  const auto black = static_cast<float>(rule.black_dn);
  const auto min_mod = static_cast<float>(rule.min_modulation);
  sdk::parallel_rows(h, threads, [&, w](uint32_t y0, uint32_t y1) {
    // Every load below is unconditional and every choice a select, so GCC
    // if-converts and vectorises the loops (-ftrapping-math forbids it to
    // speculate a conditional division or load itself).
    std::vector<float> best(w), left(w), right(w);
    std::vector<int32_t> arg(w);
    for (uint32_t y = y0; y < y1; ++y) {
      const size_t row = size_t{y} * w;
      float* __restrict b = best.data();
      float* __restrict l = left.data();
      float* __restrict r = right.data();
      int32_t* __restrict k = arg.data();
      const float* __restrict e0 = acc.e3(0).data() + row;
      for (uint32_t x = 0; x < w; ++x) {
        b[x] = e0[x];
        k[x] = 0;
        l[x] = 0.f;
        r[x] = 0.f;
      }
      // Running argmax (first maximum wins, as fbar_from_e3) with the values
      // left and right of it: E(f) arrives setting by setting.
      for (uint32_t f = 1; f < F; ++f) {
        const float* __restrict ef = acc.e3(f).data() + row;
        const float* __restrict eprev = acc.e3(f - 1).data() + row;
        const auto fi = static_cast<int32_t>(f);
        uint32_t x0 = 0;
#if defined(__SSE2__)
        // 4 pixels per step; select(m, a, b) = (m & a) | (~m & b).
        const __m128i vf = _mm_set1_epi32(fi), vprev = _mm_set1_epi32(fi - 1);
        for (; x0 + 4 <= w; x0 += 4) {
          const __m128 e = _mm_loadu_ps(ef + x0), before = _mm_loadu_ps(eprev + x0);
          const __m128 bx = _mm_loadu_ps(b + x0), lx = _mm_loadu_ps(l + x0), rx = _mm_loadu_ps(r + x0);
          const __m128i kx = _mm_loadu_si128(reinterpret_cast<const __m128i*>(k + x0));
          const __m128 better = _mm_cmpgt_ps(e, bx);
          const __m128 right_of_best = _mm_andnot_ps(better, _mm_castsi128_ps(_mm_cmpeq_epi32(kx, vprev)));
          _mm_storeu_ps(r + x0, _mm_or_ps(_mm_and_ps(right_of_best, e), _mm_andnot_ps(right_of_best, rx)));
          _mm_storeu_ps(l + x0, _mm_or_ps(_mm_and_ps(better, before), _mm_andnot_ps(better, lx)));
          _mm_storeu_ps(b + x0, _mm_or_ps(_mm_and_ps(better, e), _mm_andnot_ps(better, bx)));
          const __m128i bi = _mm_castps_si128(better);
          _mm_storeu_si128(reinterpret_cast<__m128i*>(k + x0),
                           _mm_or_si128(_mm_and_si128(bi, vf), _mm_andnot_si128(bi, kx)));
        }
#endif
        for (uint32_t x = x0; x < w; ++x) {
          const float e = ef[x], before = eprev[x], bx = b[x], lx = l[x], rx = r[x];
          const int32_t kx = k[x];
          const bool better = e > bx;
          const bool right_of_best = (!better) & (kx == fi - 1);
          r[x] = right_of_best ? e : rx;
          l[x] = better ? before : lx;
          b[x] = better ? e : bx;
          k[x] = better ? fi : kx;
        }
      }
      float* __restrict out = fbar.data() + row;
      const float* __restrict mean = acc.mean().data() + row;
      const auto last = static_cast<int32_t>(F) - 1;
      uint32_t x1 = 0;
#if defined(__SSE2__)
      {
        const __m128 vmin = _mm_set1_ps(min_mod), vblack = _mm_set1_ps(black), zero = _mm_setzero_ps();
        const __m128 one = _mm_set1_ps(1.f), half = _mm_set1_ps(0.5f), nan = _mm_set1_ps(kNaN);
        const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
        const __m128i vlast = _mm_set1_epi32(last), izero = _mm_setzero_si128();
        for (; x1 + 4 <= w; x1 += 4) {
          const __m128 lx = _mm_loadu_ps(l + x1), rx = _mm_loadu_ps(r + x1), bx = _mm_loadu_ps(b + x1);
          const __m128 mx = _mm_loadu_ps(mean + x1);
          const __m128i kx = _mm_loadu_si128(reinterpret_cast<const __m128i*>(k + x1));
          const __m128 floor = _mm_mul_ps(vmin, mx);
          const __m128 inner = _mm_castsi128_ps(_mm_and_si128(_mm_cmpgt_epi32(kx, izero), _mm_cmplt_epi32(kx, vlast)));
          __m128 strong = _mm_and_ps(_mm_cmpge_ps(lx, floor), _mm_cmpge_ps(rx, floor));
          strong = _mm_and_ps(strong, _mm_cmpge_ps(bx, floor));
          strong = _mm_and_ps(strong, _mm_and_ps(_mm_cmpgt_ps(lx, zero), _mm_cmpgt_ps(rx, zero)));
          const __m128 lit = _mm_cmpge_ps(mx, vblack);
          const __m128 bb = select_ps(_mm_cmpgt_ps(bx, zero), bx, one);
          const __m128 lm = fast_ln_ps(select_ps(strong, _mm_div_ps(lx, bb), one));
          const __m128 lp = fast_ln_ps(select_ps(strong, _mm_div_ps(rx, bb), one));
          const __m128 curv = _mm_add_ps(lm, lp);
          const __m128 curved = _mm_cmplt_ps(curv, _mm_set1_ps(-1e-9f));
          const __m128 off = _mm_div_ps(_mm_mul_ps(half, _mm_sub_ps(lm, lp)), select_ps(curved, curv, _mm_set1_ps(-1.f)));
          const __m128 in_range = _mm_cmple_ps(_mm_and_ps(off, abs_mask), _mm_set1_ps(0.5f + 1e-4f));
          const __m128 ok = _mm_and_ps(_mm_and_ps(_mm_and_ps(inner, strong), _mm_and_ps(lit, curved)), in_range);
          const __m128 clamped = _mm_min_ps(_mm_max_ps(off, _mm_set1_ps(-0.5f)), half);
          _mm_storeu_ps(out + x1, select_ps(ok, _mm_add_ps(_mm_cvtepi32_ps(kx), clamped), nan));
        }
      }
#endif
      for (uint32_t x = x1; x < w; ++x) {
        // Eq. 2.9, Gaussian interpolation: offset = (ln l - ln r) / (2 (ln l - 2 ln b + ln r)),
        // with the logs taken of l/b and r/b in (0, 1].
        // Bitwise & (not &&): no branches, so the loop vectorises.
        const float floor = min_mod * mean[x];
        const bool inner = (k[x] > 0) & (k[x] < last);
        const bool strong = (l[x] >= floor) & (r[x] >= floor) & (b[x] >= floor) & (l[x] > 0.f) & (r[x] > 0.f);
        const bool lit = mean[x] >= black;
        const float bb = b[x] > 0.f ? b[x] : 1.f;
        const float ratio_l = l[x] / bb, ratio_r = r[x] / bb;
        const float lm = fast_ln(strong ? ratio_l : 1.f), lp = fast_ln(strong ? ratio_r : 1.f);
        const float curv = lm + lp;  // <= 0; < 0 unless flat
        const bool curved = curv < -1e-9f;
        const float denom = curved ? curv : -1.f;
        const float off = 0.5f * (lm - lp) / denom;
        const bool ok = inner & strong & lit & curved & (std::fabs(off) <= 0.5f + 1e-4f);
        const float clamped = off < -0.5f ? -0.5f : (off > 0.5f ? 0.5f : off);
        out[x] = ok ? static_cast<float>(k[x]) + clamped : kNaN;
      }
      const uint8_t* sat = acc.saturation_row(y);
      size_t c = 0;
      for (uint32_t x = 0; x < w; ++x) {
        const bool saturated = (sat[x / 8] >> (x % 8)) & 1u;
        out[x] = saturated ? kNaN : out[x];
        c += out[x] == out[x] ? 1u : 0u;
      }
      counts[y] = c;
      if (depth_mm != nullptr) {
        float* d = depth_mm->data() + row;
        if (table == nullptr || index.start.empty())
          std::fill(d, d + w, kNaN);
        else
          for (uint32_t x = 0; x < w; ++x) d[x] = std::isnan(out[x]) ? kNaN : index.lookup(out[x]);
      }
    }
  });
  size_t total = 0;
  for (size_t c : counts) total += c;
  return total;
}

}  // namespace procam::defocus
