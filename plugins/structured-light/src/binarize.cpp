// SPDX-License-Identifier: MIT
// Bit-plane binarization kernels (thesis Eq. 3.5 and §3.2 footnote 2; see
// binarize.hpp for the rules and the 8-bit margin saturation argument).
#include "binarize.hpp"

#include <algorithm>
#include <cstring>
#include <cmath>
#include <limits>

#include "procam/sdk/simd.hpp"

namespace procam::sl {

void fold_plane(const float* __restrict L, const float* __restrict L_bar, size_t n,
                uint32_t position, float saturation, uint16_t* __restrict word,
                float* __restrict min_margin, uint8_t* __restrict flags) {
  const auto bit = static_cast<uint16_t>(1u << position);
  // Branch-free so the compiler can vectorize; NaN/inf are caught by the
  // flag (a NaN margin never lowers min_margin: the comparison is false).
  for (size_t i = 0; i < n; ++i) {
    const float l = L[i], lb = L_bar[i];
    const float d = l - lb;
    const float margin = std::fabs(d);
    word[i] = static_cast<uint16_t>(word[i] | (d > 0.0f ? bit : 0));  // Eq. 3.5: lit when L > L̄
    min_margin[i] = margin < min_margin[i] ? margin : min_margin[i];
    const int saturated = (l >= saturation) & (lb >= saturation);
    const int non_finite = !(margin <= std::numeric_limits<float>::max());
    flags[i] = static_cast<uint8_t>(flags[i] | saturated * kFlagSaturated |
                                    non_finite * kFlagNonFinite);
  }
}

namespace {

// d = L - L̄ as an int; margin saturated at 255.
inline void fold_one(int32_t d, uint8_t bit, bool first, bool first_word, uint8_t& word,
                     uint8_t& margin) {
  const int32_t a = d < 0 ? -d : d;
  const auto m = static_cast<uint8_t>(a > 255 ? 255 : a);
  word = static_cast<uint8_t>((first_word ? 0 : word) | (d > 0 ? bit : 0));
  margin = first ? m : (m < margin ? m : margin);
}

// L - L̄ of pixel i: synthetic 2L - (R + B) with R = W (B may be null),
// inverse L - R with R = L̄.
template <bool kSynthetic>
inline int32_t diff(const uint8_t* L, const uint8_t* R, const uint8_t* B, size_t i) {
  if constexpr (kSynthetic)
    return 2 * int32_t{L[i]} - int32_t{R[i]} - (B != nullptr ? int32_t{B[i]} : 0);
  else
    return int32_t{L[i]} - int32_t{R[i]};
}

#ifdef PROCAM_SDK_X86
// 32 pixels: d (two halves of 16 x int16, pixels 0-15 and 16-31) -> word
// byte |= bit where d > 0, margin = min(margin, min(|d|, 255)).
__attribute__((target("avx2"), always_inline)) inline void fold32_avx2(
    __m256i d_lo, __m256i d_hi, __m256i bitv, bool first, bool first_word, uint8_t* word,
    uint8_t* margin) {
  const __m256i zero = _mm256_setzero_si256();
  const __m256i gt = _mm256_permute4x64_epi64(
      _mm256_packs_epi16(_mm256_cmpgt_epi16(d_lo, zero), _mm256_cmpgt_epi16(d_hi, zero)), 0xD8);
  const __m256i set = _mm256_and_si256(gt, bitv);
  __m256i* wp = reinterpret_cast<__m256i*>(word);
  _mm256_storeu_si256(wp, first_word ? set : _mm256_or_si256(_mm256_loadu_si256(wp), set));
  // |d| <= 510 fits int16; packus saturates to 0..255 per 128-bit lane.
  const __m256i m = _mm256_permute4x64_epi64(
      _mm256_packus_epi16(_mm256_abs_epi16(d_lo), _mm256_abs_epi16(d_hi)), 0xD8);
  __m256i* mp = reinterpret_cast<__m256i*>(margin);
  _mm256_storeu_si256(mp, first ? m : _mm256_min_epu8(m, _mm256_loadu_si256(mp)));
}

template <bool kSynthetic>
__attribute__((target("avx2"))) void fold_u8_avx2(const uint8_t* __restrict L,
                                                  const uint8_t* __restrict R,
                                                  const uint8_t* __restrict B, size_t n,
                                                  uint32_t position, bool first, bool first_word,
                                                  uint8_t* __restrict word,
                                                  uint8_t* __restrict margin) {
  const auto bit = static_cast<uint8_t>(1u << position);
  const __m256i bitv = _mm256_set1_epi8(static_cast<char>(bit));
  size_t i = 0;
  for (; i + 32 <= n; i += 32) {
    // The frames come from DRAM (a hint; reads past the row are harmless).
    _mm_prefetch(reinterpret_cast<const char*>(L + i + 2048), _MM_HINT_T0);
    const __m256i l = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(L + i));
    const __m256i r = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(R + i));
    __m256i l_lo = _mm256_cvtepu8_epi16(_mm256_castsi256_si128(l));
    __m256i l_hi = _mm256_cvtepu8_epi16(_mm256_extracti128_si256(l, 1));
    __m256i r_lo = _mm256_cvtepu8_epi16(_mm256_castsi256_si128(r));
    __m256i r_hi = _mm256_cvtepu8_epi16(_mm256_extracti128_si256(r, 1));
    if constexpr (kSynthetic) {  // 2L vs W + B
      l_lo = _mm256_add_epi16(l_lo, l_lo);
      l_hi = _mm256_add_epi16(l_hi, l_hi);
      if (B != nullptr) {
        const __m256i b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(B + i));
        r_lo = _mm256_add_epi16(r_lo, _mm256_cvtepu8_epi16(_mm256_castsi256_si128(b)));
        r_hi = _mm256_add_epi16(r_hi, _mm256_cvtepu8_epi16(_mm256_extracti128_si256(b, 1)));
      }
    }
    fold32_avx2(_mm256_sub_epi16(l_lo, r_lo), _mm256_sub_epi16(l_hi, r_hi), bitv, first,
                first_word, word + i, margin + i);
  }
  for (; i < n; ++i) fold_one(diff<kSynthetic>(L, R, B, i), bit, first, first_word, word[i], margin[i]);
}

// The same rule, 32 pixels per step in 512-bit int16 lanes, with mask
// registers instead of packs and permutes (AVX-512 F + BW + VL).
constexpr size_t kPrefetchAhead = 6144;  // bytes ahead of the frame streams
template <bool kSynthetic>
__attribute__((target("avx512f,avx512bw,avx512vl"))) void fold_u8_avx512(
    const uint8_t* __restrict L, const uint8_t* __restrict R, const uint8_t* __restrict B,
    size_t n, uint32_t position, bool first, bool first_word, uint8_t* __restrict word,
    uint8_t* __restrict margin) {
  const auto bit = static_cast<uint8_t>(1u << position);
  const __m512i zero = _mm512_setzero_si512();
  size_t i = 0;
  for (; i + 32 <= n; i += 32) {
    // Frames come from DRAM (inverse mode: the waiting copy may be either
    // operand, so both are prefetched), once per cache line (a hint; reads
    // past the row are harmless).
    if ((i & 63) == 0) {
      _mm_prefetch(reinterpret_cast<const char*>(L + i + kPrefetchAhead), _MM_HINT_T0);
      if constexpr (!kSynthetic) _mm_prefetch(reinterpret_cast<const char*>(R + i + kPrefetchAhead), _MM_HINT_T0);
    }
    __m512i l = _mm512_cvtepu8_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(L + i)));
    __m512i r = _mm512_cvtepu8_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(R + i)));
    if constexpr (kSynthetic) {  // 2L vs W + B
      l = _mm512_add_epi16(l, l);
      if (B != nullptr)
        r = _mm512_add_epi16(
            r, _mm512_cvtepu8_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(B + i))));
    }
    const __m512i d = _mm512_sub_epi16(l, r);
    const __m256i set = _mm256_maskz_set1_epi8(_mm512_cmpgt_epi16_mask(d, zero), static_cast<char>(bit));
    __m256i* wp = reinterpret_cast<__m256i*>(word + i);
    _mm256_storeu_si256(wp, first_word ? set : _mm256_or_si256(_mm256_loadu_si256(wp), set));
    // |d| <= 510; unsigned saturation to 0..255.
    const __m256i m = _mm512_cvtusepi16_epi8(_mm512_abs_epi16(d));
    __m256i* mp = reinterpret_cast<__m256i*>(margin + i);
    _mm256_storeu_si256(mp, first ? m : _mm256_min_epu8(m, _mm256_loadu_si256(mp)));
  }
  for (; i < n; ++i) fold_one(diff<kSynthetic>(L, R, B, i), bit, first, first_word, word[i], margin[i]);
}
#endif  // PROCAM_SDK_X86

const bool kHaveAvx2 = sdk::cpu_has_avx2();
const bool kHaveAvx512 = sdk::cpu_has_avx512();
bool g_simd_enabled = true;
bool g_avx512_enabled = true;

}  // namespace

bool simd_active() { return kHaveAvx2 && g_simd_enabled; }
bool avx512_active() { return kHaveAvx512 && g_simd_enabled && g_avx512_enabled; }
void set_simd_enabled(bool enabled) { g_simd_enabled = enabled; }
void set_avx512_enabled(bool enabled) { g_avx512_enabled = enabled; }

namespace {
template <bool kSynthetic>
void fold_u8_scalar(const uint8_t* __restrict L, const uint8_t* __restrict R,
                    const uint8_t* __restrict B, size_t n, uint32_t position, bool first,
                    bool first_word, uint8_t* __restrict word, uint8_t* __restrict margin) {
  const auto bit = static_cast<uint8_t>(1u << position);
  for (size_t i = 0; i < n; ++i)
    fold_one(diff<kSynthetic>(L, R, B, i), bit, first, first_word, word[i], margin[i]);
}
}  // namespace

void fold_u8_synthetic_scalar(const uint8_t* L, const uint8_t* W, const uint8_t* B, size_t n,
                              uint32_t position, bool first, bool first_word, uint8_t* word,
                              uint8_t* min_margin) {
  fold_u8_scalar<true>(L, W, B, n, position, first, first_word, word, min_margin);
}

void fold_u8_inverse_scalar(const uint8_t* L, const uint8_t* L_bar, size_t n, uint32_t position,
                            bool first, bool first_word, uint8_t* word, uint8_t* min_margin) {
  fold_u8_scalar<false>(L, L_bar, nullptr, n, position, first, first_word, word, min_margin);
}

void fold_u8_synthetic(const uint8_t* L, const uint8_t* W, const uint8_t* B, size_t n,
                       uint32_t position, bool first, bool first_word, uint8_t* word,
                       uint8_t* min_margin) {
#ifdef PROCAM_SDK_X86
  if (avx512_active())
    return fold_u8_avx512<true>(L, W, B, n, position, first, first_word, word, min_margin);
  if (simd_active())
    return fold_u8_avx2<true>(L, W, B, n, position, first, first_word, word, min_margin);
#endif
  fold_u8_synthetic_scalar(L, W, B, n, position, first, first_word, word, min_margin);
}

void fold_u8_inverse(const uint8_t* L, const uint8_t* L_bar, size_t n, uint32_t position,
                     bool first, bool first_word, uint8_t* word, uint8_t* min_margin) {
#ifdef PROCAM_SDK_X86
  if (avx512_active())
    return fold_u8_avx512<false>(L, L_bar, nullptr, n, position, first, first_word, word,
                                 min_margin);
  if (simd_active())
    return fold_u8_avx2<false>(L, L_bar, nullptr, n, position, first, first_word, word,
                               min_margin);
#endif
  fold_u8_inverse_scalar(L, L_bar, n, position, first, first_word, word, min_margin);
}

namespace {
void intensity_u8_scalar(const uint8_t* src, size_t b, size_t n, float inv_scale, float* out) {
  for (size_t i = b; i < n; ++i)
    out[i] = std::clamp(static_cast<float>(src[i]) * inv_scale, 0.0f, 1.0f);
}

#ifdef PROCAM_SDK_X86
// 16 pixels per step: the same float product, clamped by max / min (the
// product is finite and never NaN, so this equals std::clamp).
__attribute__((target("avx512f,avx512bw,avx512vl"))) void intensity_u8_avx512(
    const uint8_t* src, size_t n, float inv_scale, float* out) {
  const __m512 s = _mm512_set1_ps(inv_scale), zero = _mm512_setzero_ps(), one = _mm512_set1_ps(1.0f);
  size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    const __m512 v = _mm512_cvtepi32_ps(
        _mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(src + i))));
    _mm512_storeu_ps(out + i, _mm512_min_ps(_mm512_max_ps(_mm512_mul_ps(v, s), zero), one));
  }
  intensity_u8_scalar(src, i, n, inv_scale, out);
}
#endif
}  // namespace

void intensity_u8(const uint8_t* src, size_t n, float inv_scale, float* out) {
#ifdef PROCAM_SDK_X86
  if (avx512_active()) return intensity_u8_avx512(src, n, inv_scale, out);
#endif
  intensity_u8_scalar(src, 0, n, inv_scale, out);
}

namespace {
// |margin| of one pixel, saturated to 0..255: |L - R| for a real inverse,
// |2L - W - B| for a synthesized one (B may be absent).
inline uint8_t abs_margin_u8(const uint8_t* L, const uint8_t* R, const uint8_t* B, bool synthetic,
                             size_t i) {
  const int32_t d = synthetic ? 2 * int32_t{L[i]} - int32_t{R[i]} - (B != nullptr ? int32_t{B[i]} : 0)
                              : int32_t{L[i]} - int32_t{R[i]};
  const int32_t a0 = d < 0 ? -d : d;
  return static_cast<uint8_t>(a0 > 255 ? 255 : a0);
}

// Sorted insertion of margin v (plane q) into pixel i's kTrackedPlanes + 1
// smallest, branch-free (selects on the old values) so the vectoriser turns
// it into min/max/blend; a NaN v compares false everywhere and changes nothing.
template <class T>
inline void track_insert(const TrackRow<T>& t, size_t i, T v, uint8_t q) {
  static_assert(kTrackedPlanes == 3, "the insertion below is unrolled for 3 planes");
  const T m0 = t.m[0][i], m1 = t.m[1][i], m2 = t.m[2][i], m3 = t.m[3][i];
  const uint8_t p0 = t.p[0][i], p1 = t.p[1][i], p2 = t.p[2][i];
  const bool l0 = v < m0, l1 = v < m1, l2 = v < m2;
  const T h0 = v > m0 ? v : m0, h1 = v > m1 ? v : m1, h2 = v > m2 ? v : m2;
  t.m[3][i] = h2 < m3 ? h2 : m3;
  t.m[2][i] = h1 < m2 ? h1 : m2;
  t.m[1][i] = h0 < m1 ? h0 : m1;
  t.m[0][i] = l0 ? v : m0;
  t.p[2][i] = l2 ? (l1 ? p1 : q) : p2;
  t.p[1][i] = l1 ? (l0 ? p0 : q) : p1;
  t.p[0][i] = l0 ? q : p0;
}

// The update for one row once the margins `a` are known: track_insert with
// the row's pointers as restrict parameters, so the loop vectorises (through
// the struct, or restrict locals, GCC must assume they alias: 8x slower).
void track_row_ptrs(const uint8_t* __restrict a, size_t n, uint8_t q, uint8_t* __restrict m0p,
                    uint8_t* __restrict m1p, uint8_t* __restrict m2p, uint8_t* __restrict m3p,
                    uint8_t* __restrict p0p, uint8_t* __restrict p1p, uint8_t* __restrict p2p) {
  for (size_t i = 0; i < n; ++i) {  // byte masks and min/max only: vectorises
    const uint8_t v = a[i], m0 = m0p[i], m1 = m1p[i], m2 = m2p[i], m3 = m3p[i];
    const uint8_t p0 = p0p[i], p1 = p1p[i], p2 = p2p[i];
    const auto k0 = static_cast<uint8_t>(v < m0 ? 0xFF : 0), k1 = static_cast<uint8_t>(v < m1 ? 0xFF : 0),
               k2 = static_cast<uint8_t>(v < m2 ? 0xFF : 0);
    const uint8_t h0 = v > m0 ? v : m0, h1 = v > m1 ? v : m1, h2 = v > m2 ? v : m2;
    m3p[i] = h2 < m3 ? h2 : m3;
    m2p[i] = h1 < m2 ? h1 : m2;
    m1p[i] = h0 < m1 ? h0 : m1;
    m0p[i] = v < m0 ? v : m0;
    const auto t1 = static_cast<uint8_t>((k0 & p0) | (~k0 & q));  // plane that moves to slot 1
    const auto t2 = static_cast<uint8_t>((k1 & p1) | (~k1 & q));  // to slot 2
    p2p[i] = static_cast<uint8_t>((k2 & t2) | (~k2 & p2));
    p1p[i] = static_cast<uint8_t>((k1 & t1) | (~k1 & p1));
    p0p[i] = static_cast<uint8_t>((k0 & q) | (~k0 & p0));
  }
}
inline void track_row(const uint8_t* a, size_t n, uint8_t q, const TrackRow<uint8_t>& t) {
  track_row_ptrs(a, n, q, t.m[0], t.m[1], t.m[2], t.m[3], t.p[0], t.p[1], t.p[2]);
}
}  // namespace

void track_u8(const uint8_t* __restrict L, const uint8_t* __restrict R, const uint8_t* __restrict B,
              bool synthetic, size_t n, uint8_t plane, bool first, const TrackRow<uint8_t>& t) {
  if (first) {
    for (size_t i = 0; i < n; ++i) t.m[0][i] = abs_margin_u8(L, R, B, synthetic, i);
    for (int j = 1; j <= kTrackedPlanes; ++j) std::memset(t.m[j], 255, n);
    for (int j = 0; j < kTrackedPlanes; ++j) std::memset(t.p[j], plane, n);
    return;
  }
  // Margins of a chunk first (u8 |L - R| is max - min: no widening), then the
  // update; both loops vectorise. 256 bytes stay in L1.
  constexpr size_t kChunk = 256;
  uint8_t a[kChunk];
  for (size_t x0 = 0; x0 < n; x0 += kChunk) {
    const size_t m = std::min(kChunk, n - x0);
    if (!synthetic) {
      const uint8_t* l = L + x0;
      const uint8_t* r = R + x0;
      for (size_t i = 0; i < m; ++i) {
        const uint8_t hi = l[i] > r[i] ? l[i] : r[i], lo = l[i] > r[i] ? r[i] : l[i];
        a[i] = static_cast<uint8_t>(hi - lo);
      }
    } else {
      for (size_t i = 0; i < m; ++i) a[i] = abs_margin_u8(L, R, B, true, x0 + i);
    }
    TrackRow<uint8_t> c = t;
    for (auto*& p : c.m) p += x0;
    for (auto*& p : c.p) p += x0;
    track_row(a, m, plane, c);
  }
}

void track_f(const float* __restrict L, const float* __restrict L_bar, size_t n, uint8_t plane,
             bool first, const TrackRow<float>& t) {
  const float inf = std::numeric_limits<float>::infinity();
  for (size_t i = 0; i < n; ++i) {
    const float a = std::fabs(L[i] - L_bar[i]);  // NaN: every comparison false, nothing lowered
    if (first) {
      t.m[0][i] = a == a ? a : inf;
      for (int j = 1; j <= kTrackedPlanes; ++j) t.m[j][i] = inf;
      for (int j = 0; j < kTrackedPlanes; ++j) t.p[j][i] = plane;
      continue;
    }
    track_insert<float>(t, i, a, plane);
  }
}

void synthesize_inverse(const float* L, const float* white, const float* black, size_t n,
                        float* L_bar) {
  for (size_t i = 0; i < n; ++i) L_bar[i] = white[i] + (black != nullptr ? black[i] : 0.0f) - L[i];
}

}  // namespace procam::sl
