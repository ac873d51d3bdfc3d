// SPDX-License-Identifier: MIT
// Sub-pixel refinement by local line fits through stripe steps (see subpixel.hpp).
//
// Two kernels with bit-identical results: refine_pixel (scalar, the
// definition) and, where the CPU has AVX-512, refine_row_avx512 (16 pixels
// per step). The vector kernel evaluates exactly the scalar expressions in
// the same order per lane: the neighbour test in float, the sums sy and sxy
// in double accumulated over d = -r..r (an excluded neighbour adds +0.0 or
// -0.0, which leaves a sum unchanged), the counts sn, sx, sxx as small
// integers (exact in float), and the final line value in double. This file
// is compiled with -ffp-contract=off so no multiply-add is fused in either
// kernel (CMakeLists.txt). Issue 17: the scalar kernel took most of
// structured-light's outputs() (~2.3 M pixels x 11 neighbours).
#include "subpixel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "procam/sdk/simd.hpp"

namespace procam::sl {

namespace {

// thr[|d|] = max_slope * |d| + 1: a neighbour farther from c0 than this is
// on another surface.
std::vector<float> slope_limits(const SubpixelOptions& opt) {
  std::vector<float> thr(size_t{opt.radius} + 1);
  for (uint32_t d = 0; d <= opt.radius; ++d) thr[d] = opt.max_slope * static_cast<float>(d) + 1.0f;
  return thr;
}

// The refined value of row[x] (the definition; refine_row_avx512 matches it bit for bit).
float refine_pixel(const float* row, int64_t wi, int64_t x, int64_t r, const float* thr) {
  const float c0 = row[x];
  if (!std::isfinite(c0)) return c0;
  double sn = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  float cmin = c0, cmax = c0;
  for (int64_t d = -r; d <= r; ++d) {
    const int64_t j = x + d;
    if (j < 0 || j >= wi) continue;
    const float c = row[j];
    if (!std::isfinite(c)) continue;
    if (std::fabs(c - c0) > thr[d < 0 ? -d : d]) continue;  // other surface
    const auto xd = static_cast<double>(d), yd = static_cast<double>(c - c0);
    sn += 1;
    sx += xd;
    sy += yd;
    sxx += xd * xd;
    sxy += xd * yd;
    cmin = std::min(cmin, c);
    cmax = std::max(cmax, c);
  }
  if (sn < 3 || cmax - cmin < 1.0f) return c0;  // no step in the window: nothing to localize
  const double det = sn * sxx - sx * sx;
  if (!(det > 0)) return c0;
  const double a = (sy * sxx - sx * sxy) / det;  // line value at d = 0, relative to c0
  return c0 + static_cast<float>(std::clamp(a, -1.0, 1.0));
}

#ifdef PROCAM_SDK_X86
#define PROCAM_AVX512_FN __attribute__((target("avx512f,avx512dq")))

// Final step of 8 lanes (doubles): c0 + clamp(a) where the fit applies, else c0.
PROCAM_AVX512_FN inline __m256 finish8(__m256 c0, __m256 sn_f, __m256 sx_f, __m256 sxx_f, __m512d sy,
                                       __m512d sxy, __mmask8 step) {
  const __m512d sn = _mm512_cvtps_pd(sn_f), sx = _mm512_cvtps_pd(sx_f), sxx = _mm512_cvtps_pd(sxx_f);
  const __m512d det = _mm512_sub_pd(_mm512_mul_pd(sn, sxx), _mm512_mul_pd(sx, sx));
  const __mmask8 fit = static_cast<__mmask8>(
      step & _mm512_cmp_pd_mask(sn, _mm512_set1_pd(3.0), _CMP_GE_OQ) &
      _mm512_cmp_pd_mask(det, _mm512_setzero_pd(), _CMP_GT_OQ));
  __m512d a = _mm512_div_pd(_mm512_sub_pd(_mm512_mul_pd(sy, sxx), _mm512_mul_pd(sx, sxy)), det);
  // std::clamp(a, -1, 1): a < -1 ? -1 : 1 < a ? 1 : a (a is finite where fit).
  a = _mm512_mask_mov_pd(a, _mm512_cmp_pd_mask(a, _mm512_set1_pd(-1.0), _CMP_LT_OQ), _mm512_set1_pd(-1.0));
  a = _mm512_mask_mov_pd(a, _mm512_cmp_pd_mask(_mm512_set1_pd(1.0), a, _CMP_LT_OQ), _mm512_set1_pd(1.0));
  const __m256 refined = _mm256_add_ps(c0, _mm512_cvtpd_ps(a));
  return _mm512_castps512_ps256(_mm512_mask_mov_ps(_mm512_castps256_ps512(c0), fit, _mm512_castps256_ps512(refined)));
}

PROCAM_AVX512_FN inline __m256 lo8(__m512 v) { return _mm512_castps512_ps256(v); }
PROCAM_AVX512_FN inline __m256 hi8(__m512 v) {
  return _mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(v), 1));
}

// Pixels [x0, x1) of one row, a multiple of 16 apart; src[x] = row[x] for
// every x - r .. x + 15 + r read, NaN outside the row (refine_columns). kFloatSums: the exact float kernel
// (quarter_grid_row rows, r <= kMaxExactRadius), else the double kernel.
constexpr int64_t kMaxExactRadius = 32;  // the exact kernel's mask buffer
template <bool kFloatSums>
PROCAM_AVX512_FN void refine_row_avx512(const float* src, int64_t x0, int64_t x1, int64_t r,
                                        const float* thr, float* dst);

// The double kernel: the scalar expressions per lane, in the scalar order.
template <>
PROCAM_AVX512_FN void refine_row_avx512<false>(const float* src, int64_t x0, int64_t x1, int64_t r,
                                               const float* thr, float* dst) {
  const __m512 abs_mask = _mm512_castsi512_ps(_mm512_set1_epi32(0x7FFFFFFF));
  const __m512 inf = _mm512_set1_ps(std::numeric_limits<float>::infinity());
  const __m512 one = _mm512_set1_ps(1.0f);
  for (int64_t x = x0; x < x1; x += 16) {
    const __m512 c0 = _mm512_loadu_ps(src + x);
    const __mmask16 finite0 = _mm512_cmp_ps_mask(_mm512_and_ps(c0, abs_mask), inf, _CMP_LT_OQ);
    if (finite0 == 0) {
      _mm512_storeu_ps(dst + x, c0);
      continue;
    }
    __m512 sn = _mm512_setzero_ps(), sx = _mm512_setzero_ps(), sxx = _mm512_setzero_ps();
    __m512d sy_lo = _mm512_setzero_pd(), sy_hi = _mm512_setzero_pd();
    __m512d sxy_lo = _mm512_setzero_pd(), sxy_hi = _mm512_setzero_pd();
    __m512 cmin = c0, cmax = c0;
    for (int64_t d = -r; d <= r; ++d) {
      const __m512 c = _mm512_loadu_ps(src + x + d);
      const __m512 diff = _mm512_sub_ps(c, c0);
      const __mmask16 in = static_cast<__mmask16>(
          finite0 & _mm512_cmp_ps_mask(_mm512_and_ps(c, abs_mask), inf, _CMP_LT_OQ) &
          _mm512_cmp_ps_mask(_mm512_and_ps(diff, abs_mask), _mm512_set1_ps(thr[d < 0 ? -d : d]), _CMP_LE_OQ));
      const auto df = static_cast<float>(d);
      sn = _mm512_mask_add_ps(sn, in, sn, one);
      sx = _mm512_mask_add_ps(sx, in, sx, _mm512_set1_ps(df));
      sxx = _mm512_mask_add_ps(sxx, in, sxx, _mm512_set1_ps(df * df));
      const __m512 yd = _mm512_maskz_mov_ps(in, diff);
      const __m512d ylo = _mm512_cvtps_pd(lo8(yd));
      const __m512d yhi = _mm512_cvtps_pd(hi8(yd));
      const __m512d dd = _mm512_set1_pd(static_cast<double>(d));
      sy_lo = _mm512_add_pd(sy_lo, ylo);
      sy_hi = _mm512_add_pd(sy_hi, yhi);
      sxy_lo = _mm512_add_pd(sxy_lo, _mm512_mul_pd(dd, ylo));
      sxy_hi = _mm512_add_pd(sxy_hi, _mm512_mul_pd(dd, yhi));
      cmin = _mm512_mask_min_ps(cmin, in, cmin, c);
      cmax = _mm512_mask_max_ps(cmax, in, cmax, c);
    }
    const __mmask16 step =
        finite0 & _mm512_cmp_ps_mask(_mm512_sub_ps(cmax, cmin), one, _CMP_GE_OQ);  // !(cmax - cmin < 1)
    const __m256 out_lo = finish8(lo8(c0), lo8(sn), lo8(sx), lo8(sxx), sy_lo, sxy_lo,
                                  static_cast<__mmask8>(step & 0xFF));
    const __m256 out_hi = finish8(hi8(c0), hi8(sn), hi8(sx), hi8(sxx), sy_hi, sxy_hi,
                                  static_cast<__mmask8>(step >> 8));
    _mm256_storeu_ps(dst + x, out_lo);
    _mm256_storeu_ps(dst + x + 8, out_hi);
  }
}

// The exact kernel, for rows where quarter_grid_row (below) holds: sy and
// sxy in float, 16 lanes per add. There every yd = c - c0, every d * yd and
// every partial sum is a multiple of 1/4 well inside float's 24-bit
// significand, so each float operation, fused or not, gives the exact value;
// the double kernel's operations give the same exact values (zeros with the
// same signs: IEEE rounds neither, a sum that starts at +0 is never -0, and
// x + -x = +0 in both precisions), and the sums converted to double for the
// fit are the double kernel's bits. Exact sums do not depend on their order,
// which lets this kernel drop work the double kernel must do (issue 17:
// the refinement was most of outputs() after the last frame):
//  - d = 0 adds nothing (c = c0: yd = +0, d * yd = +-0, min/max c0) but one
//    to sn, which starts at 1 instead;
//  - no separate finiteness tests: with a finite limit thr (the bound below)
//    |c - c0| <= thr already fails for a NaN or infinite c or c0, and lanes
//    where c0 is not finite keep c0 (the step mask);
//  - sxy by one fused multiply-add (exact operands, exact result);
//  - the counts sn, sx, sxx only where a neighbour was left out: in the
//    common block of 16 pixels whose 2r neighbours all pass they are the
//    constants 2r + 1, 0 and r (r + 1) (2r + 1) / 3.
template <>
PROCAM_AVX512_FN void refine_row_avx512<true>(const float* src, int64_t x0, int64_t x1, int64_t r,
                                              const float* thr, float* dst) {
  const __m512 abs_mask = _mm512_castsi512_ps(_mm512_set1_epi32(0x7FFFFFFF));
  const __m512 inf = _mm512_set1_ps(std::numeric_limits<float>::infinity());
  const __m512 one = _mm512_set1_ps(1.0f);
  const auto rf = static_cast<float>(r);
  const __m512 all_n = _mm512_set1_ps(2.0f * rf + 1.0f);
  const __m512 all_xx = _mm512_set1_ps(rf * (rf + 1.0f) * (2.0f * rf + 1.0f) / 3.0f);  // sum of d^2, exact
  __mmask16 in[2 * kMaxExactRadius + 1];
  for (int64_t x = x0; x < x1; x += 16) {
    const __m512 c0 = _mm512_loadu_ps(src + x);
    const __mmask16 finite0 = _mm512_cmp_ps_mask(_mm512_and_ps(c0, abs_mask), inf, _CMP_LT_OQ);
    if (finite0 == 0) {
      _mm512_storeu_ps(dst + x, c0);
      continue;
    }
    __m512 sy = _mm512_setzero_ps(), sxy = _mm512_setzero_ps();
    __m512 cmin = c0, cmax = c0;
    __mmask16 all_in = finite0;
    for (int64_t d = -r; d <= r; ++d) {
      if (d == 0) continue;
      const __m512 c = _mm512_loadu_ps(src + x + d);
      const __m512 diff = _mm512_sub_ps(c, c0);
      const __mmask16 m = _mm512_cmp_ps_mask(_mm512_and_ps(diff, abs_mask),
                                             _mm512_set1_ps(thr[d < 0 ? -d : d]), _CMP_LE_OQ);
      in[d + r] = m;
      all_in = static_cast<__mmask16>(all_in & m);
      const __m512 yd = _mm512_maskz_mov_ps(m, diff);
      sy = _mm512_add_ps(sy, yd);
      sxy = _mm512_fmadd_ps(_mm512_set1_ps(static_cast<float>(d)), yd, sxy);
      cmin = _mm512_mask_min_ps(cmin, m, cmin, c);
      cmax = _mm512_mask_max_ps(cmax, m, cmax, c);
    }
    __m512 sn = all_n, sx = _mm512_setzero_ps(), sxx = all_xx;
    if (all_in != finite0) {  // a neighbour left out of some pixel's window: count
      sn = one;
      sxx = _mm512_setzero_ps();
      for (int64_t d = -r; d <= r; ++d) {
        if (d == 0) continue;
        const __mmask16 m = in[d + r];
        const auto df = static_cast<float>(d);
        sn = _mm512_mask_add_ps(sn, m, sn, one);
        sx = _mm512_mask_add_ps(sx, m, sx, _mm512_set1_ps(df));
        sxx = _mm512_mask_add_ps(sxx, m, sxx, _mm512_set1_ps(df * df));
      }
    }
    const __mmask16 step =
        finite0 & _mm512_cmp_ps_mask(_mm512_sub_ps(cmax, cmin), one, _CMP_GE_OQ);  // !(cmax - cmin < 1)
    const __m256 out_lo = finish8(lo8(c0), lo8(sn), lo8(sx), lo8(sxx), _mm512_cvtps_pd(lo8(sy)),
                                  _mm512_cvtps_pd(lo8(sxy)), static_cast<__mmask8>(step & 0xFF));
    const __m256 out_hi = finish8(hi8(c0), hi8(sn), hi8(sx), hi8(sxx), _mm512_cvtps_pd(hi8(sy)),
                                  _mm512_cvtps_pd(hi8(sxy)), static_cast<__mmask8>(step >> 8));
    _mm256_storeu_ps(dst + x, out_lo);
    _mm256_storeu_ps(dst + x + 8, out_hi);
  }
}
// True when every finite value of row[0, w) is a multiple of 1/4 of at most
// 2^16 in magnitude (the vote's grid: keys are half columns, a two-code
// midpoint a quarter; any projector is narrower than 2^16 columns), and the
// window's sums stay exact in float: each |yd| <= t = max thr (a neighbour
// farther off is excluded), so |sy| <= (2r + 1) t and |sxy| <= r (2r + 1) t;
// in quarters below 2^24. Then refine_row_avx512<true>
// gives the double kernel's bits.
PROCAM_AVX512_FN bool quarter_grid_row(const float* row, int64_t w, int64_t r, const float* thr) {
  const float tmax = *std::max_element(thr, thr + r + 1);  // thr[r] unless max_slope < 0
  const double bound = 4.0 * static_cast<double>(std::max<int64_t>(r, 1)) * static_cast<double>(2 * r + 1) *
                       static_cast<double>(tmax);
  if (!(bound < 16777216.0)) return false;  // NaN (max_slope NaN / inf) included
  const __m512 abs_mask = _mm512_castsi512_ps(_mm512_set1_epi32(0x7FFFFFFF));
  const __m512 inf = _mm512_set1_ps(std::numeric_limits<float>::infinity());
  const __m512 four = _mm512_set1_ps(4.0f), limit = _mm512_set1_ps(65536.0f);
  int64_t x = 0;
  for (; x < w; x += 16) {
    const __mmask16 lanes = w - x >= 16 ? __mmask16{0xFFFF} : static_cast<__mmask16>((1u << (w - x)) - 1u);
    const __m512 v = _mm512_maskz_loadu_ps(lanes, row + x);
    const __m512 a = _mm512_and_ps(v, abs_mask);
    const __mmask16 finite = static_cast<__mmask16>(lanes & _mm512_cmp_ps_mask(a, inf, _CMP_LT_OQ));
    const __m512 q = _mm512_mul_ps(v, four);  // exact: a power of two, |v| <= 2^16
    const __mmask16 ok = static_cast<__mmask16>(
        _mm512_cmp_ps_mask(a, limit, _CMP_LE_OQ) &
        _mm512_cmp_ps_mask(_mm512_roundscale_ps(q, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC), q, _CMP_EQ_OQ));
    if ((finite & ~ok) != 0) return false;
  }
  return true;
}
#endif

}  // namespace

void refine_columns(const float* col, uint32_t w, uint32_t y0, uint32_t y1,
                    const SubpixelOptions& opt, float* out, SubpixelKernel kernel) {
  const auto r = static_cast<int64_t>(opt.radius);
  const auto wi = static_cast<int64_t>(w);
  const std::vector<float> thr = slope_limits(opt);
  int64_t vec_end = 0;  // pixels [0, vec_end) of each row by the vector kernel
  std::vector<float> pad;
#ifdef PROCAM_SDK_X86
  if (kernel == SubpixelKernel::best && sdk::cpu_has_avx512()) {
    vec_end = wi / 16 * 16;
    pad.assign(static_cast<size_t>(wi + 2 * r), std::numeric_limits<float>::quiet_NaN());
  }
#else
  (void)kernel;
#endif
  for (uint32_t y = y0; y < y1; ++y) {
    const float* row = col + static_cast<size_t>(y) * w;
    float* dst = out + static_cast<size_t>(y) * w;
#ifdef PROCAM_SDK_X86
    if (vec_end > 0) {
      // Blocks [xa, xb) read only inside the row: straight from it. The
      // edge blocks read the padded copy, where only the part they read is
      // copied (row[0, xa + r) and row[xb - r, w)), not the whole row.
      const int64_t xa = std::min(vec_end, (r + 15) / 16 * 16);
      const int64_t xb = std::max(xa, std::min(vec_end, (wi - r) / 16 * 16));
      const float* padded = pad.data() + r;  // padded[x] = row[x], NaN outside
      std::copy(row, row + std::min(wi, xa + r), pad.begin() + r);
      std::copy(row + std::max<int64_t>(0, xb - r), row + wi, pad.begin() + r + std::max<int64_t>(0, xb - r));
      const bool exact = r <= kMaxExactRadius && quarter_grid_row(row, wi, r, thr.data());
      const auto run = [&](const float* src, int64_t x0, int64_t x1) {
        if (x0 >= x1) return;
        if (exact)
          refine_row_avx512<true>(src, x0, x1, r, thr.data(), dst);
        else
          refine_row_avx512<false>(src, x0, x1, r, thr.data(), dst);
      };
      run(padded, 0, xa);
      run(row, xa, xb);
      run(padded, xb, vec_end);
    }
#endif
    for (int64_t x = vec_end; x < wi; ++x) dst[x] = refine_pixel(row, wi, x, r, thr.data());
  }
}

}  // namespace procam::sl
