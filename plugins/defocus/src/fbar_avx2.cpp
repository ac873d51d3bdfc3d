// SPDX-License-Identifier: MIT
// AVX2 twin of fbar_row_scalar (fbar_kernel.hpp): 8 pixels per step, the same
// float operations in the same order (no FMA), so bit-identical results.
// Compiled with __attribute__((target("avx2"))) and called only where
// sdk::cpu_has_avx2() (sdk/simd.hpp): no -march flags.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>

#include "e3_accumulator.hpp"
#include "fbar_kernel.hpp"
#include "procam/sdk/simd.hpp"

namespace procam::defocus::detail {

#ifdef PROCAM_SDK_X86
namespace {

#define PROCAM_AVX2 __attribute__((target("avx2"), always_inline)) inline

PROCAM_AVX2 __m256 select8(__m256 m, __m256 a, __m256 b) { return _mm256_blendv_ps(b, a, m); }

// fast_ln of fbar_kernel.cpp on 8 lanes: x = m 2^e, m in [sqrt(1/2), sqrt(2)),
// ln m = 2 atanh(t), t = (m - 1)/(m + 1), four odd terms.
PROCAM_AVX2 __m256 fast_ln8(__m256 x) {
  const __m256i bits = _mm256_castps_si256(x);
  __m256i e = _mm256_sub_epi32(_mm256_and_si256(_mm256_srli_epi32(bits, 23), _mm256_set1_epi32(0xff)),
                               _mm256_set1_epi32(127));
  __m256 m = _mm256_castsi256_ps(
      _mm256_or_si256(_mm256_and_si256(bits, _mm256_set1_epi32(0x007fffff)), _mm256_set1_epi32(0x3f800000)));
  const __m256 big = _mm256_cmp_ps(m, _mm256_set1_ps(1.41421356f), _CMP_GT_OQ);
  m = select8(big, _mm256_mul_ps(m, _mm256_set1_ps(0.5f)), m);
  e = _mm256_sub_epi32(e, _mm256_castps_si256(big));  // big lanes are -1: e + 1
  const __m256 one = _mm256_set1_ps(1.f);
  const __m256 t = _mm256_div_ps(_mm256_sub_ps(m, one), _mm256_add_ps(m, one)), t2 = _mm256_mul_ps(t, t);
  __m256 p = _mm256_add_ps(_mm256_set1_ps(2.f / 5.f), _mm256_mul_ps(t2, _mm256_set1_ps(2.f / 7.f)));
  p = _mm256_add_ps(_mm256_set1_ps(2.f / 3.f), _mm256_mul_ps(t2, p));
  p = _mm256_add_ps(_mm256_set1_ps(2.f), _mm256_mul_ps(t2, p));
  return _mm256_add_ps(_mm256_mul_ps(_mm256_cvtepi32_ps(e), _mm256_set1_ps(0.69314718f)), _mm256_mul_ps(t, p));
}

// FloatTable::lookup on 8 lanes where `valid`, NaN elsewhere (the same float
// operations as the scalar lookup).
PROCAM_AVX2 __m256 lookup8(const FloatTable& t, __m256 x, __m256 valid) {
  const __m256 in = _mm256_and_ps(valid, _mm256_and_ps(_mm256_cmp_ps(x, _mm256_set1_ps(t.lo), _CMP_GE_OQ),
                                                       _mm256_cmp_ps(x, _mm256_set1_ps(t.hi), _CMP_LE_OQ)));
  __m256i b = _mm256_cvttps_epi32(_mm256_mul_ps(_mm256_sub_ps(x, _mm256_set1_ps(t.x0)), _mm256_set1_ps(t.inv_dx)));
  b = _mm256_min_epi32(_mm256_max_epi32(b, _mm256_setzero_si256()), _mm256_set1_epi32(t.last_bin));
  const __m256 thr = _mm256_i32gather_ps(t.thr.data(), b, 4);
  // Line 2b, or 2b + 1 past the bin's breakpoint (true lanes are -1).
  const __m256i i = _mm256_sub_epi32(_mm256_add_epi32(b, b), _mm256_castps_si256(_mm256_cmp_ps(x, thr, _CMP_GE_OQ)));
  // Both values of line i as one 64-bit element (FloatTable::lines): lanes
  // 0-3 and 4-7 in two 4-lane gathers, then de-interleaved into y0 and slope
  // in lane order (shufps picks per 128-bit half, permute4x64 restores the
  // order of the 64-bit pieces). The same floats as the scalar lookup.
  const auto* pairs = reinterpret_cast<const long long*>(t.lines.data());
  const __m256 lo = _mm256_castsi256_ps(_mm256_i32gather_epi64(pairs, _mm256_castsi256_si128(i), 8));
  const __m256 hi = _mm256_castsi256_ps(_mm256_i32gather_epi64(pairs, _mm256_extracti128_si256(i, 1), 8));
  // [y0 y1 y4 y5 | y2 y3 y6 y7] -> [y0 .. y7], likewise the slopes.
  const __m256 y0 = _mm256_castpd_ps(
      _mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0))), 0xd8));
  const __m256 slope = _mm256_castpd_ps(
      _mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1))), 0xd8));
  const __m256 xb = _mm256_add_ps(_mm256_set1_ps(t.x0), _mm256_mul_ps(_mm256_cvtepi32_ps(b), _mm256_set1_ps(t.dx)));
  const __m256 y = _mm256_add_ps(y0, _mm256_mul_ps(_mm256_sub_ps(x, xb), slope));
  return select8(in, y, _mm256_set1_ps(std::numeric_limits<float>::quiet_NaN()));
}

// Stores 8 lanes at p: non-temporal (two 16-byte halves; no read-for-
// ownership of output lines the pass never reads) when `stream`, else plain.
PROCAM_AVX2 void store8(float* p, __m256 v, bool stream) {
  if (stream) {
    _mm_stream_ps(p, _mm256_castps256_ps128(v));
    _mm_stream_ps(p + 4, _mm256_extractf128_ps(v, 1));
  } else {
    _mm256_storeu_ps(p, v);
  }
}

bool aligned16(const float* p) { return p == nullptr || (reinterpret_cast<uintptr_t>(p) & 15u) == 0; }

// e3_from_buckets (e3_accumulator.hpp) on 8 lanes: D_b at d[b * stride],
// the same float operations in the same order (the negation is the sign
// flip the compiler emits for -a2).
PROCAM_AVX2 __m256 int16x8_to_ps(const int16_t* p) {
  return _mm256_cvtepi32_ps(_mm256_cvtepi16_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p))));
}
PROCAM_AVX2 __m256 e3_from_buckets8(const int16_t* d, size_t stride) {
  const __m256 a0 = int16x8_to_ps(d), a1 = int16x8_to_ps(d + stride);
  const __m256 a2 = int16x8_to_ps(d + 2 * stride), a3 = int16x8_to_ps(d + 3 * stride);
  const __m256 k = _mm256_set1_ps(0.70710678118654752f);
  const __m256 re = _mm256_add_ps(a0, _mm256_mul_ps(k, _mm256_sub_ps(a1, a3)));
  const __m256 neg_a2 = _mm256_xor_ps(a2, _mm256_set1_ps(-0.f));
  const __m256 im = _mm256_sub_ps(neg_a2, _mm256_mul_ps(k, _mm256_add_ps(a1, a3)));
  const __m256 mag = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(re, re), _mm256_mul_ps(im, im)));
  return _mm256_mul_ps(_mm256_set1_ps(2.0f / static_cast<float>(kPeriodPx)), mag);
}

// E(f) of pixels x..x+7: the map, or the deferred fold from its buckets.
PROCAM_AVX2 __m256 e_at8(const RowArgs& a, uint32_t f, uint32_t x) {
  if (a.fold != nullptr && f == a.fold_f) return e3_from_buckets8(a.fold + x, a.fold_stride);
  return _mm256_loadu_ps(a.e[f] + x);
}

// 8 valid bytes (255 / 0) from the 8 bits of a movemask.
struct ByteMasks {
  uint64_t v[256];
  constexpr ByteMasks() : v() {
    for (uint32_t m = 0; m < 256; ++m)
      for (uint32_t i = 0; i < 8; ++i)
        if ((m >> i) & 1u) v[m] |= uint64_t{0xff} << (8 * i);
  }
};
constexpr ByteMasks kByteMasks;

}  // namespace

__attribute__((target("avx2"))) size_t fbar_row_avx2(const RowArgs& a, uint32_t x_begin, uint32_t x_end) noexcept {
  size_t count = 0;
  uint32_t x = x_begin;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.f), half = _mm256_set1_ps(0.5f);
  const __m256 nan = _mm256_set1_ps(std::numeric_limits<float>::quiet_NaN());
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 vmin = _mm256_set1_ps(a.min_mod), vblack = _mm256_set1_ps(a.black);
  const __m256 vlast = _mm256_set1_ps(static_cast<float>(a.F - 1));
  const __m256i bit_of_lane = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  // Output rows are streamed past the cache where 16-byte aligned (x_begin is a multiple of 8).
  const bool stream = aligned16(a.fbar + x_begin) && aligned16(a.depth ? a.depth + x_begin : nullptr) &&
                      aligned16(a.peak ? a.peak + x_begin : nullptr);
  const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  const bool stream_valid = a.valid != nullptr && (reinterpret_cast<uintptr_t>(a.valid + x_begin) & 7u) == 0;
  size_t valid_count = 0;
  // Two loops per chunk of up to kChunk pixels: f-bar first (into fb, in L1),
  // then the table lookup and the valid bytes. The lookup's dependent gathers
  // (thresholds, then lines) have a long latency; in a loop of their own
  // several groups are in flight at once, behind the f-bar arithmetic only
  // one or two were. Same operations per pixel, so the same bits.
  constexpr uint32_t kChunk = 256;
  alignas(32) float fb[kChunk];
  uint8_t ok_of[kChunk / 8];
  while (x + 8 <= x_end) {
    const uint32_t chunk_begin = x;
    const uint32_t groups = std::min<uint32_t>(kChunk / 8, (x_end - x) / 8);
    for (uint32_t g = 0; g < groups; ++g, x += 8) {
      // Running argmax (first maximum wins); k as float (exact small integers).
      __m256 b = e_at8(a, 0, x), prev = b, l = zero, r = zero, k = zero;
      for (uint32_t f = 1; f < a.F; ++f) {
        const __m256 e = e_at8(a, f, x);
        const __m256 better = _mm256_cmp_ps(e, b, _CMP_GT_OQ);
        const __m256 was_prev = _mm256_cmp_ps(k, _mm256_set1_ps(static_cast<float>(f - 1)), _CMP_EQ_OQ);
        const __m256 right_of_best = _mm256_andnot_ps(better, was_prev);
        r = select8(right_of_best, e, r);
        l = select8(better, prev, l);
        b = select8(better, e, b);
        k = select8(better, _mm256_set1_ps(static_cast<float>(f)), k);
        prev = e;
      }
      // Eq. 2.9 as in fbar_row_scalar.
      const __m256 mean = _mm256_loadu_ps(a.mean + x);
      const __m256 floor = _mm256_mul_ps(vmin, mean);
      const __m256 inner = _mm256_and_ps(_mm256_cmp_ps(k, zero, _CMP_GT_OQ), _mm256_cmp_ps(k, vlast, _CMP_LT_OQ));
      __m256 strong = _mm256_and_ps(_mm256_cmp_ps(l, floor, _CMP_GE_OQ), _mm256_cmp_ps(r, floor, _CMP_GE_OQ));
      strong = _mm256_and_ps(strong, _mm256_cmp_ps(b, floor, _CMP_GE_OQ));
      strong = _mm256_and_ps(strong, _mm256_and_ps(_mm256_cmp_ps(l, zero, _CMP_GT_OQ), _mm256_cmp_ps(r, zero, _CMP_GT_OQ)));
      const __m256 lit = _mm256_cmp_ps(mean, vblack, _CMP_GE_OQ);
      const __m256 bb = select8(_mm256_cmp_ps(b, zero, _CMP_GT_OQ), b, one);
      const __m256 lm = fast_ln8(select8(strong, _mm256_div_ps(l, bb), one));
      const __m256 lp = fast_ln8(select8(strong, _mm256_div_ps(r, bb), one));
      const __m256 curv = _mm256_add_ps(lm, lp);
      const __m256 curved = _mm256_cmp_ps(curv, _mm256_set1_ps(-1e-9f), _CMP_LT_OQ);
      const __m256 off = _mm256_div_ps(_mm256_mul_ps(half, _mm256_sub_ps(lm, lp)), select8(curved, curv, _mm256_set1_ps(-1.f)));
      const __m256 in_range = _mm256_cmp_ps(_mm256_and_ps(off, abs_mask), _mm256_set1_ps(0.5f + 1e-4f), _CMP_LE_OQ);
      // Saturation: bit x % 8 of byte x / 8, x a multiple of 8 here.
      const __m256i sat_byte = _mm256_set1_epi32(a.sat[x / 8]);
      const __m256 unsaturated = _mm256_castsi256_ps(
          _mm256_cmpeq_epi32(_mm256_and_si256(sat_byte, bit_of_lane), _mm256_setzero_si256()));
      const __m256 ok = _mm256_and_ps(_mm256_and_ps(_mm256_and_ps(inner, strong), _mm256_and_ps(lit, curved)),
                                      _mm256_and_ps(in_range, unsaturated));
      const __m256 clamped = _mm256_min_ps(_mm256_max_ps(off, _mm256_set1_ps(-0.5f)), half);
      const __m256 fbar = select8(ok, _mm256_add_ps(k, clamped), nan);
      store8(a.fbar + x, fbar, stream);
      const auto ok_bits = static_cast<unsigned>(_mm256_movemask_ps(ok));
      count += static_cast<size_t>(__builtin_popcount(ok_bits));
      if (a.peak != nullptr) store8(a.peak + x, b, stream);
      _mm256_store_ps(fb + 8 * g, fbar);
      ok_of[g] = static_cast<uint8_t>(ok_bits);
    }
    x = chunk_begin;
    for (uint32_t g = 0; g < groups; ++g, x += 8) {
      const __m256 fbar = _mm256_load_ps(fb + 8 * g);
      // ok exactly where fbar is not NaN (an ok fbar is k + a clamped offset: finite).
      const __m256 ok = _mm256_cmp_ps(fbar, fbar, _CMP_ORD_Q);
      // No valid lane (background, shadow, black): no lookup, its result would be all NaN.
      const __m256 out = a.table == nullptr ? fbar : (ok_of[g] != 0u ? lookup8(*a.table, fbar, ok) : nan);
      if (a.table != nullptr) store8(a.depth + x, out, stream);
      if (a.valid != nullptr) {
        // Finite: |v| < inf (false for NaN and inf), as the scalar twin.
        const auto m = static_cast<uint32_t>(_mm256_movemask_ps(_mm256_cmp_ps(_mm256_and_ps(out, abs_mask), inf, _CMP_LT_OQ)));
        valid_count += static_cast<size_t>(__builtin_popcount(m));
        if (stream_valid)
          _mm_stream_si64(reinterpret_cast<long long*>(a.valid + x), static_cast<long long>(kByteMasks.v[m]));
        else
          std::memcpy(a.valid + x, &kByteMasks.v[m], 8);
      }
    }
  }
  if (a.valid != nullptr) *a.valid_count += valid_count;
  if (stream || stream_valid) _mm_sfence();  // the streamed rows are visible before the pass reports done
  return count + fbar_row_scalar(a, x, x_end);
}

#else
size_t fbar_row_avx2(const RowArgs& a, uint32_t x_begin, uint32_t x_end) noexcept {
  return fbar_row_scalar(a, x_begin, x_end);
}
#endif

}  // namespace procam::defocus::detail
