// SPDX-License-Identifier: MIT
// One-pass end of a striping scan on packed stacks (see striping_pass.hpp).
#include "striping_pass.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "media_model.hpp"
#include "procam/sdk/parallel.hpp"
#include "procam/sdk/simd.hpp"

namespace procam::polarized_striping {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// Thresholds and constants of one pass, shared by both kernels.
struct Consts {
  int32_t d_b = 1, d_w = 1;      // K - 2 of the best / worst stack
  float fd_b = 1, fd_w = 1;
  int32_t sat_top = 0;           // top value >= this: clipped (ceil(saturation))
  int32_t sat_n = 0;             // N >= this: background clipped (ceil(saturation D_b))
  int32_t rise_thr = 0;          // L > this: rises by the margin (floor(margin D_b))
  int32_t tie_thr = 0;           // t1 - t2 > this: beats top2 by the margin (floor(margin))
  float mu = 3, z = 1, p = 1, omp = 1;  // omp = 1 - p (p = 0 when not separated)
  // Reciprocals of the divisors that are the same for every pixel: a
  // multiply instead of a division (the divider's throughput bounds the AVX2
  // kernel). The backgrounds and rise keep their exact integer quotients
  // (B^ = (bg_w - bg_b) / p amplifies an ulp of them by 1 / p).
  float inv_p = 1, inv_z = 1;
  bool step = false, polarised = false, separate = false;
};

// max/min with _mm256_max_ps / _mm256_min_ps semantics (a > b ? a : b), so
// that both kernels agree bit for bit (signed zeros included).
inline float maxf(float a, float b) { return a > b ? a : b; }
inline float minf(float a, float b) { return a < b ? a : b; }

int32_t clamp_i32(double v) {
  return static_cast<int32_t>(std::clamp(v, -2147483000.0, 2147483000.0));
}

Consts make_consts(const PackedView& best, const PackedView* worst, const PassSettings& s) {
  Consts c;
  c.d_b = int32_t(best.frames) - 2;
  c.fd_b = float(c.d_b);
  c.d_w = worst ? int32_t(worst->frames) - 2 : 1;
  c.fd_w = float(c.d_w);
  c.sat_top = clamp_i32(std::ceil(s.saturation));
  c.sat_n = clamp_i32(std::ceil(s.saturation * c.d_b));
  c.rise_thr = clamp_i32(std::floor(s.margin * c.d_b));
  c.tie_thr = clamp_i32(std::floor(s.margin));
  c.mu = float(s.mu);
  c.z = float(s.z);
  c.step = !(s.z > 0);
  c.polarised = worst != nullptr;
  c.separate = c.polarised && s.separate;
  const double p = c.polarised && s.separate ? s.p : 0.0;
  c.p = float(p);
  c.omp = float(1.0 - p);
  c.inv_p = c.separate && p > 0 ? float(1.0 / p) : 1.0f;
  c.inv_z = c.step ? 1.0f : float(1.0 / s.z);
  return c;
}

// exp(x) for x <= 88 (Cephes expf: range reduction by ln 2 in two parts, a
// degree-6 polynomial; < 2 ulp). Plain mul/add in this order, mirrored by
// the AVX2 kernel.
inline float exp_poly(float x) {
  x = maxf(x, -87.0f);
  const float n = std::floor(x * 1.44269504088896341f + 0.5f);
  x = x - n * 0.693359375f;
  x = x - n * -2.12194440e-4f;
  float y = 1.9875691500e-4f;
  y = y * x + 1.3981999507e-3f;
  y = y * x + 8.3334519073e-3f;
  y = y * x + 4.1665795894e-2f;
  y = y * x + 1.6666665459e-1f;
  y = y * x + 5.0000001201e-1f;
  y = y * (x * x) + x + 1.0f;
  const int32_t e = (int32_t(n) + 127) << 23;
  return y * std::bit_cast<float>(e);
}

// Eq. 5.10: W = 1 / (1 + exp(-(S - mu) / z)); 1 above t = 40, 0 where exp
// would overflow float (t < -88; the double reference rounds that to 0 too).
inline float weight_of(float s, const Consts& c) {
  if (c.step) return s > c.mu ? 1.0f : (s < c.mu ? 0.0f : 0.5f);
  const float t = (s - c.mu) * c.inv_z;
  if (t > 40.0f) return 1.0f;
  if (-t > 88.0f) return 0.0f;
  return 1.0f / (1.0f + exp_poly(-t));
}

// The scalar twin: noinline so that it is never contracted into FMAs inside
// the AVX2 kernel's caller (bit-identical maps on both paths).
__attribute__((noinline)) size_t pass_scalar(const PackedView& best, const PackedView* worst, const Consts& c,
                                             const float* centre, const PassMaps& m, size_t i0, size_t i1,
                                             QualitySums& q) {
  size_t valid = 0;
  int64_t img = 0, img2 = 0;
  for (size_t i = i0; i < i1; ++i) {
    const int32_t k1 = best.key1[i], k2 = best.key2[i];
    const int32_t t1 = k1 >> 8, t2 = k2 >> 8, i1x = 255 - (k1 & 255), i2x = 255 - (k2 & 255);
    const int32_t n = int32_t(best.sum[i]) - t1 - t2;
    const int32_t l1 = c.d_b * t1 - n, l2 = c.d_b * t2 - n;
    const float bg = float(n) / c.fd_b;
    const float rise = maxf(float(l1) / c.fd_b, 0.0f);
    const int32_t di = i1x - i2x;
    const bool edge = (di == 1 || di == -1) && l2 > c.rise_thr;
    const bool dec = t2 < c.sat_top && n < c.sat_n && l1 > c.rise_thr && (edge || t1 - t2 > c.tie_thr);
    const float frac_e = float(l2) / float(l1 + l2);
    const float stripe_v = edge ? float(i1x) + float(i2x - i1x) * frac_e : float(i1x);
    bool ok = t2 < c.sat_top;
    float b, s = kNaNf, d = kNaNf, a = kNaNf;
    if (c.polarised) {
      const int32_t w1 = worst->key1[i] >> 8, w2 = worst->key2[i] >> 8;
      const float bw = float(int32_t(worst->sum[i]) - w1 - w2) / c.fd_w;
      ok = ok && w2 < c.sat_top;
      float sig = 0.0f, bsc = bg + bw;
      if (c.separate) {  // Eq. 5.6 on the backgrounds (signal_from_polarized)
        const float total = maxf(bg + bw, 0.0f);
        bsc = minf(maxf((bw - bg) * c.inv_p, 0.0f), total);
        sig = total - bsc;
      }
      b = ok ? bsc : kNaNf;
      if (dec && ok) {
        d = 2.0f * rise;
        a = sig;
        s = d + a;
      }
    } else {
      b = ok ? bg : kNaNf;
      if (dec && ok) d = s = rise;
    }
    const bool stripe = dec && ok;
    img += t1, img2 += int64_t(t1) * t1;
    if (m.image) m.image[i] = float(t1);
    if (m.image_u8) m.image_u8[i] = static_cast<uint8_t>(t1);
    m.enhanced[i] = s;
    m.backscatter[i] = b;
    if (!stripe) {
      m.stripe[i] = kNaNf;
      for (float* p : {m.col, m.cqm, m.weight, m.gqm})
        if (p) p[i] = kNaNf;
      continue;
    }
    ++valid;
    m.stripe[i] = stripe_v;
    if (m.col) {
      // Index clamped to the 257-entry table (NaN -> 0, as cvttps gives INT_MIN).
      const int32_t k0 = stripe_v >= 0.0f && stripe_v < 256.0f ? int32_t(stripe_v) : (stripe_v >= 256.0f ? 255 : 0);
      const float f = stripe_v - float(k0);
      m.col[i] = centre[k0] + f * (centre[k0 + 1] - centre[k0]);
    }
    if (!m.quality && !m.cqm && !m.weight && !m.gqm) continue;
    const float w = weight_of(s, c);
    const float bp = b * c.omp;
    const float den_c = s + bp;  // Eq. 5.8
    const float cq = den_c > 0.0f ? minf(maxf(s / den_c, 0.0f), 1.0f) : 0.0f;
    if (m.weight) m.weight[i] = w;
    if (m.cqm) m.cqm[i] = cq;
    if (m.quality) {
      q.enh += double(s), q.enh2 += double(s) * double(s);
      q.w += double(w), q.cqm += double(cq), q.cqm_w += double(cq) * double(w);
    }
    if (c.polarised) {
      const float den_g = d + a + bp;  // Eq. 5.9
      const float g = den_g > 0.0f ? minf(maxf((d + bp) / den_g, 0.0f), 1.0f) : 0.0f;
      if (m.gqm) m.gqm[i] = g;
      if (m.quality) q.gqm += double(g), q.gqm_w += double(g) * double(w);
    }
  }
  q.img += double(img), q.img2 += double(img2);
  return valid;
}

#ifdef PROCAM_SDK_X86
// The AVX2 kernel: pass_scalar's operations, 8 pixels at a time; [i0, i1) a
// multiple of 8; kStream: every map 16-byte aligned at i0 (non-temporal stores).
#define PROCAM_A2 __attribute__((target("avx2"), always_inline)) inline
PROCAM_A2 __m256i load8(const uint16_t* p) {
  return _mm256_cvtepu16_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}
// n / d, correctly rounded (the bits of _mm256_div_ps), for integer n with
// |n| <= 2^17 and d an integer in [1, 254] (the divisors K - 2 of a packed
// scan), inv = RN(1/d): q = RN(n inv) is within an ulp of n/d, and one FMA
// step q + RN(n - q d) inv (n - q d exact by the FMA) rounds to n/d
// (Markstein's theorem). The divider's throughput bound the pass; these are
// three pipelined multiply-adds. exact_quotients_mismatches() checks every
// (n, d) of that range against the division (striping_pass_test).
__attribute__((target("avx2,fma"), always_inline)) inline __m256 div_int_exact(__m256 n, __m256 d, __m256 inv) {
  const __m256 q = _mm256_mul_ps(n, inv);
  return _mm256_fmadd_ps(_mm256_fnmadd_ps(q, d, n), inv, q);
}
template <bool kStream>
PROCAM_A2 void store8(float* p, __m256 v) {
  if constexpr (kStream) {  // two 16-byte halves: maps are 16-byte aligned (malloc), not always 32
    _mm_stream_ps(p, _mm256_castps256_ps128(v));
    _mm_stream_ps(p + 4, _mm256_extractf128_ps(v, 1));
  }
  else _mm256_storeu_ps(p, v);
}
// The 8 values (0..255 in 32-bit lanes) as bytes; non-temporal: one 8-byte movnti.
template <bool kStream>
PROCAM_A2 void store8_u8(uint8_t* p, __m256i v) {
  const __m128i w16 = _mm_packus_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  const __m128i b8 = _mm_packus_epi16(w16, w16);
  if constexpr (kStream) _mm_stream_si64(reinterpret_cast<long long*>(p), _mm_cvtsi128_si64(b8));
  else _mm_storel_epi64(reinterpret_cast<__m128i*>(p), b8);
}
// Adds the 8 floats (zero where not selected) to a 4-lane double accumulator.
PROCAM_A2 __m256d add8(__m256d acc, __m256 v) {
  return _mm256_add_pd(_mm256_add_pd(acc, _mm256_cvtps_pd(_mm256_castps256_ps128(v))),
                       _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1)));
}
PROCAM_A2 __m256d add8_prod(__m256d acc, __m256 u, __m256 v) {
  const __m256d ul = _mm256_cvtps_pd(_mm256_castps256_ps128(u)), uh = _mm256_cvtps_pd(_mm256_extractf128_ps(u, 1));
  const __m256d vl = _mm256_cvtps_pd(_mm256_castps256_ps128(v)), vh = _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1));
  return _mm256_add_pd(_mm256_add_pd(acc, _mm256_mul_pd(ul, vl)), _mm256_mul_pd(uh, vh));
}
PROCAM_A2 double hsum(__m256d v) {
  alignas(32) double t[4];
  _mm256_store_pd(t, v);
  return (t[0] + t[1]) + (t[2] + t[3]);
}
PROCAM_A2 __m256 clamp01(__m256 v) {
  return _mm256_min_ps(_mm256_max_ps(v, _mm256_setzero_ps()), _mm256_set1_ps(1.0f));
}
PROCAM_A2 __m256 exp8(__m256 x) {  // exp_poly, lane by lane
  x = _mm256_max_ps(x, _mm256_set1_ps(-87.0f));
  const __m256 n = _mm256_floor_ps(
      _mm256_add_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504088896341f)), _mm256_set1_ps(0.5f)));
  x = _mm256_sub_ps(x, _mm256_mul_ps(n, _mm256_set1_ps(0.693359375f)));
  x = _mm256_sub_ps(x, _mm256_mul_ps(n, _mm256_set1_ps(-2.12194440e-4f)));
  __m256 y = _mm256_set1_ps(1.9875691500e-4f);
  y = _mm256_add_ps(_mm256_mul_ps(y, x), _mm256_set1_ps(1.3981999507e-3f));
  y = _mm256_add_ps(_mm256_mul_ps(y, x), _mm256_set1_ps(8.3334519073e-3f));
  y = _mm256_add_ps(_mm256_mul_ps(y, x), _mm256_set1_ps(4.1665795894e-2f));
  y = _mm256_add_ps(_mm256_mul_ps(y, x), _mm256_set1_ps(1.6666665459e-1f));
  y = _mm256_add_ps(_mm256_mul_ps(y, x), _mm256_set1_ps(5.0000001201e-1f));
  y = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(y, _mm256_mul_ps(x, x)), x), _mm256_set1_ps(1.0f));
  const __m256i e = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvttps_epi32(n), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(y, _mm256_castsi256_ps(e));
}
PROCAM_A2 __m256 weight8(__m256 s, const Consts& c) {  // weight_of, lane by lane
  const __m256 mu = _mm256_set1_ps(c.mu), one = _mm256_set1_ps(1.0f);
  if (c.step) {
    const __m256 half = _mm256_blendv_ps(_mm256_set1_ps(0.5f), _mm256_setzero_ps(), _mm256_cmp_ps(s, mu, _CMP_LT_OQ));
    return _mm256_blendv_ps(half, one, _mm256_cmp_ps(s, mu, _CMP_GT_OQ));
  }
  const __m256 t = _mm256_mul_ps(_mm256_sub_ps(s, mu), _mm256_set1_ps(c.inv_z));
  const __m256 x = _mm256_sub_ps(_mm256_setzero_ps(), t);
  __m256 w = _mm256_div_ps(one, _mm256_add_ps(one, exp8(x)));
  w = _mm256_blendv_ps(w, _mm256_setzero_ps(), _mm256_cmp_ps(x, _mm256_set1_ps(88.0f), _CMP_GT_OQ));
  return _mm256_blendv_ps(w, one, _mm256_cmp_ps(t, _mm256_set1_ps(40.0f), _CMP_GT_OQ));
}

// kQuality: compute Eq. 5.8-5.10 (the report's sums and the quality maps);
// false only when neither is wanted (PassMaps::quality off, no quality map).
template <bool kStream, bool kQuality>
__attribute__((target("avx2,fma"))) size_t pass_avx2(const PackedView& best, const PackedView* worst, const Consts& c,
                                                  const float* centre, const PassMaps& m, size_t i0, size_t i1,
                                                  QualitySums& q) {
  const __m256i c255 = _mm256_set1_epi32(255), one_i = _mm256_set1_epi32(1), m_one = _mm256_set1_epi32(-1);
  const __m256i d_b = _mm256_set1_epi32(c.d_b), sat_top = _mm256_set1_epi32(c.sat_top);
  const __m256i sat_n = _mm256_set1_epi32(c.sat_n), rise_thr = _mm256_set1_epi32(c.rise_thr);
  const __m256i tie_thr = _mm256_set1_epi32(c.tie_thr);
  const __m256 fd_b = _mm256_set1_ps(c.fd_b), fd_w = _mm256_set1_ps(c.fd_w), zero = _mm256_setzero_ps();
  const __m256 nan = _mm256_set1_ps(kNaNf), two = _mm256_set1_ps(2.0f), omp = _mm256_set1_ps(c.omp);
  const __m256 inv_p = _mm256_set1_ps(c.inv_p);
  const __m256 inv_db = _mm256_set1_ps(1.0f / c.fd_b), inv_dw = _mm256_set1_ps(1.0f / c.fd_w);
  __m256d s_enh = _mm256_setzero_pd(), s_enh2 = s_enh, s_w = s_enh, s_cqm = s_enh, s_cqm_w = s_enh;
  __m256d s_gqm = s_enh, s_gqm_w = s_enh;
  __m256i s_img = _mm256_setzero_si256(), s_img2 = s_img;  // per lane: <= 255 resp. 65025 per pixel, flushed per call
  size_t valid = 0;
  int64_t img = 0, img2 = 0;
  size_t since_flush = 0;
  for (size_t i = i0; i < i1; i += 8) {
    const __m256i k1 = load8(best.key1 + i), k2 = load8(best.key2 + i), sm = load8(best.sum + i);
    const __m256i t1 = _mm256_srli_epi32(k1, 8), t2 = _mm256_srli_epi32(k2, 8);
    const __m256i i1x = _mm256_sub_epi32(c255, _mm256_and_si256(k1, c255));
    const __m256i i2x = _mm256_sub_epi32(c255, _mm256_and_si256(k2, c255));
    const __m256i n = _mm256_sub_epi32(_mm256_sub_epi32(sm, t1), t2);
    const __m256i l1 = _mm256_sub_epi32(_mm256_mullo_epi32(d_b, t1), n);
    const __m256i l2 = _mm256_sub_epi32(_mm256_mullo_epi32(d_b, t2), n);
    const __m256 bg = div_int_exact(_mm256_cvtepi32_ps(n), fd_b, inv_db);
    const __m256i di = _mm256_sub_epi32(i1x, i2x);
    const __m256i adj = _mm256_or_si256(_mm256_cmpeq_epi32(di, one_i), _mm256_cmpeq_epi32(di, m_one));
    const __m256i edge = _mm256_and_si256(adj, _mm256_cmpgt_epi32(l2, rise_thr));
    __m256i ok = _mm256_cmpgt_epi32(sat_top, t2);
    __m256i dec = _mm256_and_si256(_mm256_and_si256(ok, _mm256_cmpgt_epi32(sat_n, n)), _mm256_cmpgt_epi32(l1, rise_thr));
    dec = _mm256_and_si256(dec, _mm256_or_si256(edge, _mm256_cmpgt_epi32(_mm256_sub_epi32(t1, t2), tie_thr)));
    __m256 b, a = nan;
    if (c.polarised) {
      const __m256i w1 = _mm256_srli_epi32(load8(worst->key1 + i), 8), w2 = _mm256_srli_epi32(load8(worst->key2 + i), 8);
      const __m256i nw = _mm256_sub_epi32(_mm256_sub_epi32(load8(worst->sum + i), w1), w2);
      const __m256 bw = div_int_exact(_mm256_cvtepi32_ps(nw), fd_w, inv_dw);
      ok = _mm256_and_si256(ok, _mm256_cmpgt_epi32(sat_top, w2));
      __m256 sig = zero, bsc = _mm256_add_ps(bg, bw);
      if (c.separate) {
        const __m256 total = _mm256_max_ps(_mm256_add_ps(bg, bw), zero);
        bsc = _mm256_min_ps(_mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(bw, bg), inv_p), zero), total);
        sig = _mm256_sub_ps(total, bsc);
      }
      b = _mm256_blendv_ps(nan, bsc, _mm256_castsi256_ps(ok));
      a = sig;
    } else {
      b = _mm256_blendv_ps(nan, bg, _mm256_castsi256_ps(ok));
    }
    const __m256i sel_i = _mm256_and_si256(dec, ok);
    const __m256 sel = _mm256_castsi256_ps(sel_i);
    const __m256i img_v = t1;
    s_img = _mm256_add_epi32(s_img, img_v);
    s_img2 = _mm256_add_epi32(s_img2, _mm256_mullo_epi32(img_v, img_v));
    if (++since_flush == 4096) {  // 4096 x 65025 < 2^31 per lane
      alignas(32) int32_t t[8], u[8];
      _mm256_store_si256(reinterpret_cast<__m256i*>(t), s_img);
      _mm256_store_si256(reinterpret_cast<__m256i*>(u), s_img2);
      for (int j = 0; j < 8; ++j) img += t[j], img2 += u[j];
      s_img = s_img2 = _mm256_setzero_si256();
      since_flush = 0;
    }
    if (m.image_u8) store8_u8<kStream>(m.image_u8 + i, t1);
    else store8<kStream>(m.image + i, _mm256_cvtepi32_ps(t1));
    store8<kStream>(m.backscatter + i, b);
    const int sel_bits = _mm256_movemask_ps(sel);
    if (sel_bits == 0) {
      // No valid stripe in these 8 pixels (gaps between sheets, medium only,
      // clipped): every other map is NaN, and the report's sums would add
      // zeros. Skipping their arithmetic (rise, stripe, Eq. 5.8-5.10) keeps
      // every bit and makes the pass's work follow the lit pixels.
      store8<kStream>(m.enhanced + i, nan);
      store8<kStream>(m.stripe + i, nan);
      for (float* p : {m.col, m.weight, m.cqm, m.gqm})
        if (p) store8<kStream>(p + i, nan);
      continue;
    }
    const __m256 rise = _mm256_max_ps(div_int_exact(_mm256_cvtepi32_ps(l1), fd_b, inv_db), zero);
    const __m256 fi1 = _mm256_cvtepi32_ps(i1x);
    __m256 stripe_v = fi1;
    if (_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_and_si256(edge, sel_i))) != 0) {  // a valid pixel on a stripe edge
      const __m256 frac_e = _mm256_div_ps(_mm256_cvtepi32_ps(l2), _mm256_cvtepi32_ps(_mm256_add_epi32(l1, l2)));
      const __m256 stripe_e = _mm256_add_ps(fi1, _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_sub_epi32(i2x, i1x)), frac_e));
      stripe_v = _mm256_blendv_ps(fi1, stripe_e, _mm256_castsi256_ps(edge));
    }
    __m256 s, d;
    if (c.polarised) {
      d = _mm256_mul_ps(two, rise);
      s = _mm256_add_ps(d, a);
    } else {
      d = s = rise;
    }
    store8<kStream>(m.enhanced + i, _mm256_blendv_ps(nan, s, sel));
    store8<kStream>(m.stripe + i, _mm256_blendv_ps(nan, stripe_v, sel));
    if (m.col) {
      const __m256i k0 = _mm256_min_epi32(
          _mm256_max_epi32(_mm256_and_si256(_mm256_cvttps_epi32(stripe_v), sel_i), _mm256_setzero_si256()), c255);
      const __m256 c0 = _mm256_i32gather_ps(centre, k0, 4), c1 = _mm256_i32gather_ps(centre, _mm256_add_epi32(k0, one_i), 4);
      const __m256 col = _mm256_add_ps(c0, _mm256_mul_ps(_mm256_sub_ps(stripe_v, _mm256_cvtepi32_ps(k0)), _mm256_sub_ps(c1, c0)));
      store8<kStream>(m.col + i, _mm256_blendv_ps(nan, col, sel));
    }
    valid += size_t(__builtin_popcount(unsigned(sel_bits)));
    if constexpr (!kQuality) continue;
    const __m256 w = weight8(s, c);
    const __m256 bp = _mm256_mul_ps(b, omp);
    const __m256 den_c = _mm256_add_ps(s, bp);
    const __m256 cq = _mm256_and_ps(clamp01(_mm256_div_ps(s, den_c)), _mm256_cmp_ps(den_c, zero, _CMP_GT_OQ));
    if (m.weight) store8<kStream>(m.weight + i, _mm256_blendv_ps(nan, w, sel));
    if (m.cqm) store8<kStream>(m.cqm + i, _mm256_blendv_ps(nan, cq, sel));
    const __m256 s0 = _mm256_and_ps(s, sel), w0 = _mm256_and_ps(w, sel), cq0 = _mm256_and_ps(cq, sel);
    s_enh = add8(s_enh, s0), s_enh2 = add8_prod(s_enh2, s0, s0);
    s_w = add8(s_w, w0), s_cqm = add8(s_cqm, cq0), s_cqm_w = add8_prod(s_cqm_w, cq0, w0);
    if (c.polarised) {
      const __m256 den_g = _mm256_add_ps(_mm256_add_ps(d, a), bp);
      const __m256 g = _mm256_and_ps(clamp01(_mm256_div_ps(_mm256_add_ps(d, bp), den_g)),
                                     _mm256_cmp_ps(den_g, zero, _CMP_GT_OQ));
      if (m.gqm) store8<kStream>(m.gqm + i, _mm256_blendv_ps(nan, g, sel));
      const __m256 g0 = _mm256_and_ps(g, sel);
      s_gqm = add8(s_gqm, g0), s_gqm_w = add8_prod(s_gqm_w, g0, w0);
    }
  }
  if constexpr (kStream) _mm_sfence();  // streamed stores visible before the band is reported done
  alignas(32) int32_t t[8], u[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(t), s_img);
  _mm256_store_si256(reinterpret_cast<__m256i*>(u), s_img2);
  for (int j = 0; j < 8; ++j) img += t[j], img2 += u[j];
  q.img += double(img), q.img2 += double(img2);
  if (m.quality) {
    q.enh += hsum(s_enh), q.enh2 += hsum(s_enh2), q.w += hsum(s_w), q.cqm += hsum(s_cqm), q.cqm_w += hsum(s_cqm_w);
    q.gqm += hsum(s_gqm), q.gqm_w += hsum(s_gqm_w);
  }
  return valid;
}
#undef PROCAM_A2
#endif

}  // namespace

namespace {
bool cpu_has_fma() noexcept {
#ifdef PROCAM_SDK_X86
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("fma") != 0;
  }();
  return has;
#else
  return false;
#endif
}
}  // namespace

#ifdef PROCAM_SDK_X86
namespace {
__attribute__((target("avx2,fma"))) size_t quotient_mismatches_avx2(int32_t d) {
  size_t bad = 0;
  const float fd = float(d);
  const __m256 dv = _mm256_set1_ps(fd), inv = _mm256_set1_ps(1.0f / fd);
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  alignas(32) float got[8];
  for (int32_t n = -(1 << 17); n <= (1 << 17); n += 8) {
    _mm256_store_ps(got, div_int_exact(_mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(n), lanes)), dv, inv));
    for (int32_t j = 0; j < 8; ++j) {
      const float want = float(n + j) / fd;
      bad += std::memcmp(&got[j], &want, sizeof(float)) != 0;
    }
  }
  return bad;
}
}  // namespace
#endif

size_t exact_quotients_mismatches(int32_t d) {
#ifdef PROCAM_SDK_X86
  if (pass_kernel_available(PassKernel::avx2)) return quotient_mismatches_avx2(d);
#endif
  (void)d;
  return 0;
}

bool pass_kernel_available(PassKernel kernel) {
#ifdef PROCAM_SDK_X86
  if (kernel == PassKernel::avx2) return sdk::cpu_has_avx2() && cpu_has_fma();
#else
  if (kernel == PassKernel::avx2) return false;
#endif
  return true;
}

namespace {

// One worker's share of the DOP sample: the keys of its finite ratios, a
// histogram of their top 16 bits, and how many pixels passed the sum test
// (NaN ratios included, as estimate_dop counts them).
struct DopPart {
  std::vector<uint32_t> keys;
  std::vector<uint32_t> hist;
  std::vector<uint32_t> picked;  // select_keys: this part's keys in the two chosen buckets
  size_t counted = 0;
};

// Scratch of packed_dop, kept per calling thread (the session's thread) from
// call to call: fresh pages for ~1 MB of keys and 256 KiB histograms fault
// one by one, which cost more than the whole sample on a VM.
struct DopScratch {
  std::vector<DopPart> parts;
  std::vector<uint64_t> hist;
  std::vector<uint32_t> low, low2;
};

// The bucket (top 16 bits) holding rank k of the merged histogram, and the
// number of keys in the buckets below it.
uint32_t bucket_of_rank(const std::vector<uint64_t>& hist, size_t k, size_t& below) {
  uint32_t hi = 0;
  below = 0;
  while (below + hist[hi] <= k) below += hist[hi++];
  return hi;
}
uint32_t low_of_rank(const std::vector<uint32_t>& low, size_t below, size_t k) {
  uint32_t lo = 0;
  while (below + low[lo] <= k) below += low[lo++];
  return lo;
}

// The k-th and (k+1)-th smallest (0-based) keys over all parts (k + 1 <
// total), from the merged histogram `hist` of the top 16 bits: the buckets
// holding ranks k and k + 1, then histograms of the low 16 bits of those
// buckets' keys, both filled in one pass over the keys (a bucket can hold
// most of the sample: the backgrounds of a hazy scene cluster; O(n), no sort).
// The scan over every key picks the two buckets' keys part by part on the
// parts' workers (it was the serial half of the DOP step, issue 13); the
// low-bit histograms are then filled from the picked keys only (a bucket is
// 1/128 of an octave of r: a few per cent of a hazy scene's sample).
void select_keys(std::vector<DopPart>& parts, const std::vector<uint64_t>& hist, size_t k, uint32_t& key_k,
                 uint32_t& key_k1, DopScratch& scratch, uint32_t threads) {
  size_t below_a = 0, below_b = 0;
  const uint32_t hi_a = bucket_of_rank(hist, k, below_a), hi_b = bucket_of_rank(hist, k + 1, below_b);
  sdk::parallel_rows(static_cast<uint32_t>(parts.size()), threads, [&](uint32_t p0, uint32_t p1) {
    for (uint32_t p = p0; p < p1; ++p) {
      DopPart& part = parts[p];
      part.picked.clear();
      part.picked.reserve(hist[hi_a] + (hi_b != hi_a ? hist[hi_b] : 0));
      for (uint32_t key : part.keys) {
        const uint32_t h = key >> 16;
        if (h == hi_a || h == hi_b) part.picked.push_back(key);
      }
    }
  });
  scratch.low.assign(65536, 0);
  if (hi_b != hi_a) scratch.low2.assign(65536, 0);
  for (const DopPart& part : parts)
    for (uint32_t key : part.picked) {
      if ((key >> 16) == hi_a) ++scratch.low[key & 0xffffu];
      else ++scratch.low2[key & 0xffffu];
    }
  key_k = (hi_a << 16) | low_of_rank(scratch.low, below_a, k);
  key_k1 = (hi_b << 16) | (hi_b == hi_a ? low_of_rank(scratch.low, below_a, k + 1)
                                        : low_of_rank(scratch.low2, below_b, k + 1));
}

// One DopPart entry: pixel i's ratio r = (bg_w - bg_b) / (bg_w + bg_b) as
// packed_dop draws it (the scalar rule; dop_keys_avx2 mirrors it).
inline void dop_sample(const PackedView& best, const PackedView& worst, size_t i, int32_t sat, float db, float dw,
                       double min_sum, DopPart& part) {
  const int32_t b2 = best.key2[i] >> 8, w2 = worst.key2[i] >> 8;
  if (b2 >= sat || w2 >= sat) return;  // clipped: no background
  // The backgrounds as the reference pass rounds them (float quotients of
  // integers), then estimate_dop's ratio in double.
  const float bb = float(int32_t(best.sum[i]) - (best.key1[i] >> 8) - b2) / db;
  const float bw = float(int32_t(worst.sum[i]) - (worst.key1[i] >> 8) - w2) / dw;
  const double sum = double(bw) + double(bb);
  if (!(sum > min_sum)) return;
  ++part.counted;
  const auto r = static_cast<float>((double(bw) - double(bb)) / sum);
  if (!std::isfinite(r)) return;  // quantile() drops these
  const uint32_t key = key_from_float(r);
  part.keys.push_back(key);
  ++part.hist[key >> 16];
}

#ifdef PROCAM_SDK_X86
// The DOP ratios r of entries [j, j + 8) (dop_sample's arithmetic: float
// background quotients, then the double sum, difference and quotient rounded
// to float) into `r`; returns the lanes that count (backgrounds unclipped and
// their sum above min_sum). Shared by dop_keys_avx2 and pivot_keys_avx2 so
// both passes make the same keys.
__attribute__((target("avx2"), always_inline)) inline int dop_ratios8(const PackedView& best, const PackedView& worst,
                                                                     size_t j, __m256i satv, __m256 fdb, __m256 fdw,
                                                                     __m256d ms, __m256& r) {
  const __m256i b2 = _mm256_srli_epi32(load8(best.key2 + j), 8), w2 = _mm256_srli_epi32(load8(worst.key2 + j), 8);
  const __m256i ok = _mm256_and_si256(_mm256_cmpgt_epi32(satv, b2), _mm256_cmpgt_epi32(satv, w2));
  const __m256i nb = _mm256_sub_epi32(_mm256_sub_epi32(load8(best.sum + j), _mm256_srli_epi32(load8(best.key1 + j), 8)), b2);
  const __m256i nw = _mm256_sub_epi32(_mm256_sub_epi32(load8(worst.sum + j), _mm256_srli_epi32(load8(worst.key1 + j), 8)), w2);
  const __m256 bb = _mm256_div_ps(_mm256_cvtepi32_ps(nb), fdb), bw = _mm256_div_ps(_mm256_cvtepi32_ps(nw), fdw);
  const __m256d bb_lo = _mm256_cvtps_pd(_mm256_castps256_ps128(bb)), bb_hi = _mm256_cvtps_pd(_mm256_extractf128_ps(bb, 1));
  const __m256d bw_lo = _mm256_cvtps_pd(_mm256_castps256_ps128(bw)), bw_hi = _mm256_cvtps_pd(_mm256_extractf128_ps(bw, 1));
  const __m256d sum_lo = _mm256_add_pd(bw_lo, bb_lo), sum_hi = _mm256_add_pd(bw_hi, bb_hi);
  const int bits = _mm256_movemask_ps(_mm256_castsi256_ps(ok)) &
                   (_mm256_movemask_pd(_mm256_cmp_pd(sum_lo, ms, _CMP_GT_OQ)) |
                    (_mm256_movemask_pd(_mm256_cmp_pd(sum_hi, ms, _CMP_GT_OQ)) << 4));
  if (bits == 0) return 0;
  const __m128 r_lo = _mm256_cvtpd_ps(_mm256_div_pd(_mm256_sub_pd(bw_lo, bb_lo), sum_lo));
  const __m128 r_hi = _mm256_cvtpd_ps(_mm256_div_pd(_mm256_sub_pd(bw_hi, bb_hi), sum_hi));
  r = _mm256_set_m128(r_hi, r_lo);
  return bits;
}
#endif

#ifdef PROCAM_SDK_X86
// dop_sample for the contiguous entries [j0, j1) (stride 1: a stack's
// compact DOP sample), 8 at a time: the same IEEE operations in the same
// order (float quotients, then double sum, difference and quotient rounded
// to float), so the same keys; returns where it stopped (the rest: scalar).
__attribute__((target("avx2"))) size_t dop_keys_avx2(const PackedView& best, const PackedView& worst, size_t j0,
                                                     size_t j1, int32_t sat, float db, float dw, double min_sum,
                                                     DopPart& part) {
  const __m256i satv = _mm256_set1_epi32(sat);
  const __m256 fdb = _mm256_set1_ps(db), fdw = _mm256_set1_ps(dw);
  const __m256d ms = _mm256_set1_pd(min_sum);
  size_t j = j0;
  alignas(32) float r8[8];
  for (; j + 8 <= j1; j += 8) {
    __m256 r;
    const int bits = dop_ratios8(best, worst, j, satv, fdb, fdw, ms, r);
    if (bits == 0) continue;
    _mm256_store_ps(r8, r);
    for (int l = 0; l < 8; ++l) {
      if (!((bits >> l) & 1)) continue;
      ++part.counted;
      if (!std::isfinite(r8[l])) continue;
      const uint32_t key = key_from_float(r8[l]);
      part.keys.push_back(key);
      ++part.hist[key >> 16];
    }
  }
  return j;
}
#endif

// ---- The DOP quantile by pivots (issue 13, fifth round) --------------------
// The radix selection above histograms every key and then re-reads the keys
// of the chosen bucket; in a hazy scene that bucket holds nearly all of them,
// and the histogram's increments of one hot counter form a chain of
// store-to-load dependencies. Here (Floyd and Rivest's select, 1975): the
// keys of a strided subsample of ~kPivotSample entries, sorted, give two
// pivots lo <= hi that bracket the wanted ranks with a margin of 5 standard
// deviations of a subsample quantile's rank plus 8; one parallel pass then
// computes every key in registers and keeps only counts (how many keys are
// below lo), the largest key and the keys in [lo, hi] (a few per cent of
// the sample). When both ranks k, k + 1 fall in that window (below <= k and
// k + 1 < below + in), they are the (k - below)-th and next smallest of the
// window: exact, the same keys as the radix selection. Otherwise (a
// subsample that misjudged the distribution) the caller falls back to the
// radix selection: the result never depends on the pivots, only the time.
constexpr size_t kPivotSample = 2048;

// An order key as a signed integer: a < b as floats (-0 < +0) iff
// order_key(a) < order_key(b); key_from_float(v) = order_key(v) ^ 2^31.
// Its own inverse on the bits.
inline int32_t order_key_bits(uint32_t b) { return int32_t(b ^ (uint32_t(int32_t(b) >> 31) & 0x7fffffffu)); }
inline float float_from_order_key(int32_t k) { return std::bit_cast<float>(uint32_t(order_key_bits(uint32_t(k)))); }

// One worker's share of the pivot pass.
struct PivotPart {
  size_t counted = 0, finite = 0, below = 0, n_in = 0;
  int32_t top = std::numeric_limits<int32_t>::min();  // largest key
  std::vector<int32_t> in;                             // keys in [lo, hi]; sized to the band
};

// Entry i's ratio by dop_sample's rule: 0 not counted (clipped, or the sum
// of the backgrounds not above min_sum), 1 counted but not finite, 2 r set.
inline int dop_ratio(const PackedView& best, const PackedView& worst, size_t i, int32_t sat, float db, float dw,
                     double min_sum, float& r) {
  const int32_t b2 = best.key2[i] >> 8, w2 = worst.key2[i] >> 8;
  if (b2 >= sat || w2 >= sat) return 0;
  const float bb = float(int32_t(best.sum[i]) - (best.key1[i] >> 8) - b2) / db;
  const float bw = float(int32_t(worst.sum[i]) - (worst.key1[i] >> 8) - w2) / dw;
  const double sum = double(bw) + double(bb);
  if (!(sum > min_sum)) return 0;
  r = static_cast<float>((double(bw) - double(bb)) / sum);
  return std::isfinite(r) ? 2 : 1;
}

inline void pivot_take(int32_t key, int32_t lo, int32_t hi, PivotPart& part) {
  ++part.finite;
  part.below += key < lo;
  part.top = std::max(part.top, key);
  if (key >= lo && key <= hi) part.in[part.n_in++] = key;
}

#ifdef PROCAM_SDK_X86
// The pivot pass over contiguous entries [j0, j1) (stride 1), 8 at a time:
// dop_keys_avx2's arithmetic (the same IEEE operations, so the same r),
// then the keys, the counts and the window's keys without storing the rest.
// Returns where it stopped (the rest: scalar).
__attribute__((target("avx2"))) size_t pivot_keys_avx2(const PackedView& best, const PackedView& worst, size_t j0,
                                                       size_t j1, int32_t sat, float db, float dw, double min_sum,
                                                       int32_t lo, int32_t hi, PivotPart& part) {
  const __m256i satv = _mm256_set1_epi32(sat), lov = _mm256_set1_epi32(lo), hiv = _mm256_set1_epi32(hi);
  const __m256i expm = _mm256_set1_epi32(0x7f800000), absm = _mm256_set1_epi32(0x7fffffff);
  const __m256i lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  const __m256i lowest = _mm256_set1_epi32(std::numeric_limits<int32_t>::min());
  const __m256 fdb = _mm256_set1_ps(db), fdw = _mm256_set1_ps(dw);
  const __m256d ms = _mm256_set1_pd(min_sum);
  __m256i top = lowest;
  size_t counted = 0, finite = 0, below = 0, n_in = part.n_in;
  int32_t* in = part.in.data();
  alignas(32) int32_t k8[8];
  size_t j = j0;
  for (; j + 8 <= j1; j += 8) {
    __m256 r;
    const int bits = dop_ratios8(best, worst, j, satv, fdb, fdw, ms, r);
    if (bits == 0) continue;
    counted += size_t(__builtin_popcount(unsigned(bits)));
    const __m256i rb = _mm256_castps_si256(r);
    const int nonfinite = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(rb, expm), expm)));
    const int fbits = bits & ~nonfinite;
    if (fbits == 0) continue;
    finite += size_t(__builtin_popcount(unsigned(fbits)));
    const __m256i key = _mm256_xor_si256(rb, _mm256_and_si256(_mm256_srai_epi32(rb, 31), absm));
    const __m256i fmask = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(fbits), lane_bit), lane_bit);
    top = _mm256_max_epi32(top, _mm256_blendv_epi8(lowest, key, fmask));
    const int lt = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(lov, key))) & fbits;
    below += size_t(__builtin_popcount(unsigned(lt)));
    const int gt = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(key, hiv)));
    const int inb = fbits & ~lt & ~gt;
    if (inb == 0) continue;
    // Branch-free left-pack: ~7 % of the keys fall in the window, so "any
    // of these 8" is a coin toss for the branch predictor. Writes stay
    // inside the band: n_in <= the entries taken before j + l.
    _mm256_store_si256(reinterpret_cast<__m256i*>(k8), key);
    for (int l = 0; l < 8; ++l) {
      in[n_in] = k8[l];
      n_in += size_t((inb >> l) & 1);
    }
  }
  alignas(32) int32_t t8[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(t8), top);
  for (int32_t t : t8) part.top = std::max(part.top, t);
  part.counted += counted, part.finite += finite, part.below += below, part.n_in = n_in;
  return j;
}
#endif

struct PivotScratch {
  std::vector<PivotPart> parts;
  std::vector<int32_t> sub, all;
};

// The quantile by pivots (see above) into `out`; false when the pivots
// missed the ranks or the subsample is too small to place them (then the
// radix selection runs).
bool dop_by_pivots(const PackedView& best, const PackedView& worst, uint32_t samples, size_t stride, int32_t sat,
                   float db, float dw, double min_sum, double percentile, uint32_t threads, size_t min_pixels,
                   double& out) {
  thread_local PivotScratch scratch;
  const size_t step = std::max<size_t>(1, samples / kPivotSample);
  std::vector<int32_t>& sub = scratch.sub;
  sub.clear();
  for (size_t j = 0; j < samples; j += step) {
    float r = 0;
    if (dop_ratio(best, worst, j * stride, sat, db, dw, min_sum, r) == 2) sub.push_back(order_key_bits(std::bit_cast<uint32_t>(r)));
  }
  if (sub.size() < 256) return false;
  std::sort(sub.begin(), sub.end());
  const double pct = std::clamp(percentile, 0.0, 1.0), m = double(sub.size());
  const double centre = pct * (m - 1.0), margin = 5.0 * std::sqrt(m * pct * (1.0 - pct)) + 8.0;
  const double r_lo = std::floor(centre - margin), r_hi = std::ceil(centre + margin) + 1.0;
  const int32_t lo = r_lo < 0.0 ? std::numeric_limits<int32_t>::min() : sub[size_t(r_lo)];
  const int32_t hi = r_hi >= m ? std::numeric_limits<int32_t>::max() : sub[size_t(r_hi)];
  // Chunks taken dynamically, 8 per thread (a preempted worker holds up one
  // chunk, not half the sample); the result does not depend on the split.
  const uint32_t chunks = threads <= 1 ? 1u : std::min<uint32_t>(samples, threads * 8u);
  std::vector<PivotPart>& parts = scratch.parts;
  parts.resize(chunks);
  const auto start = [&](uint32_t b) { return static_cast<uint32_t>(uint64_t{samples} * b / chunks); };
  for (uint32_t b = 0; b < chunks; ++b) {
    PivotPart& part = parts[b];
    const size_t size = start(b + 1) - start(b);
    if (part.in.size() < size) part.in.resize(size);  // kept from call to call: no fresh pages
    part.counted = part.finite = part.below = part.n_in = 0;
    part.top = std::numeric_limits<int32_t>::min();
  }
  procam::parallel_bands(chunks, threads, [&](uint32_t b) {
    PivotPart& part = parts[b];
    const uint32_t j0 = start(b), j1 = start(b + 1);
    size_t j = j0;
#ifdef PROCAM_SDK_X86
    if (stride == 1 && sdk::cpu_has_avx2()) j = pivot_keys_avx2(best, worst, j0, j1, sat, db, dw, min_sum, lo, hi, part);
#endif
    for (; j < j1; ++j) {
      float r = 0;
      const int got = dop_ratio(best, worst, j * stride, sat, db, dw, min_sum, r);
      part.counted += got > 0;
      if (got == 2) pivot_take(order_key_bits(std::bit_cast<uint32_t>(r)), lo, hi, part);
    }
  });
  size_t counted = 0, finite = 0, below = 0, n_in = 0;
  int32_t top = std::numeric_limits<int32_t>::min();
  for (const PivotPart& part : parts)
    counted += part.counted, finite += part.finite, below += part.below, n_in += part.n_in, top = std::max(top, part.top);
  if (counted < min_pixels || finite == 0) {
    out = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  // quantile(): linear interpolation between the k-th and (k+1)-th smallest.
  const double pos = pct * double(finite - 1);
  const auto k = static_cast<size_t>(std::floor(pos));
  int32_t key_lo = top, key_hi = top;
  if (k + 1 < finite) {
    if (!(below <= k && k + 1 < below + n_in)) return false;
    std::vector<int32_t>& all = scratch.all;
    all.clear();
    for (const PivotPart& part : parts) all.insert(all.end(), part.in.begin(), part.in.begin() + std::ptrdiff_t(part.n_in));
    const auto at = all.begin() + std::ptrdiff_t(k - below);
    std::nth_element(all.begin(), at, all.end());
    key_lo = *at;
    key_hi = *std::min_element(at + 1, all.end());
  }
  const double v_lo = double(float_from_order_key(key_lo));
  const double v_hi = k + 1 >= finite ? v_lo : double(float_from_order_key(key_hi));
  out = std::clamp(v_lo + (pos - double(k)) * (v_hi - v_lo), 0.0, 1.0);
  return true;
}

}  // namespace

double packed_dop(const PackedView& best, const PackedView& worst, size_t count, size_t stride, double saturation,
                  double min_sum, double percentile, uint32_t threads, size_t min_pixels, DopSelect select,
                  bool* by_pivots) {
  const auto samples = static_cast<uint32_t>(std::min<size_t>(count, UINT32_MAX));  // <= 2^19 in practice
  const int32_t sat = static_cast<int32_t>(std::min(std::ceil(saturation), 1e9));
  const float db = float(int32_t(best.frames) - 2), dw = float(int32_t(worst.frames) - 2);
  if (by_pivots) *by_pivots = false;
  if (select == DopSelect::best) {
    double v = 0;
    if (dop_by_pivots(best, worst, samples, stride, sat, db, dw, min_sum, percentile, threads, min_pixels, v)) {
      if (by_pivots) *by_pivots = true;
      return v;
    }
  }
  thread_local DopScratch scratch;
  // parallel_rows' bands: min(threads, samples) of them, band b starting at samples * b / bands.
  const uint32_t bands = std::clamp<uint32_t>(threads, 1u, std::max(samples, 1u));
  std::vector<DopPart>& parts = scratch.parts;
  parts.resize(bands);
  for (DopPart& part : parts) part.keys.clear(), part.hist.assign(65536, 0), part.counted = 0;
  sdk::parallel_rows(samples, threads, [&](uint32_t j0, uint32_t j1) {
    uint32_t b = 0;
    while (b + 1 < bands && uint64_t{samples} * (b + 1) / bands <= j0) ++b;
    DopPart& part = parts[b];
    part.keys.reserve(j1 - j0);
    size_t j = j0;
#ifdef PROCAM_SDK_X86
    if (stride == 1 && sdk::cpu_has_avx2()) j = dop_keys_avx2(best, worst, j0, j1, sat, db, dw, min_sum, part);
#endif
    for (size_t i = j * stride; i < size_t{j1} * stride; i += stride) dop_sample(best, worst, i, sat, db, dw, min_sum, part);
  });
  size_t counted = 0, finite = 0;
  std::vector<uint64_t>& hist = scratch.hist;
  hist.assign(65536, 0);
  for (const DopPart& part : parts) {
    counted += part.counted, finite += part.keys.size();
    for (size_t b = 0; b < hist.size(); ++b) hist[b] += part.hist[b];
  }
  if (counted < min_pixels || finite == 0) return std::numeric_limits<double>::quiet_NaN();
  // quantile(): linear interpolation between the lo-th and (lo+1)-th smallest.
  const double pos = std::clamp(percentile, 0.0, 1.0) * double(finite - 1);
  const auto lo = static_cast<size_t>(std::floor(pos));
  uint32_t key_lo = 0, key_hi = 0;
  if (lo + 1 < finite) {
    select_keys(parts, hist, lo, key_lo, key_hi, scratch, threads);
  } else {  // the largest key: the top non-empty bucket's largest low bits
    size_t below = 0;
    const uint32_t hi = bucket_of_rank(hist, lo, below);
    uint32_t low_max = 0;
    for (const DopPart& part : parts)
      for (uint32_t key : part.keys)
        if ((key >> 16) == hi) low_max = std::max(low_max, key & 0xffffu);
    key_lo = key_hi = (hi << 16) | low_max;
  }
  const double v_lo = double(float_from_key(key_lo));
  const double v_hi = lo + 1 >= finite ? v_lo : double(float_from_key(key_hi));
  const double v = v_lo + (pos - double(lo)) * (v_hi - v_lo);
  return std::clamp(v, 0.0, 1.0);
}

size_t striping_pass(const PackedView& best, const PackedView* worst, const PassSettings& s, const PassMaps& m,
                     size_t i0, size_t i1, QualitySums& q, PassKernel kernel) {
  const Consts c = make_consts(best, worst, s);
  const size_t n = i1 > i0 ? i1 - i0 : 0;
  size_t valid = 0;
  q.n_img += n;
  const auto count = [&](size_t v) {
    if (!m.quality) return v;
    q.n_enh += v, q.n_w += v, q.n_cqm += v, q.n_cqm_w += v;
    if (worst) q.n_gqm += v, q.n_gqm_w += v;
    return v;
  };
  if (kernel == PassKernel::best) kernel = pass_kernel_available(PassKernel::avx2) ? PassKernel::avx2 : PassKernel::scalar;
#ifdef PROCAM_SDK_X86
  if (kernel == PassKernel::avx2 && sdk::cpu_has_avx2()) {
    // Head up to a 16-byte boundary of the image map, 8-pixel blocks, tail.
    // Non-temporal stores (the maps are not read again here; ~30 MB written
    // with the core maps, ~74 MB with all of them at 1920x1200,
    // without reading them into the cache first) when every map shares that
    // alignment.
    // (The U8 image's 8-byte movnti needs no alignment.)
    const auto mis = [&](const float* p) { return (reinterpret_cast<uintptr_t>(p + i0) & 15u) / 4u; };
    const size_t head = std::min(n, size_t((4 - mis(m.enhanced)) & 3u));
    bool same = true;
    for (const float* p : {m.image, m.backscatter, m.stripe, m.col, m.cqm, m.weight, m.gqm})
      same = same && (p == nullptr || mis(p) == mis(m.enhanced));
    const size_t body = (n - head) / 8 * 8;
    valid += pass_scalar(best, worst, c, s.centre, m, i0, i0 + head, q);
    const bool qual = m.quality || m.cqm || m.weight || m.gqm;
    const size_t b0 = i0 + head, b1 = i0 + head + body;
    valid += same ? (qual ? pass_avx2<true, true>(best, worst, c, s.centre, m, b0, b1, q)
                          : pass_avx2<true, false>(best, worst, c, s.centre, m, b0, b1, q))
                  : (qual ? pass_avx2<false, true>(best, worst, c, s.centre, m, b0, b1, q)
                          : pass_avx2<false, false>(best, worst, c, s.centre, m, b0, b1, q));
    valid += pass_scalar(best, worst, c, s.centre, m, i0 + head + body, i1, q);
    return count(valid);
  }
#endif
  return count(pass_scalar(best, worst, c, s.centre, m, i0, i1, q));
}

}  // namespace procam::polarized_striping
