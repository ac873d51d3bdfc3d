// SPDX-License-Identifier: MIT
// The AVX2 + FMA row kernel of ColumnTriangulator (triangulate_kernels.hpp),
// compiled per function with __attribute__((target)) and chosen at run time.
#include <immintrin.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <limits>

#include "triangulate_kernels.hpp"

namespace procam::sdk::detail {
namespace {

// AVX2 + FMA: 8 pixels per step, in two tiers.
//
// Fast tier: D = n.d and N = n.t, where all the cancellation happens
// (|D| << |n||d| for grazing rays, N -> 0 near the epipole), are computed in
// double as in row_portable, and so is the parallel test. The division is
// float (8 lanes): s = float(N) / float(D), ~2 ulp. It is refined to ~2^-47
// relative as a float pair s + s_lo, s_lo = (N - s D) / D (residual in
// double, quotient in float), and x = (s + s_lo)(dx + dx_lo), y likewise,
// z = s + s_lo are rounded once from these pairs (avx2_product): the
// correctly rounded floats of the exact values, i.e. the same floats as the
// double kernel's but where a value lies within ~2^-46 of a rounding
// boundary. Validity: "parallel" and "s > 0" are decided as in double (the
// sign of float(N)/float(D) is that of N/D; a non-finite column makes s NaN
// or 0). "In front of the projector" (pz > 0) is decided in float, so a
// block where any lane has |pz| <= 1e-5 (|s Rz| + |r2t|) (the float error
// bound is ~1e-6 of that), or where s could overflow x or y as floats, is
// recomputed by the exact tier.
// Exact tier: every step in double, the same formulas as row_portable (with
// FMA: they agree to ~1e-16 relative, far below the float outputs).

// The exact tier for 4 pixels (doubles): fx, fy, fz as floats, the validity
// decisions that need double as a lane mask.
struct Avx2Consts {
  __m256d a0, b0, at, bt, r20, r2t, fx2, cx, tiny, zero, dmax;
};

__attribute__((target("avx2,fma"), always_inline)) inline __m256d avx2_half(
    const Avx2Consts& K, __m256d c, __m256d dx, __m256d dy, __m256d p, __m256d q, __m256d rz,
    __m256d ddr, __m128& fx, __m128& fy, __m128& fz) {
  const __m256d P = _mm256_fmadd_pd(K.a0, dx, p), Q = _mm256_fmadd_pd(K.b0, dx, q);
  const __m256d D = _mm256_fmadd_pd(c, Q, P), N = _mm256_fmadd_pd(c, K.bt, K.at);
  const __m256d s = _mm256_div_pd(N, D);
  const __m256d pz = _mm256_fmsub_pd(s, _mm256_fmadd_pd(K.r20, dx, rz), K.r2t);
  const __m256d dd = _mm256_fmadd_pd(dx, dx, ddr), cm = _mm256_sub_pd(c, K.cx);
  const __m256d nn = _mm256_fmadd_pd(cm, cm, K.fx2);
  const __m256d lim = _mm256_mul_pd(K.tiny, _mm256_mul_pd(nn, dd));
  __m256d ok = _mm256_cmp_pd(_mm256_mul_pd(D, D), lim, _CMP_GE_OQ);
  ok = _mm256_and_pd(ok, _mm256_cmp_pd(s, K.zero, _CMP_GT_OQ));
  ok = _mm256_and_pd(ok, _mm256_cmp_pd(s, K.dmax, _CMP_LE_OQ));
  ok = _mm256_and_pd(ok, _mm256_cmp_pd(pz, K.zero, _CMP_GT_OQ));
  fx = _mm256_cvtpd_ps(_mm256_mul_pd(s, dx));
  fy = _mm256_cvtpd_ps(_mm256_mul_pd(s, dy));
  fz = _mm256_cvtpd_ps(s);
  return ok;
}

// Everything a step needs besides the pixels, broadcast once per row.
struct Avx2Row {
  Avx2Consts K;
  __m256d dy0, p0, q0, rz0, dd0;          // separable rays: this row's terms
  __m256d a1, a2, b1, b2, r21, r22, one;  // per-pixel rays: the row terms' coefficients
  __m256d e12, cxe12, fx2e24;             // 1e-12 (c - cx_p) and 1e-24 fx_p^2
  __m256 r20f, rz0f, r21f, r22f, r2tf, tol, tol_r2t, dy0f, dy0l;  // float tier
  __m256 smax, abs_mask, fmax, zerof, nan;
};

template <bool kPerPixel>
__attribute__((target("avx2,fma"), always_inline)) inline void avx2_row_terms(
    const Avx2Row& r, __m256d dy, __m256d& p, __m256d& q, __m256d& rz, __m256d& dd) {
  if constexpr (kPerPixel) {
    p = _mm256_fmadd_pd(r.a1, dy, r.a2);
    q = _mm256_fmadd_pd(r.b1, dy, r.b2);
    rz = _mm256_fmadd_pd(r.r21, dy, r.r22);
    dd = _mm256_fmadd_pd(dy, dy, r.one);
  } else {
    p = r.p0, q = r.q0, rz = r.rz0, dd = r.dd0;
  }
}

__attribute__((target("avx2,fma"), always_inline)) inline __m256d avx2_widen(__m256 v, int h) {
  return _mm256_cvtps_pd(h == 0 ? _mm256_castps256_ps128(v) : _mm256_extractf128_ps(v, 1));
}

// Two lane masks of 4 doubles as one of 8 floats (lanes of lo, then of hi):
// the low 32 bits of each double lane, gathered by a shuffle and a permute.
__attribute__((target("avx2,fma"), always_inline)) inline __m256 avx2_narrow_mask(__m256d lo,
                                                                                  __m256d hi) {
  const __m256 m = _mm256_shuffle_ps(_mm256_castpd_ps(lo), _mm256_castpd_ps(hi), 0x88);
  return _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(m), 0xD8));
}

// round((s + s_lo)(d + d_lo)) for float pairs (s_lo, d_lo: the small parts):
// the exact product s d (two_prod: p + its rounding error) plus the cross
// terms, rounded once at the end. Error before that rounding ~2^-46 relative.
__attribute__((target("avx2,fma"), always_inline)) inline __m256 avx2_product(__m256 s,
                                                                             __m256 s_lo,
                                                                             __m256 d,
                                                                             __m256 d_lo) {
  const __m256 p = _mm256_mul_ps(s, d), err = _mm256_fmsub_ps(s, d, p);
  return _mm256_add_ps(p, _mm256_fmadd_ps(s, d_lo, _mm256_fmadd_ps(s_lo, d, err)));
}

// Fast tier for 8 pixels: X, Y, Z and the valid lanes (ok);
// false when a lane's decision is uncertain in float (then nothing is to be
// used).
template <bool kPerPixel>
__attribute__((target("avx2,fma"), always_inline)) inline bool avx2_fast(
    const Avx2Row& r, __m256 c8, const __m256d* dxd, __m256 dx8, __m256 dxl8, __m256 dy8,
    __m256 dyl8, __m256& X, __m256& Y, __m256& Z, __m256& okv) {
  __m128 Df[2], Nf[2];
  __m256d not_parallel[2], Dd[2], Nd[2];
  for (int h = 0; h < 2; ++h) {
    const __m256d c = avx2_widen(c8, h), dx = dxd[h];
    __m256d p, q, rz, dd;
    avx2_row_terms<kPerPixel>(r, kPerPixel ? avx2_widen(dy8, h) : r.dy0, p, q, rz, dd);
    const __m256d P = _mm256_fmadd_pd(r.K.a0, dx, p), Q = _mm256_fmadd_pd(r.K.b0, dx, q);
    const __m256d D = _mm256_fmadd_pd(c, Q, P), N = _mm256_fmadd_pd(c, r.K.bt, r.K.at);
    // |D| >= 1e-12 |n||d|, squared, with the 1e-24 folded into nn.
    const __m256d cm = _mm256_fmsub_pd(c, r.e12, r.cxe12);
    const __m256d nn = _mm256_fmadd_pd(cm, cm, r.fx2e24);
    const __m256d lim = _mm256_mul_pd(nn, _mm256_fmadd_pd(dx, dx, dd));
    not_parallel[h] = _mm256_cmp_pd(_mm256_mul_pd(D, D), lim, _CMP_GE_OQ);
    Dd[h] = D;
    Nd[h] = N;
    Df[h] = _mm256_cvtpd_ps(D);
    Nf[h] = _mm256_cvtpd_ps(N);
  }
  const __m256 D8 = _mm256_set_m128(Df[1], Df[0]);
  const __m256 s = _mm256_div_ps(_mm256_set_m128(Nf[1], Nf[0]), D8);
  const __m256 Rz = kPerPixel ? _mm256_fmadd_ps(r.r20f, dx8, _mm256_fmadd_ps(r.r21f, dy8, r.r22f))
                              : _mm256_fmadd_ps(r.r20f, dx8, r.rz0f);
  const __m256 m = _mm256_mul_ps(s, Rz), pz = _mm256_sub_ps(m, r.r2tf);
  const __m256 bound = _mm256_fmadd_ps(r.tol, _mm256_and_ps(m, r.abs_mask), r.tol_r2t);
  // Also uncertain: s >= smax, below which s dx and s dy cannot overflow a
  // float (the exact tier then checks them). s is NaN or <= 0 where the
  // column is not finite (N or D is then inf or NaN), so "s > 0" rejects it.
  const __m256 uncertain =
      _mm256_or_ps(_mm256_cmp_ps(_mm256_and_ps(pz, r.abs_mask), bound, _CMP_LE_OQ),
                   _mm256_cmp_ps(s, r.smax, _CMP_GE_OQ));
  if (_mm256_movemask_ps(uncertain) != 0) return false;
  // s to ~2^-47: s + s_lo, s_lo = (N - s D) / D with the residual in
  // double and its quotient in float; then x = (s + s_lo)(dx + dx_lo) as an
  // exact float product plus the cross terms (dx_lo: the float ray's
  // remainder from the double one), so x, y, z are the correctly rounded
  // floats of the double results: identical to the double kernel's but for
  // values within ~2^-46 of a rounding boundary.
  __m128 ef[2];
  for (int h = 0; h < 2; ++h)
    ef[h] = _mm256_cvtpd_ps(_mm256_fnmadd_pd(avx2_widen(s, h), Dd[h], Nd[h]));
  const __m256 s_lo = _mm256_div_ps(_mm256_set_m128(ef[1], ef[0]), D8);
  X = avx2_product(s, s_lo, dx8, dxl8);
  Y = avx2_product(s, s_lo, dy8, dyl8);
  Z = _mm256_add_ps(s, s_lo);
  const __m256 ok = _mm256_and_ps(_mm256_cmp_ps(s, r.zerof, _CMP_GT_OQ),
                                  _mm256_cmp_ps(pz, r.zerof, _CMP_GT_OQ));
  okv = _mm256_and_ps(ok, avx2_narrow_mask(not_parallel[0], not_parallel[1]));
  return true;
}

// Exact tier for 8 pixels (same outputs as avx2_fast).
template <bool kPerPixel>
__attribute__((target("avx2,fma"), always_inline)) inline void avx2_exact(
    const Avx2Row& r, __m256 c8, const __m256d* dxd, __m256 dy8, __m256& X, __m256& Y,
    __m256& Z, __m256& okv) {
  __m128 fx[2], fy[2], fz[2];
  __m256d ok[2];
  for (int h = 0; h < 2; ++h) {
    const __m256d dy = kPerPixel ? avx2_widen(dy8, h) : r.dy0;
    __m256d p, q, rz, dd;
    avx2_row_terms<kPerPixel>(r, dy, p, q, rz, dd);
    ok[h] = avx2_half(r.K, avx2_widen(c8, h), dxd[h], dy, p, q, rz, dd, fx[h], fy[h],
                      fz[h]);
  }
  X = _mm256_set_m128(fx[1], fx[0]);
  Y = _mm256_set_m128(fy[1], fy[0]);
  Z = _mm256_set_m128(fz[1], fz[0]);
  __m256 okf = _mm256_cmp_ps(_mm256_and_ps(c8, r.abs_mask), r.fmax, _CMP_LE_OQ);
  okf = _mm256_and_ps(okf, _mm256_cmp_ps(_mm256_and_ps(X, r.abs_mask), r.fmax, _CMP_LE_OQ));
  okf = _mm256_and_ps(okf, _mm256_cmp_ps(_mm256_and_ps(Y, r.abs_mask), r.fmax, _CMP_LE_OQ));
  okf = _mm256_and_ps(okf, _mm256_cmp_ps(Z, r.fmax, _CMP_LE_OQ));
  okv = _mm256_and_ps(okf, avx2_narrow_mask(ok[0], ok[1]));
}

// Left-pack permutations: for the valid-lane bits b, idx[b][e] is the
// source lane of element e, where element e of the permuted vector is
// packed point 2e (e < 4) or 2(e - 4) + 1 (e >= 4); unused elements read 0.
struct LeftPackTable {
  alignas(32) int32_t idx[256][8];
};
constexpr LeftPackTable make_left_pack() {
  LeftPackTable t{};
  for (int b = 0; b < 256; ++b) {
    int sel[8] = {0, 0, 0, 0, 0, 0, 0, 0}, n = 0;
    for (int lane = 0; lane < 8; ++lane)
      if ((b >> lane & 1) != 0) sel[n++] = lane;
    for (int e = 0; e < 8; ++e) t.idx[b][e] = sel[e < 4 ? 2 * e : 2 * (e - 4) + 1];
  }
  return t;
}
constexpr LeftPackTable kLeftPack = make_left_pack();

// 8 pixels: depth to dp, and x, y, z, the valid-lane mask to the chunk
// scratch at sx, sy, sz, sm (8 floats each).
// kPerPixel: the rays' y comes per pixel (yp), else from the row; their x
// in double from xdp (pinhole), else widened from xp.
template <bool kPerPixel>
__attribute__((target("avx2,fma"), always_inline)) inline void avx2_compute(
    const Avx2Row& r, const float* cp, const float* xp, const double* xdp, const float* xlp,
    const float* yp, float* dp, float* sx, float* sy, float* sz, float* sm) {
  const __m256 c8 = _mm256_loadu_ps(cp), dx8 = _mm256_loadu_ps(xp);
  const __m256 dy8 = kPerPixel ? _mm256_loadu_ps(yp) : r.dy0f;
  __m256d dxd[2];
  if constexpr (kPerPixel) {
    dxd[0] = avx2_widen(dx8, 0);
    dxd[1] = avx2_widen(dx8, 1);
  } else {
    dxd[0] = _mm256_loadu_pd(xdp);
    dxd[1] = _mm256_loadu_pd(xdp + 4);
  }
  const __m256 dxl8 = kPerPixel ? _mm256_setzero_ps() : _mm256_loadu_ps(xlp);
  const __m256 dyl8 = kPerPixel ? _mm256_setzero_ps() : r.dy0l;
  __m256 X, Y, Z, okv;
  if (!avx2_fast<kPerPixel>(r, c8, dxd, dx8, dxl8, dy8, dyl8, X, Y, Z, okv)) [[unlikely]]
    avx2_exact<kPerPixel>(r, c8, dxd, dy8, X, Y, Z, okv);
  _mm256_storeu_ps(dp, _mm256_blendv_ps(r.nan, Z, okv));
  _mm256_store_ps(sx, X);
  _mm256_store_ps(sy, Y);
  _mm256_store_ps(sz, Z);
  _mm256_store_ps(sm, okv);
}

// The valid points of 8 computed pixels, left-packed at q (advanced): one
// permutation from the table, then 4 x 8 -> 8 quads (x, y, z, intensity);
// the table's lane order makes the first shuffle hold the packed points 0
// and 1, the next 2 and 3, ... (the unpacks pair lane i with lane i + 4).
// All 8 quads are stored; q moves past the valid ones.
__attribute__((target("avx2,fma"), always_inline)) inline void avx2_pack(
    const float* sx, const float* sy, const float* sz, const float* sm, const float* ip,
    float*& q) {
  const auto b = static_cast<unsigned>(_mm256_movemask_ps(_mm256_load_ps(sm)));
  const __m256 In = ip != nullptr ? _mm256_loadu_ps(ip) : _mm256_setzero_ps();
  const __m256i idx = _mm256_load_si256(reinterpret_cast<const __m256i*>(kLeftPack.idx[b]));
  const __m256 Xp = _mm256_permutevar8x32_ps(_mm256_load_ps(sx), idx);
  const __m256 Yp = _mm256_permutevar8x32_ps(_mm256_load_ps(sy), idx);
  const __m256 Zp = _mm256_permutevar8x32_ps(_mm256_load_ps(sz), idx);
  const __m256 Ip = _mm256_permutevar8x32_ps(In, idx);
  const __m256 t0 = _mm256_unpacklo_ps(Xp, Yp), t1 = _mm256_unpackhi_ps(Xp, Yp);
  const __m256 t2 = _mm256_unpacklo_ps(Zp, Ip), t3 = _mm256_unpackhi_ps(Zp, Ip);
  _mm256_storeu_ps(q, _mm256_shuffle_ps(t0, t2, 0x44));
  _mm256_storeu_ps(q + 8, _mm256_shuffle_ps(t0, t2, 0xEE));
  _mm256_storeu_ps(q + 16, _mm256_shuffle_ps(t1, t3, 0x44));
  _mm256_storeu_ps(q + 24, _mm256_shuffle_ps(t1, t3, 0xEE));
  q += 4 * __builtin_popcount(b);
}

__attribute__((target("avx2,fma"), always_inline)) inline __m256d d(double v) {
  return _mm256_set1_pd(v);
}
__attribute__((target("avx2,fma"), always_inline)) inline __m256 f(double v) {
  return _mm256_set1_ps(static_cast<float>(v));
}

template <bool kPerPixel>
__attribute__((target("avx2,fma"))) uint32_t row_avx2_t(const Coeffs& k, const float* col,
                                                        const float* rx, const float* ry,
                                                        double ry0, const float* I, uint32_t w,
                                                        float* depth, float* quads) {
  const RowTerms rt = row_terms(k, ry0);
  constexpr double kTol = 1e-5;  // relative bound of the float tier's pz test
  const Avx2Row r{{d(k.a0), d(k.b0), d(k.at), d(k.bt), d(k.r20), d(k.r2t), d(k.fx2), d(k.cx),
                   d(1e-24), d(0.0), d(DBL_MAX)},
                  d(ry0), d(rt.p), d(rt.q), d(rt.rz), d(rt.dd),
                  d(k.a1), d(k.a2), d(k.b1), d(k.b2), d(k.r21), d(k.r22), d(1.0),
                  d(1e-12), d(1e-12 * k.cx), d(1e-24 * k.fx2),
                  f(k.r20), f(rt.rz), f(k.r21), f(k.r22), f(k.r2t), f(kTol),
                  f(kTol * std::abs(k.r2t)), f(ry0),
                  f(ry0 - static_cast<double>(static_cast<float>(ry0))), f(k.smax),
                  _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff)), _mm256_set1_ps(FLT_MAX),
                  _mm256_setzero_ps(), _mm256_set1_ps(std::numeric_limits<float>::quiet_NaN())};
  // Chunks of the row: all blocks computed into L1 scratch, then packed. Two
  // short dependency chains instead of one long one per block, so more
  // blocks overlap in the out-of-order window.
  constexpr uint32_t kChunk = 128;
  alignas(32) float sx[kChunk], sy[kChunk], sz[kChunk], sm[kChunk];
  float* q = quads;
  for (uint32_t x0 = 0; x0 < w; x0 += kChunk) {
    const uint32_t n = std::min(kChunk, w - x0), full = n / 8 * 8;
    for (uint32_t i = 0; i < full; i += 8) {
      const uint32_t x = x0 + i;
      avx2_compute<kPerPixel>(r, col + x, rx + x, kPerPixel ? nullptr : k.ray_x + x,
                              kPerPixel ? nullptr : k.ray_x_lo + x, kPerPixel ? ry + x : nullptr, depth + x, sx + i, sy + i, sz + i,
                              sm + i);
    }
    float is[8] = {};
    if (full < n) {  // the last n % 8 pixels, padded with invalid (NaN) columns
      float c[8], xs[8], xls[8], ys[8], dp[8];
      double xds[8];
      const uint32_t x = x0 + full, m = n - full;
      for (uint32_t i = 0; i < 8; ++i) {
        c[i] = i < m ? col[x + i] : std::numeric_limits<float>::quiet_NaN();
        xs[i] = i < m ? rx[x + i] : 0.0f;
        xds[i] = i < m && !kPerPixel ? k.ray_x[x + i] : 0.0;
        xls[i] = i < m && !kPerPixel ? k.ray_x_lo[x + i] : 0.0f;
        ys[i] = i < m && kPerPixel ? ry[x + i] : 0.0f;
        is[i] = i < m && I != nullptr ? I[x + i] : 0.0f;
      }
      avx2_compute<kPerPixel>(r, c, xs, xds, xls, ys, dp, sx + full, sy + full, sz + full, sm + full);
      std::memcpy(depth + x, dp, m * sizeof(float));
    }
    for (uint32_t i = 0; i < full; i += 8)
      avx2_pack(sx + i, sy + i, sz + i, sm + i, I != nullptr ? I + x0 + i : nullptr, q);
    if (full < n) avx2_pack(sx + full, sy + full, sz + full, sm + full, is, q);
  }
  return static_cast<uint32_t>((q - quads) / 4);
}

}  // namespace

__attribute__((target("avx2,fma"))) uint32_t row_avx2(const Coeffs& k, const float* col,
                                                      const float* rx, const float* ry, double ry0,
                                                      const float* I, uint32_t w, float* depth,
                                                      float* quads) {
  return ry != nullptr ? row_avx2_t<true>(k, col, rx, ry, ry0, I, w, depth, quads)
                       : row_avx2_t<false>(k, col, rx, ry, ry0, I, w, depth, quads);
}

// The same, 8 lanes (32-bit lane counts, summed every 2^20 steps).
__attribute__((target("avx2"))) uint64_t count_finite_avx2(const float* v, size_t n) {
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 fmax = _mm256_set1_ps(FLT_MAX);
  uint64_t m = 0;
  size_t i = 0;
  while (i + 8 <= n) {
    __m256i acc = _mm256_setzero_si256();
    const size_t end = std::min(n & ~size_t{7}, i + (size_t{8} << 20));
    for (; i < end; i += 8) {  // a true compare is -1 in every bit: subtract it
      const __m256 ok = _mm256_cmp_ps(_mm256_and_ps(_mm256_loadu_ps(v + i), abs_mask), fmax,
                                      _CMP_LE_OQ);
      acc = _mm256_sub_epi32(acc, _mm256_castps_si256(ok));
    }
    alignas(32) uint32_t lanes[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(lanes), acc);
    for (const uint32_t l : lanes) m += l;
  }
  return m + count_finite_portable(v + i, n - i);
}

}  // namespace procam::sdk::detail
