// SPDX-License-Identifier: MIT
// Ensemble vote and classification (thesis §3.3.3, §3.4; see vote.hpp).
#include "vote.hpp"

#include "binarize.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "procam/sdk/simd.hpp"

namespace procam::sl {

const char* transport_class_name(uint8_t c) {
  switch (c) {
    case kUnlit: return "unlit";
    case kAllAgree: return "all_agree";
    case kInterreflection: return "interreflection";
    case kSubsurface: return "subsurface";
    case kPartial: return "partial";
    case kError: return "error";
    case kConflict: return "conflict";
    default: return "unknown";
  }
}

void vote_pixels(const float* const code[kEnsembleCodes], const uint8_t* lit, size_t begin,
                 size_t end, float agree_px, float* coord, uint8_t* valid, float* confidence,
                 uint8_t* cls) {
  constexpr uint32_t kPreference[kEnsembleCodes] = {kGray, kXor04, kXor02, kMinsw};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (size_t i = begin; i < end; ++i) {
    float v[kEnsembleCodes];
    for (uint32_t k = 0; k < kEnsembleCodes; ++k) v[k] = code[k][i];
    uint32_t support[kEnsembleCodes] = {0, 0, 0, 0};
    uint32_t pairs = 0;
    bool gray_pair = false, logical_pair = false;
    for (uint32_t a = 0; a < kEnsembleCodes; ++a)
      for (uint32_t b = a + 1; b < kEnsembleCodes; ++b) {
        // NaN compares false: an invalid code never agrees.
        if (std::fabs(v[a] - v[b]) <= agree_px) {
          ++support[a];
          ++support[b];
          ++pairs;
          if (a == kGray && b == kMinsw) gray_pair = true;
          if (a == kXor02 && b == kXor04) logical_pair = true;
        }
      }
    uint32_t best = 0;
    for (uint32_t k = 0; k < kEnsembleCodes; ++k) best = support[k] > best ? support[k] : best;
    if (best == 0 || lit[i] == 0) {
      coord[i] = nan;
      valid[i] = 0;
      confidence[i] = 0.0f;
      cls[i] = lit[i] != 0 ? kError : kUnlit;
      continue;
    }
    uint32_t pick = kGray;
    uint8_t c = kPartial;
    float value = 0.0f;
    if (pairs == 1 && gray_pair) {
      // min-SW's value (thesis), but their midpoint when the two are a full
      // agree_px apart (in half columns, as vote_keys compares them).
      const bool full_apart = std::floor(2.0f * std::fabs(v[kGray] - v[kMinsw]) + 1e-3f) >=
                              std::floor(2.0f * agree_px);
      value = full_apart ? 0.5f * (v[kGray] + v[kMinsw]) : v[kMinsw];
      c = kSubsurface;
    } else {
      for (uint32_t k : kPreference)
        if (support[k] == best) {
          pick = k;
          break;
        }
      c = pairs == 1 && logical_pair ? kInterreflection : pairs == 6 ? kAllAgree : kPartial;
      // Median of the codes agreeing with the pick (sum minus the extremes;
      // values are multiples of 0.5, every step is exact) when there are 3 or
      // 4; with 2 their midpoint (issue 18: the pick's own value could sit a
      // column from the truth when the two split between neighbouring columns).
      float sum = 0.0f, lo = v[pick], hi = v[pick];
      uint32_t count = 0;
      for (uint32_t k = 0; k < kEnsembleCodes; ++k)
        if (std::fabs(v[k] - v[pick]) <= agree_px) {
          sum += v[k];
          lo = std::min(lo, v[k]);
          hi = std::max(hi, v[k]);
          ++count;
        }
      value = count >= 3 ? (sum - lo - hi) / static_cast<float>(count - 2) : 0.5f * sum;
    }
    coord[i] = value;
    valid[i] = 255;
    confidence[i] = static_cast<float>(best + 1) / 4.0f;
    cls[i] = c;
  }
}

namespace {
// report_columns: the refined column moves the vote's value by at most half
// a column (issue 18, session 15).
constexpr float kMaxReportShift = 0.5f;

void report_columns_scalar(float* coord, const uint8_t* valid, const float* confidence, const float* refined,
                           size_t b, size_t n) {
  for (size_t i = b; i < n; ++i)
    if (valid[i] != 0 && confidence[i] < 1.0f && std::isfinite(refined[i]))
      coord[i] = std::clamp(0.5f * std::nearbyint(2.0f * refined[i]), coord[i] - kMaxReportShift,
                            coord[i] + kMaxReportShift);
}

#ifdef PROCAM_SDK_X86
// report_columns_scalar, 16 pixels per step: the same tests (an ordered
// compare is false for NaN, as the scalar < and isfinite), the same
// products (2 x and 0.5 x: exact, or the same overflow), and nearbyint as
// roundscale in the current rounding mode without exceptions (what
// nearbyint is). Returns the pixels done.
__attribute__((target("avx512f,avx512bw,avx512vl"))) size_t report_columns_avx512(
    float* coord, const uint8_t* valid, const float* confidence, const float* refined, size_t n) {
  const __m512 inf = _mm512_set1_ps(std::numeric_limits<float>::infinity());
  const __m512 one = _mm512_set1_ps(1.0f), two = _mm512_set1_ps(2.0f), half = _mm512_set1_ps(0.5f);
  const __m512 shift = _mm512_set1_ps(kMaxReportShift);
  size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    const __mmask16 v = _mm_test_epi8_mask(_mm_loadu_si128(reinterpret_cast<const __m128i*>(valid + i)),
                                           _mm_set1_epi8(-1));
    const __m512 r = _mm512_loadu_ps(refined + i);
    const __mmask16 take = static_cast<__mmask16>(
        v & _mm512_cmp_ps_mask(_mm512_loadu_ps(confidence + i), one, _CMP_LT_OQ) &
        _mm512_cmp_ps_mask(_mm512_abs_ps(r), inf, _CMP_LT_OQ));
    if (take == 0) continue;
    const __m512 rounded =
        _mm512_roundscale_ps(_mm512_mul_ps(two, r), _MM_FROUND_CUR_DIRECTION | _MM_FROUND_NO_EXC);
    // std::clamp(x, c - 0.5, c + 0.5) bit for bit: max/min return their
    // second operand when either is NaN or both compare equal, as clamp
    // returns x when neither x < lo nor hi < x.
    const __m512 c = _mm512_loadu_ps(coord + i);
    const __m512 x = _mm512_mul_ps(half, rounded);
    const __m512 clamped = _mm512_min_ps(_mm512_add_ps(c, shift), _mm512_max_ps(_mm512_sub_ps(c, shift), x));
    _mm512_mask_storeu_ps(coord + i, take, clamped);
  }
  return i;
}
#endif

}  // namespace

void report_columns(float* coord, const uint8_t* valid, const float* confidence, const float* refined,
                    size_t n) {
  size_t i = 0;
#ifdef PROCAM_SDK_X86
  if (avx512_active()) i = report_columns_avx512(coord, valid, confidence, refined, n);
#endif
  report_columns_scalar(coord, valid, confidence, refined, i, n);
}

int32_t agree_key_threshold(float agree_px) {
  return static_cast<int32_t>(std::floor(2.0f * agree_px));
}

namespace {

void vote_keys_scalar(const int32_t* const key[kEnsembleCodes], const uint8_t* lit, size_t b,
                      size_t n, int32_t agree2, float* coord, uint8_t* valid, float* confidence,
                      uint8_t* cls) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const int32_t* k0 = key[kGray];
  const int32_t* k1 = key[kXor02];
  const int32_t* k2 = key[kXor04];
  const int32_t* k3 = key[kMinsw];
  for (size_t i = b; i < n; ++i) {
    const int32_t a0 = k0[i], a1 = k1[i], a2 = k2[i], a3 = k3[i];
    auto agree = [agree2](int32_t x, int32_t y) -> int32_t {
      const int32_t d = x - y;
      return static_cast<int32_t>((x >= 0) & (y >= 0) & ((d < 0 ? -d : d) <= agree2));
    };
    const int32_t p01 = agree(a0, a1), p02 = agree(a0, a2), p03 = agree(a0, a3);
    const int32_t p12 = agree(a1, a2), p13 = agree(a1, a3), p23 = agree(a2, a3);
    const int32_t s0 = p01 + p02 + p03, s1 = p01 + p12 + p13, s2 = p02 + p12 + p23,
                  s3 = p03 + p13 + p23;
    const int32_t pairs = p01 + p02 + p03 + p12 + p13 + p23;
    int32_t best = s0 > s1 ? s0 : s1;
    best = best > s2 ? best : s2;
    best = best > s3 ? best : s3;
    const bool sub = pairs == 1 && p03 != 0, inter = pairs == 1 && p12 != 0;
    // Pick: first of gray, xor04, xor02, minsw with the largest support;
    // value: median key of the codes agreeing with the pick, pick included;
    // {gray, minsw} alone -> minsw's key (thesis rule).
    const int32_t pick = s0 == best ? a0 : s2 == best ? a2 : s1 == best ? a1 : a3;
    const int32_t m0 = agree(a0, pick), m1 = agree(a1, pick), m2 = agree(a2, pick), m3 = agree(a3, pick);
    const int32_t members = m0 + m1 + m2 + m3;
    // Median of the members: sum minus the extremes when there are 3 or 4;
    // with 2 members their midpoint (sum of both, count 2).
    const int32_t big = std::numeric_limits<int32_t>::max();
    const int32_t lo = std::min(std::min(m0 ? a0 : big, m1 ? a1 : big), std::min(m2 ? a2 : big, m3 ? a3 : big));
    const int32_t hi = std::max(std::max(m0 ? a0 : -1, m1 ? a1 : -1), std::max(m2 ? a2 : -1, m3 ? a3 : -1));
    const bool trim = members >= 3;
    const int32_t msum = m0 * a0 + m1 * a1 + m2 * a2 + m3 * a3;
    // {gray, minsw} a full agree_px apart: their midpoint, not minsw's value
    // (issue 18, session 15; docs/structured-light.md "Ensemble vote").
    const int32_t d03 = a0 - a3;
    const bool sub_value = sub && (d03 < 0 ? -d03 : d03) < agree2;
    const int32_t sum = sub_value ? a3 : trim ? msum - lo - hi : msum;
    const int32_t count = sub_value ? 1 : trim ? members - 2 : 2;
    const auto c = static_cast<uint8_t>(sub ? kSubsurface : inter ? kInterreflection : pairs == 6 ? kAllAgree : kPartial);
    const bool is_lit = lit[i] != 0;
    const bool ok = best > 0 && is_lit;
    // count is 1 or 2 (a median of 3 or 4): key / 2 / count, exact.
    coord[i] = ok ? static_cast<float>(sum) * (count == 2 ? 0.25f : 0.5f) : nan;
    valid[i] = ok ? 255 : 0;
    confidence[i] = ok ? static_cast<float>(best + 1) * 0.25f : 0.0f;
    cls[i] = ok ? c : static_cast<uint8_t>(is_lit ? kError : kUnlit);
  }
}

#ifdef PROCAM_SDK_X86
#define PROCAM_AVX2 __attribute__((target("avx2"), always_inline)) inline
PROCAM_AVX2 __m256i agree8(__m256i a, __m256i b, __m256i limit) {
  const __m256i minus1 = _mm256_set1_epi32(-1);
  const __m256i both = _mm256_and_si256(_mm256_cmpgt_epi32(a, minus1), _mm256_cmpgt_epi32(b, minus1));
  return _mm256_and_si256(both, _mm256_cmpgt_epi32(limit, _mm256_abs_epi32(_mm256_sub_epi32(a, b))));
}
PROCAM_AVX2 __m256i pick8(__m256i mask, __m256i yes, __m256i no) {
  return _mm256_blendv_epi8(no, yes, mask);
}
PROCAM_AVX2 void store8(uint8_t* dst, __m256i v) {  // 8 x int32 in 0..255 -> 8 bytes
  const __m128i w16 = _mm_packs_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  _mm_storel_epi64(reinterpret_cast<__m128i*>(dst), _mm_packus_epi16(w16, w16));
}

// 8 pixels per step, the same integer rule as vote_keys_scalar (masks are
// -1/0, so sums of masks are minus counts).
__attribute__((target("avx2"))) void vote_keys_avx2(const int32_t* const key[kEnsembleCodes],
                                                   const uint8_t* lit, size_t n, int32_t agree2,
                                                   float* coord, uint8_t* valid,
                                                   float* confidence, uint8_t* cls) {
  const __m256i zero = _mm256_setzero_si256();
  const __m256i limit = _mm256_set1_epi32(agree2 + 1);  // |d| <= agree2 <=> agree2 + 1 > |d|
  const __m256i one = _mm256_set1_epi32(1), six = _mm256_set1_epi32(6);
  const __m256 half = _mm256_set1_ps(0.5f), quarter = _mm256_set1_ps(0.25f);
  const __m256 nan = _mm256_set1_ps(std::numeric_limits<float>::quiet_NaN());
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256i a0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(key[kGray] + i));
    const __m256i a1 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(key[kXor02] + i));
    const __m256i a2 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(key[kXor04] + i));
    const __m256i a3 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(key[kMinsw] + i));
    const __m256i p01 = agree8(a0, a1, limit), p02 = agree8(a0, a2, limit), p03 = agree8(a0, a3, limit);
    const __m256i p12 = agree8(a1, a2, limit), p13 = agree8(a1, a3, limit), p23 = agree8(a2, a3, limit);
    const __m256i s0 = _mm256_sub_epi32(zero, _mm256_add_epi32(_mm256_add_epi32(p01, p02), p03));
    const __m256i s1 = _mm256_sub_epi32(zero, _mm256_add_epi32(_mm256_add_epi32(p01, p12), p13));
    const __m256i s2 = _mm256_sub_epi32(zero, _mm256_add_epi32(_mm256_add_epi32(p02, p12), p23));
    const __m256i s3 = _mm256_sub_epi32(zero, _mm256_add_epi32(_mm256_add_epi32(p03, p13), p23));
    const __m256i pairs = _mm256_srli_epi32(_mm256_add_epi32(_mm256_add_epi32(s0, s1), _mm256_add_epi32(s2, s3)), 1);
    const __m256i best = _mm256_max_epi32(_mm256_max_epi32(s0, s1), _mm256_max_epi32(s2, s3));
    const __m256i single = _mm256_cmpeq_epi32(pairs, one);
    const __m256i sub = _mm256_and_si256(single, p03), inter = _mm256_and_si256(single, p12);
    __m256i v = a3;  // preference gray, xor04, xor02, minsw: apply in reverse
    v = pick8(_mm256_cmpeq_epi32(s1, best), a1, v);
    v = pick8(_mm256_cmpeq_epi32(s2, best), a2, v);
    v = pick8(_mm256_cmpeq_epi32(s0, best), a0, v);
    // Mean key of the codes agreeing with the pick; {gray, minsw} alone -> minsw.
    const __m256i m0 = agree8(a0, v, limit), m1 = agree8(a1, v, limit);
    const __m256i m2 = agree8(a2, v, limit), m3 = agree8(a3, v, limit);
    __m256i sum = _mm256_add_epi32(_mm256_add_epi32(_mm256_and_si256(m0, a0), _mm256_and_si256(m1, a1)),
                                   _mm256_add_epi32(_mm256_and_si256(m2, a2), _mm256_and_si256(m3, a3)));
    __m256i count = _mm256_sub_epi32(zero, _mm256_add_epi32(_mm256_add_epi32(m0, m1), _mm256_add_epi32(m2, m3)));
    // Median: drop the members' extremes when there are 3 or 4.
    const __m256i big = _mm256_set1_epi32(std::numeric_limits<int32_t>::max()), neg = _mm256_set1_epi32(-1);
    const __m256i lo = _mm256_min_epi32(_mm256_min_epi32(pick8(m0, a0, big), pick8(m1, a1, big)),
                                        _mm256_min_epi32(pick8(m2, a2, big), pick8(m3, a3, big)));
    const __m256i hi = _mm256_max_epi32(_mm256_max_epi32(pick8(m0, a0, neg), pick8(m1, a1, neg)),
                                        _mm256_max_epi32(pick8(m2, a2, neg), pick8(m3, a3, neg)));
    const __m256i trim = _mm256_cmpgt_epi32(count, _mm256_set1_epi32(2));
    sum = pick8(trim, _mm256_sub_epi32(sum, _mm256_add_epi32(lo, hi)), sum);  // 2 members: their sum
    count = pick8(trim, _mm256_sub_epi32(count, _mm256_set1_epi32(2)), count);  // and count 2: midpoint
    // {gray, minsw} a full agree_px apart keep their midpoint (scalar kernel).
    const __m256i sub_value =
        _mm256_and_si256(sub, _mm256_cmpgt_epi32(_mm256_set1_epi32(agree2), _mm256_abs_epi32(_mm256_sub_epi32(a0, a3))));
    sum = pick8(sub_value, a3, sum);
    count = pick8(sub_value, one, count);  // 1 or 2: scale the key by 1/2 or 1/4 (exact)
    const __m256 scale = _mm256_blendv_ps(half, quarter, _mm256_castsi256_ps(_mm256_cmpeq_epi32(count, _mm256_set1_epi32(2))));
    const __m256 mean = _mm256_mul_ps(_mm256_cvtepi32_ps(sum), scale);
    __m256i c = _mm256_set1_epi32(kPartial);
    c = pick8(_mm256_cmpeq_epi32(pairs, six), _mm256_set1_epi32(kAllAgree), c);
    c = pick8(inter, _mm256_set1_epi32(kInterreflection), c);
    c = pick8(sub, _mm256_set1_epi32(kSubsurface), c);
    const __m256i is_lit = _mm256_cmpgt_epi32(
        _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(lit + i))), zero);
    const __m256i ok = _mm256_and_si256(_mm256_cmpgt_epi32(best, zero), is_lit);
    c = pick8(ok, c, pick8(is_lit, _mm256_set1_epi32(kError), _mm256_set1_epi32(kUnlit)));
    const __m256 okf = _mm256_castsi256_ps(ok);
    _mm256_storeu_ps(coord + i, _mm256_blendv_ps(nan, mean, okf));
    _mm256_storeu_ps(confidence + i,
                     _mm256_and_ps(okf, _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_add_epi32(best, one)), quarter)));
    store8(valid + i, _mm256_and_si256(ok, _mm256_set1_epi32(255)));
    store8(cls + i, c);
  }
  if (i < n) vote_keys_scalar(key, lit, i, n, agree2, coord, valid, confidence, cls);
}

#define PROCAM_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl"), always_inline)) inline
PROCAM_AVX512 __mmask16 agree16(__m512i a, __m512i b, __mmask16 both, __m512i limit) {
  return static_cast<__mmask16>(
      both & _mm512_cmpgt_epi32_mask(limit, _mm512_abs_epi32(_mm512_sub_epi32(a, b))));
}
PROCAM_AVX512 __m512i count16(__mmask16 x, __mmask16 y, __mmask16 z) {  // x + y + z per lane
  const __m512i one = _mm512_set1_epi32(1);
  return _mm512_add_epi32(_mm512_add_epi32(_mm512_maskz_mov_epi32(x, one), _mm512_maskz_mov_epi32(y, one)),
                          _mm512_maskz_mov_epi32(z, one));
}

// vote_keys_avx2, 16 pixels per step: agreements as mask registers, supports
// as counts (the same integer rule as vote_keys_scalar).
__attribute__((target("avx512f,avx512bw,avx512vl"))) void vote_keys_avx512(
    const int32_t* const key[kEnsembleCodes], const uint8_t* lit, size_t n, int32_t agree2,
    float* coord, uint8_t* valid, float* confidence, uint8_t* cls) {
  const __m512i zero = _mm512_setzero_si512(), minus1 = _mm512_set1_epi32(-1);
  const __m512i limit = _mm512_set1_epi32(agree2 + 1);  // |d| <= agree2 <=> agree2 + 1 > |d|
  const __m512i one = _mm512_set1_epi32(1), six = _mm512_set1_epi32(6);
  const __m512 half = _mm512_set1_ps(0.5f), quarter = _mm512_set1_ps(0.25f);
  const __m512 nan = _mm512_set1_ps(std::numeric_limits<float>::quiet_NaN());
  size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    const __m512i a0 = _mm512_loadu_si512(key[kGray] + i);
    const __m512i a1 = _mm512_loadu_si512(key[kXor02] + i);
    const __m512i a2 = _mm512_loadu_si512(key[kXor04] + i);
    const __m512i a3 = _mm512_loadu_si512(key[kMinsw] + i);
    const __mmask16 v0 = _mm512_cmpgt_epi32_mask(a0, minus1), v1 = _mm512_cmpgt_epi32_mask(a1, minus1);
    const __mmask16 v2 = _mm512_cmpgt_epi32_mask(a2, minus1), v3 = _mm512_cmpgt_epi32_mask(a3, minus1);
    const __mmask16 p01 = agree16(a0, a1, v0 & v1, limit), p02 = agree16(a0, a2, v0 & v2, limit);
    const __mmask16 p03 = agree16(a0, a3, v0 & v3, limit), p12 = agree16(a1, a2, v1 & v2, limit);
    const __mmask16 p13 = agree16(a1, a3, v1 & v3, limit), p23 = agree16(a2, a3, v2 & v3, limit);
    const __m512i s0 = count16(p01, p02, p03), s1 = count16(p01, p12, p13);
    const __m512i s2 = count16(p02, p12, p23), s3 = count16(p03, p13, p23);
    const __m512i pairs = _mm512_srli_epi32(_mm512_add_epi32(_mm512_add_epi32(s0, s1), _mm512_add_epi32(s2, s3)), 1);
    const __m512i best = _mm512_max_epi32(_mm512_max_epi32(s0, s1), _mm512_max_epi32(s2, s3));
    const __mmask16 single = _mm512_cmpeq_epi32_mask(pairs, one);
    const __mmask16 sub = single & p03, inter = single & p12;
    __m512i v = a3;  // preference gray, xor04, xor02, minsw: apply in reverse
    v = _mm512_mask_mov_epi32(v, _mm512_cmpeq_epi32_mask(s1, best), a1);
    v = _mm512_mask_mov_epi32(v, _mm512_cmpeq_epi32_mask(s2, best), a2);
    v = _mm512_mask_mov_epi32(v, _mm512_cmpeq_epi32_mask(s0, best), a0);
    // Mean key of the codes agreeing with the pick; {gray, minsw} alone -> minsw.
    const __mmask16 vv = _mm512_cmpgt_epi32_mask(v, minus1);
    const __mmask16 m0 = agree16(a0, v, v0 & vv, limit), m1 = agree16(a1, v, v1 & vv, limit);
    const __mmask16 m2 = agree16(a2, v, v2 & vv, limit), m3 = agree16(a3, v, v3 & vv, limit);
    __m512i sum = _mm512_add_epi32(_mm512_add_epi32(_mm512_maskz_mov_epi32(m0, a0), _mm512_maskz_mov_epi32(m1, a1)),
                                   _mm512_add_epi32(_mm512_maskz_mov_epi32(m2, a2), _mm512_maskz_mov_epi32(m3, a3)));
    __m512i count = _mm512_add_epi32(count16(m0, m1, m2), _mm512_maskz_mov_epi32(m3, one));
    // Median: drop the members' extremes when there are 3 or 4.
    const __m512i big = _mm512_set1_epi32(std::numeric_limits<int32_t>::max());
    const __m512i lo = _mm512_min_epi32(_mm512_min_epi32(_mm512_mask_mov_epi32(big, m0, a0), _mm512_mask_mov_epi32(big, m1, a1)),
                                        _mm512_min_epi32(_mm512_mask_mov_epi32(big, m2, a2), _mm512_mask_mov_epi32(big, m3, a3)));
    const __m512i hi = _mm512_max_epi32(_mm512_max_epi32(_mm512_mask_mov_epi32(minus1, m0, a0), _mm512_mask_mov_epi32(minus1, m1, a1)),
                                        _mm512_max_epi32(_mm512_mask_mov_epi32(minus1, m2, a2), _mm512_mask_mov_epi32(minus1, m3, a3)));
    const __mmask16 trim = _mm512_cmpgt_epi32_mask(count, _mm512_set1_epi32(2));
    sum = _mm512_mask_sub_epi32(sum, trim, sum, _mm512_add_epi32(lo, hi));  // 2 members: their sum
    count = _mm512_mask_sub_epi32(count, trim, count, _mm512_set1_epi32(2));  // and count 2: midpoint
    // {gray, minsw} a full agree_px apart keep their midpoint (scalar kernel).
    const __mmask16 sub_value = static_cast<__mmask16>(
        sub & _mm512_cmpgt_epi32_mask(_mm512_set1_epi32(agree2), _mm512_abs_epi32(_mm512_sub_epi32(a0, a3))));
    sum = _mm512_mask_mov_epi32(sum, sub_value, a3);
    count = _mm512_mask_mov_epi32(count, sub_value, one);  // 1 or 2: scale the key by 1/2 or 1/4 (exact)
    const __m512 mean = _mm512_mul_ps(
        _mm512_cvtepi32_ps(sum),
        _mm512_mask_mov_ps(half, _mm512_cmpeq_epi32_mask(count, _mm512_set1_epi32(2)), quarter));
    __m512i c = _mm512_set1_epi32(kPartial);
    c = _mm512_mask_mov_epi32(c, _mm512_cmpeq_epi32_mask(pairs, six), _mm512_set1_epi32(kAllAgree));
    c = _mm512_mask_mov_epi32(c, inter, _mm512_set1_epi32(kInterreflection));
    c = _mm512_mask_mov_epi32(c, sub, _mm512_set1_epi32(kSubsurface));
    const __m128i lit16 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(lit + i));
    const __mmask16 is_lit = _mm_test_epi8_mask(lit16, lit16);
    const __mmask16 ok = _mm512_cmpgt_epi32_mask(best, zero) & is_lit;
    c = _mm512_mask_mov_epi32(
        _mm512_mask_mov_epi32(_mm512_set1_epi32(kUnlit), is_lit, _mm512_set1_epi32(kError)), ok, c);
    _mm512_storeu_ps(coord + i, _mm512_mask_mov_ps(nan, ok, mean));
    _mm512_storeu_ps(confidence + i,
                     _mm512_maskz_mov_ps(ok, _mm512_mul_ps(_mm512_cvtepi32_ps(_mm512_add_epi32(best, one)), quarter)));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(valid + i), _mm_maskz_set1_epi8(ok, static_cast<char>(255)));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(cls + i), _mm512_cvtepi32_epi8(c));
  }
  if (i < n) vote_keys_scalar(key, lit, i, n, agree2, coord, valid, confidence, cls);
}

// count_classes_scalar, 64 pixels per step.
__attribute__((target("avx512f,avx512bw,avx512vl"))) size_t count_classes_avx512(
    const uint8_t* lit, const uint8_t* valid, const uint8_t* cls, size_t n, PixelCounts& c) {
  const __m512i zero = _mm512_setzero_si512();
  size_t i = 0;
  for (; i + 64 <= n; i += 64) {
    const __m512i l = _mm512_loadu_si512(lit + i), v = _mm512_loadu_si512(valid + i);
    const __m512i k = _mm512_loadu_si512(cls + i);
    c.lit += static_cast<size_t>(__builtin_popcountll(_mm512_cmpneq_epi8_mask(l, zero)));
    c.valid += static_cast<size_t>(__builtin_popcountll(_mm512_cmpneq_epi8_mask(v, zero)));
    for (uint32_t j = 0; j + 1 < kTransportClassCount; ++j)
      c.cls[j] += static_cast<size_t>(
          __builtin_popcountll(_mm512_cmpeq_epi8_mask(k, _mm512_set1_epi8(static_cast<char>(j)))));
    c.cls[kTransportClassCount - 1] += static_cast<size_t>(__builtin_popcountll(
        _mm512_cmpge_epu8_mask(k, _mm512_set1_epi8(static_cast<char>(kTransportClassCount - 1)))));
    c.flagged += static_cast<size_t>(__builtin_popcountll(
        _mm512_cmpeq_epi8_mask(k, _mm512_set1_epi8(static_cast<char>(kError))) |
        _mm512_cmpeq_epi8_mask(k, _mm512_set1_epi8(static_cast<char>(kConflict)))));
  }
  return i;
}
#endif

void count_classes_scalar(const uint8_t* lit, const uint8_t* valid, const uint8_t* cls, size_t b, size_t n,
                          PixelCounts& c) {
  for (size_t i = b; i < n; ++i) {
    c.lit += lit[i] != 0 ? 1u : 0u;
    c.valid += valid[i] != 0 ? 1u : 0u;
    c.flagged += cls[i] == kError || cls[i] == kConflict ? 1u : 0u;
    ++c.cls[std::min<size_t>(cls[i], kTransportClassCount - 1)];
  }
}

}  // namespace

void count_classes(const uint8_t* lit, const uint8_t* valid, const uint8_t* cls, size_t n, PixelCounts& c) {
  size_t i = 0;
#ifdef PROCAM_SDK_X86
  if (avx512_active()) i = count_classes_avx512(lit, valid, cls, n, c);
#endif
  count_classes_scalar(lit, valid, cls, i, n, c);
}

void vote_keys(const int32_t* const key[kEnsembleCodes], const uint8_t* lit, size_t n,
               int32_t agree2, float* coord, uint8_t* valid, float* confidence, uint8_t* cls) {
#ifdef PROCAM_SDK_X86
  if (avx512_active()) return vote_keys_avx512(key, lit, n, agree2, coord, valid, confidence, cls);
  if (simd_active()) return vote_keys_avx2(key, lit, n, agree2, coord, valid, confidence, cls);
#endif
  vote_keys_scalar(key, lit, 0, n, agree2, coord, valid, confidence, cls);
}

}  // namespace procam::sl
