// SPDX-License-Identifier: MIT
// Per-pixel decode with validity rules (thesis §3.2; see decode.hpp).
#include "decode.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "procam/sdk/simd.hpp"

namespace procam::sl {

namespace {
std::vector<uint32_t> bounds_over(const StripeCode& code, uint32_t length,
                                  const uint32_t* index_of, const float* coord_of) {
  std::vector<uint32_t> bound(code.bits, 0);
  for (uint32_t x = 0; x < length; ++x) {
    const uint32_t w = code.words[index_of != nullptr ? index_of[x] : x];
    for (uint32_t k = 0; k < code.bits; ++k) {
      const uint32_t c = code.decode(w ^ (1u << k));
      if (c == StripeCode::kInvalid) continue;
      const double at = coord_of != nullptr ? static_cast<double>(coord_of[c]) : c;
      const auto err = static_cast<uint32_t>(std::ceil(std::fabs(at - x)));
      bound[k] = std::max(bound[k], err);
    }
  }
  return bound;
}
}  // namespace

std::vector<uint32_t> plane_error_bounds(const StripeCode& code) {
  return bounds_over(code, code.length, nullptr, nullptr);
}

std::vector<uint32_t> plane_error_bounds(const ProjectedCode& code) {
  return bounds_over(code.code, code.length(), code.index_of.data(), code.coord_of.data());
}

std::vector<uint8_t> tolerable_planes(const std::vector<uint32_t>& error_bounds,
                                      uint32_t max_weak_error_px) {
  const auto bits = static_cast<uint32_t>(error_bounds.size());
  std::vector<uint8_t> t(bits, 0);
  if (max_weak_error_px == 0) return t;
  for (uint32_t p = 0; p < bits; ++p) t[p] = error_bounds[bits - 1 - p] <= max_weak_error_px;
  return t;
}

WordMap word_map(const StripeCode& code, const std::vector<int32_t>* value_of) {
  WordMap m;
  m.table.assign(code.lut.size(), -1);
  for (size_t w = 0; w < m.table.size(); ++w) {
    const uint32_t c = code.lut[w];
    if (c == StripeCode::kInvalid) continue;
    m.table[w] = value_of != nullptr ? (*value_of)[c] : static_cast<int32_t>(c);
  }
  // Arithmetic form: value = scale * index, words Gray or XOR-with-base.
  if (code.length == 0 || code.bits > 16) return m;
  const int32_t scale = m.table[code.words[0]] == 0 && code.length > 1 ? m.table[code.words[1]] : 0;
  if (scale != 1 && scale != 2) return m;
  const uint32_t all = (1u << code.bits) - 1u;
  for (int32_t base = -1; base + 1 < static_cast<int32_t>(code.bits); ++base) {
    const uint32_t high = base < 0 ? 0u : all & ~((2u << base) - 1u);
    bool same = true;
    for (uint32_t w = 0; w <= all && same; ++w) {
      const uint32_t g = base >= 0 && ((w >> base) & 1u) != 0 ? w ^ high : w;
      uint32_t c = g;
      for (uint32_t shift = 1; shift < 16; shift <<= 1) c ^= c >> shift;
      const int32_t expect = c < code.length ? scale * static_cast<int32_t>(c) : -1;
      same = m.table[w] == expect;
    }
    if (same) {
      m.arithmetic = true;
      m.xor_base = base;
      m.high_mask = high;
      m.length = code.length;
      m.scale = scale;
      return m;
    }
  }
  return m;
}

float noise_threshold(const DecodeThresholds& t, float S) {
  const float var = t.noise_a + t.noise_b * S;
  return t.noise_k > 0.0f && var > 0.0f ? t.noise_k * std::sqrt(var) : 0.0f;
}

NoiseFit apply_noise_rule(const BitPlaneStream& s, double noise_k, DecodeThresholds& t, double& k_used) {
  k_used = 0;
  if (!(noise_k > 0)) return NoiseFit{};
  const NoiseFit fit = s.fit_noise();
  if (fit.measured) {
    k_used = noise_k;
    t.noise_k = static_cast<float>(noise_k);
    t.noise_a = static_cast<float>(fit.a);
    t.noise_b = static_cast<float>(fit.b);
  }
  return fit;
}

DecodeContext::DecodeContext(const BitPlaneStream& stream, const DecodeThresholds& thresholds)
    : s(stream), t(thresholds), inv_scale(1.0f / stream.full_scale()) {
  if (!s.u8()) return;
  for (int v = 0; v < 512; ++v) {
    noise8[v] = noise_threshold(t, static_cast<float>(v));
    noise = noise || noise8[v] > 0.0f;
  }
  for (int v = 0; v < 256; ++v) {  // the float expressions of the scalar rule, per integer value
    const auto c = static_cast<float>(v);
    inv_c8[v] = v > 0 ? 1.0f / c : 0.0f;
    thr_f8[v] = t.min_bit_margin * c;
    thr8[v] = thr_f8[v] >= 255.0f ? 255 : static_cast<uint8_t>(std::floor(thr_f8[v]));
    lit8[v] = v > 0 && c >= t.min_contrast_abs;
    const float i = c * inv_scale;
    intensity8[v] = std::clamp(i, 0.0f, 1.0f);
  }
}

namespace {
#ifdef PROCAM_SDK_X86
__attribute__((target("avx2"), always_inline)) inline void store8(uint8_t* dst, __m256i v) {
  const __m128i w16 = _mm_packs_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  _mm_storel_epi64(reinterpret_cast<__m128i*>(dst), _mm_packus_epi16(w16, w16));
}

__attribute__((target("avx2"))) size_t index_maps_avx2(const int32_t* out, size_t n, float* coord,
                                                      uint8_t* valid) {
  const __m256 nan = _mm256_set1_ps(std::numeric_limits<float>::quiet_NaN());
  const __m256i minus1 = _mm256_set1_epi32(-1), c255 = _mm256_set1_epi32(255);
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(out + i));
    const __m256i ok = _mm256_cmpgt_epi32(v, minus1);
    _mm256_storeu_ps(coord + i, _mm256_blendv_ps(nan, _mm256_cvtepi32_ps(v), _mm256_castsi256_ps(ok)));
    if (valid != nullptr) store8(valid + i, _mm256_and_si256(ok, c255));
  }
  return i;
}

// decode_base for 8-bit state, 8 pixels per step: the same float expressions
// as the tables of DecodeContext (t * C, 1 / C, C >= min_contrast_abs), so
// the results are identical; returns the first pixel not done.
__attribute__((target("avx2"))) size_t decode_base_u8_avx2(const DecodeContext& ctx, size_t b,
                                                          size_t e, BaseRow& row, uint8_t* lit) {
  const uint8_t* w8 = ctx.s.white8();
  const uint8_t* b8 = ctx.s.black8();
  const __m256i zero = _mm256_setzero_si256(), c255 = _mm256_set1_epi32(255);
  const __m256i full = _mm256_set1_epi32(255);
  const __m256 t = _mm256_set1_ps(ctx.t.min_bit_margin);
  const __m256 min_abs = _mm256_set1_ps(ctx.t.min_contrast_abs);
  const __m256 onef = _mm256_set1_ps(1.0f), f255 = _mm256_set1_ps(255.0f);
  const __m256i clip = ctx.t.clipped_white_invalid ? _mm256_set1_epi32(-1) : zero;
  const __m256i one_i = _mm256_set1_epi32(1);
  size_t i = b;
  for (; i + 8 <= e; i += 8) {
    const size_t k = i - b;
    const __m256i w = _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(w8 + i)));
    __m256i c = w;
    if (b8 != nullptr)
      c = _mm256_sub_epi32(w, _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(b8 + i))));
    const __m256i pos = _mm256_cmpgt_epi32(c, zero);
    const __m256 cf = _mm256_cvtepi32_ps(c);
    const __m256i lit_px = _mm256_and_si256(pos, _mm256_castps_si256(_mm256_cmp_ps(cf, min_abs, _CMP_GE_OQ)));
    const __m256i clipped = _mm256_and_si256(clip, _mm256_cmpeq_epi32(w, full));
    const __m256i ok = _mm256_andnot_si256(clipped, lit_px);
    __m256 thr = _mm256_mul_ps(t, cf);
    if (ctx.noise) {  // max(t * C, noise8[W + B]), the scalar expression
      __m256i sum = w;
      if (b8 != nullptr)
        sum = _mm256_add_epi32(w, _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(b8 + i))));
      thr = _mm256_max_ps(thr, _mm256_i32gather_ps(ctx.noise8, sum, 4));
    }
    _mm256_storeu_ps(row.thr.data() + k, thr);
    _mm256_storeu_ps(row.inv_c.data() + k, _mm256_and_ps(_mm256_castsi256_ps(pos), _mm256_div_ps(onef, cf)));
    const __m256i thr8 = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_floor_ps(thr), f255));
    store8(row.gate.data() + k, _mm256_blendv_epi8(c255, thr8, ok));
    store8(row.base_ok.data() + k, _mm256_and_si256(ok, one_i));
    if (lit != nullptr) store8(lit + i, _mm256_and_si256(lit_px, c255));
  }
  return i;
}

#define PROCAM_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl")))
// 16 x int32 -> 16 bytes clamped to 0..255 (what store8's packs + packus do).
PROCAM_AVX512 inline void store16_clamped(uint8_t* dst, __m512i v) {
  _mm_storeu_si128(reinterpret_cast<__m128i*>(dst),
                   _mm512_cvtusepi32_epi8(_mm512_max_epi32(v, _mm512_setzero_si512())));
}

PROCAM_AVX512 size_t index_maps_avx512(const int32_t* out, size_t n, float* coord,
                                       uint8_t* valid) {
  const __m512 nan = _mm512_set1_ps(std::numeric_limits<float>::quiet_NaN());
  const __m512i minus1 = _mm512_set1_epi32(-1);
  size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    const __m512i v = _mm512_loadu_si512(out + i);
    const __mmask16 ok = _mm512_cmpgt_epi32_mask(v, minus1);
    _mm512_storeu_ps(coord + i, _mm512_mask_mov_ps(nan, ok, _mm512_cvtepi32_ps(v)));
    if (valid != nullptr)
      _mm_storeu_si128(reinterpret_cast<__m128i*>(valid + i),
                       _mm_maskz_set1_epi8(ok, static_cast<char>(255)));
  }
  return i;
}

// decode_base_u8_avx2, 16 pixels per step (same float expressions).
PROCAM_AVX512 size_t decode_base_u8_avx512(const DecodeContext& ctx, size_t b, size_t e,
                                           BaseRow& row, uint8_t* lit) {
  const uint8_t* w8 = ctx.s.white8();
  const uint8_t* b8 = ctx.s.black8();
  const __m512i zero = _mm512_setzero_si512(), c255 = _mm512_set1_epi32(255);
  const __m512 t = _mm512_set1_ps(ctx.t.min_bit_margin);
  const __m512 min_abs = _mm512_set1_ps(ctx.t.min_contrast_abs);
  const __m512 onef = _mm512_set1_ps(1.0f), f255 = _mm512_set1_ps(255.0f);
  const bool clip = ctx.t.clipped_white_invalid;
  size_t i = b;
  for (; i + 16 <= e; i += 16) {
    const size_t k = i - b;
    const __m512i w = _mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(w8 + i)));
    __m512i c = w;
    if (b8 != nullptr)
      c = _mm512_sub_epi32(w, _mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(b8 + i))));
    const __mmask16 pos = _mm512_cmpgt_epi32_mask(c, zero);
    const __m512 cf = _mm512_cvtepi32_ps(c);
    const __mmask16 lit_px = pos & _mm512_cmp_ps_mask(cf, min_abs, _CMP_GE_OQ);
    const __mmask16 clipped = clip ? _mm512_cmpeq_epi32_mask(w, c255) : __mmask16{0};
    const __mmask16 ok = lit_px & static_cast<__mmask16>(~clipped);
    __m512 thr = _mm512_mul_ps(t, cf);
    if (ctx.noise) {  // max(t * C, noise8[W + B]), the scalar expression
      __m512i sum = w;
      if (b8 != nullptr)
        sum = _mm512_add_epi32(w, _mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(b8 + i))));
      thr = _mm512_max_ps(thr, _mm512_i32gather_ps(sum, ctx.noise8, 4));
    }
    _mm512_storeu_ps(row.thr.data() + k, thr);
    _mm512_storeu_ps(row.inv_c.data() + k, _mm512_maskz_div_ps(pos, onef, cf));
    const __m512i thr8 = _mm512_cvttps_epi32(_mm512_min_ps(_mm512_roundscale_ps(thr, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC), f255));
    store16_clamped(row.gate.data() + k, _mm512_mask_mov_epi32(c255, ok, thr8));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(row.base_ok.data() + k), _mm_maskz_set1_epi8(ok, 1));
    if (lit != nullptr)
      _mm_storeu_si128(reinterpret_cast<__m128i*>(lit + i), _mm_maskz_set1_epi8(lit_px, static_cast<char>(255)));
  }
  return i;
}
#endif
}  // namespace

void index_maps(const int32_t* out, size_t n, float* coord, uint8_t* valid) {
  size_t i = 0;
#ifdef PROCAM_SDK_X86
  if (avx512_active())
    i = index_maps_avx512(out, n, coord, valid);
  else if (simd_active())
    i = index_maps_avx2(out, n, coord, valid);
#endif
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (; i < n; ++i) {
    coord[i] = out[i] >= 0 ? static_cast<float>(out[i]) : nan;
    if (valid != nullptr) valid[i] = out[i] >= 0 ? 255 : 0;
  }
}

void decode_base(const DecodeContext& ctx, size_t b, size_t e, BaseRow& row, uint8_t* lit,
                 float* intensity) {
  const BitPlaneStream& s = ctx.s;
  const DecodeThresholds& t = ctx.t;
  const float fs = s.full_scale();
  uint8_t* base_ok = row.base_ok.data();
  uint8_t* gate = row.gate.data();
  float* thr = row.thr.data();
  float* inv_c = row.inv_c.data();
  if (s.u8()) {
    const uint8_t* w8 = s.white8();
    const uint8_t* b8 = s.black8();
    const bool clip = t.clipped_white_invalid;
    size_t start = b;
#ifdef PROCAM_SDK_X86
    if (avx512_active() && intensity == nullptr)
      start = decode_base_u8_avx512(ctx, b, e, row, lit);
    else if (simd_active() && intensity == nullptr)
      start = decode_base_u8_avx2(ctx, b, e, row, lit);
#endif
    for (size_t i = start; i < e; ++i) {
      const size_t k = i - b;
      const int32_t bk = b8 != nullptr ? int32_t{b8[i]} : 0;
      const int32_t w = w8[i], c = w - bk;
      const auto cu = static_cast<size_t>(c > 0 ? c : 0);
      const bool lit_px = c > 0 && ctx.lit8[cu] != 0;
      const bool ok = lit_px && (!clip || w < 255);
      base_ok[k] = ok;
      inv_c[k] = ctx.inv_c8[cu];
      float th = c > 0 ? ctx.thr_f8[cu] : t.min_bit_margin * static_cast<float>(c);
      uint8_t g = ctx.thr8[cu];
      if (ctx.noise) {  // the SIMD kernels' max_ps(t * C, noise) and floor
        const float nz = ctx.noise8[static_cast<size_t>(w + bk)];
        th = th > nz ? th : nz;
        g = th >= 255.0f ? 255 : static_cast<uint8_t>(std::floor(th));
      }
      thr[k] = th;
      gate[k] = ok ? g : 255;
      if (lit != nullptr) lit[i] = lit_px ? 255 : 0;
      if (intensity != nullptr) intensity[i] = ctx.intensity8[w];
    }
    return;
  }
  const float* wf = s.white_f();
  const float* bf = s.black_f();
  for (size_t i = b; i < e; ++i) {
    const size_t k = i - b;
    const float w = wf[i], bl = bf != nullptr ? bf[i] : 0.0f;
    const float contrast = w - bl;
    const bool finite = std::isfinite(w) && std::isfinite(bl) && std::isfinite(contrast);
    const bool pos = finite && contrast > 0.0f;
    const bool lit_px = pos && contrast >= t.min_contrast_abs;
    base_ok[k] = lit_px && (!t.clipped_white_invalid || w < fs);
    inv_c[k] = pos ? 1.0f / contrast : 0.0f;
    thr[k] = std::max(t.min_bit_margin * contrast, finite ? noise_threshold(t, w + bl) : 0.0f);
    gate[k] = 255;  // unused: float state
    if (lit != nullptr) lit[i] = lit_px ? 255 : 0;
    if (intensity != nullptr) {
      const float v = w * ctx.inv_scale;
      intensity[i] = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
    }
  }
}

namespace {

// The rules of decode.hpp, one pixel at a time (any state representation).
// Row terms of pixel i are at row[k0 + i - b]; out / confidence at [i - b].
// Pixel i's word: st.word[i] (float state) or wbyte[0][i] | wbyte[1][i] << 8.
size_t decode_code_scalar(const BitPlaneStream& s, const CodeState& st, const int32_t* table,
                          size_t b, size_t e, const BaseRow& row, size_t k0, int32_t* out,
                          float* confidence) {
  const uint8_t* lo = st.wbyte[0].get();
  const uint8_t* hi = st.wbyte[1].get();
  const float inf = std::numeric_limits<float>::infinity();
  const float fmax = std::numeric_limits<float>::max();
  const bool strict_any = st.folded[0] > 0, weak = st.has_weak;
  size_t weak_used = 0;
  for (size_t i = b; i < e; ++i) {
    const size_t k = k0 + i - b, o = i - b;
    float ms = inf, mw = inf;
    uint8_t fl = 0;
    if (s.u8()) {
      if (strict_any) ms = static_cast<float>(st.m8[0][i]);
      if (weak) mw = static_cast<float>(st.m8[1][i]);
    } else {
      if (strict_any) ms = st.mf[0][i];
      if (weak) mw = st.mf[1][i];
      fl = st.flags[i];
    }
    const float m = ms < mw ? ms : mw;
    const bool nonfinite = (fl & kFlagNonFinite) != 0;
    if (confidence != nullptr)
      confidence[o] = !nonfinite && m <= fmax ? std::min(m * row.inv_c[k], 1.0f) : 0.0f;
    const uint32_t word = s.u8() ? lo[i] | (hi != nullptr ? uint32_t{hi[i]} << 8 : 0u) : st.word[i];
    const int32_t v = table[word];
    const float thr = row.thr[k];
    const bool ok = row.base_ok[k] != 0 && !nonfinite && (fl & kFlagSaturated) == 0 && ms > thr &&
                    mw > 0.0f && v >= 0;
    weak_used += ok && !(mw > thr) ? 1u : 0u;
    out[o] = ok ? v : -1;
  }
  return weak_used;
}

#ifdef PROCAM_SDK_X86
// 8-bit state with at least one strict plane: integer margins against the
// integer gate (m > gate <=> m > thr for integer m, see BaseRow), 8 pixels
// per step; the tail goes through the scalar loop.
__attribute__((target("avx2"))) size_t decode_code_u8_avx2(const BitPlaneStream& s,
                                                          const CodeState& st,
                                                          const WordMap& map, size_t b,
                                                          size_t e, const BaseRow& row,
                                                          int32_t* out, float* confidence) {
  const int32_t* table = map.table.data();
  const bool arithmetic = map.arithmetic;
  const __m128i base_shift = _mm_cvtsi32_si128(map.xor_base < 0 ? 0 : map.xor_base);
  const __m256i high = _mm256_set1_epi32(static_cast<int32_t>(map.high_mask));
  const __m256i one_i = _mm256_set1_epi32(1);
  const __m256i length = _mm256_set1_epi32(static_cast<int32_t>(map.length));
  const bool is_xor = map.xor_base >= 0, doubled = map.scale == 2;
  const uint8_t* ms8 = st.m8[0].get();
  const uint8_t* lo = st.wbyte[0].get();
  const uint8_t* hi = st.wbyte[1].get();
  const uint8_t* mw8 = st.has_weak ? st.m8[1].get() : nullptr;
  const uint8_t* gate = row.gate.data();
  const float* inv_c = row.inv_c.data();
  const __m256i minus1 = _mm256_set1_epi32(-1), zero = _mm256_setzero_si256();
  const __m256 one = _mm256_set1_ps(1.0f);
  size_t weak_used = 0;
  size_t i = b;
  for (; i + 8 <= e; i += 8) {
    const size_t k = i - b;
    __m256i w = _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(lo + i)));
    if (hi != nullptr)
      w = _mm256_or_si256(w, _mm256_slli_epi32(_mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(hi + i))), 8));
    __m256i v;
    if (arithmetic) {  // the table's values without a gather (see WordMap)
      __m256i g = w;
      if (is_xor) {
        const __m256i b_set = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_srl_epi32(w, base_shift), one_i), one_i);
        g = _mm256_xor_si256(g, _mm256_and_si256(b_set, high));
      }
      g = _mm256_xor_si256(g, _mm256_srli_epi32(g, 1));
      g = _mm256_xor_si256(g, _mm256_srli_epi32(g, 2));
      g = _mm256_xor_si256(g, _mm256_srli_epi32(g, 4));
      g = _mm256_xor_si256(g, _mm256_srli_epi32(g, 8));
      const __m256i in_range = _mm256_cmpgt_epi32(length, g);
      if (doubled) g = _mm256_add_epi32(g, g);
      v = _mm256_or_si256(_mm256_and_si256(in_range, g), _mm256_andnot_si256(in_range, minus1));
    } else {
      v = _mm256_i32gather_epi32(table, w, 4);
    }
    const __m256i ms = _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(ms8 + i)));
    const __m256i g = _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(gate + k)));
    __m256i ok = _mm256_and_si256(_mm256_cmpgt_epi32(ms, g), _mm256_cmpgt_epi32(v, minus1));
    __m256i m = ms;
    if (mw8 != nullptr) {
      const __m256i mw = _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(mw8 + i)));
      ok = _mm256_and_si256(ok, _mm256_cmpgt_epi32(mw, zero));
      const __m256i tolerated = _mm256_andnot_si256(_mm256_cmpgt_epi32(mw, g), ok);
      weak_used += static_cast<size_t>(__builtin_popcount(
          static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(tolerated)))));
      m = _mm256_min_epi32(ms, mw);
    }
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + k), _mm256_or_si256(_mm256_and_si256(ok, v), _mm256_andnot_si256(ok, minus1)));
    if (confidence != nullptr) {
      const __m256 c = _mm256_mul_ps(_mm256_cvtepi32_ps(m), _mm256_loadu_ps(inv_c + k));
      _mm256_storeu_ps(confidence + k, _mm256_min_ps(c, one));
    }
  }
  if (i < e)
    weak_used += decode_code_scalar(s, st, table, i, e, row, i - b, out + (i - b),
                                    confidence != nullptr ? confidence + (i - b) : nullptr);
  return weak_used;
}

// decode_code_u8_avx2, 16 pixels per step with mask registers; margins and
// gate compared as bytes (all in 0..255). kMaps: writes index_maps' coord
// and valid (may be null) directly instead of `out` (then scratch only).
template <bool kMaps>
PROCAM_AVX512 size_t decode_code_u8_avx512(const BitPlaneStream& s, const CodeState& st,
                                           const WordMap& map, size_t b, size_t e,
                                           const BaseRow& row, int32_t* out, float* confidence,
                                           float* coord, uint8_t* valid) {
  const __m512 nan = _mm512_set1_ps(std::numeric_limits<float>::quiet_NaN());
  const int32_t* table = map.table.data();
  const bool arithmetic = map.arithmetic;
  const __m512i base_bit = _mm512_set1_epi32(map.xor_base < 0 ? 0 : int32_t{1} << map.xor_base);
  const __m512i high = _mm512_set1_epi32(static_cast<int32_t>(map.high_mask));
  const __m512i length = _mm512_set1_epi32(static_cast<int32_t>(map.length));
  const bool is_xor = map.xor_base >= 0, doubled = map.scale == 2;
  const uint8_t* ms8 = st.m8[0].get();
  const uint8_t* lo = st.wbyte[0].get();
  const uint8_t* hi = st.wbyte[1].get();
  const uint8_t* mw8 = st.has_weak ? st.m8[1].get() : nullptr;
  const uint8_t* gate = row.gate.data();
  const float* inv_c = row.inv_c.data();
  const __m512i minus1 = _mm512_set1_epi32(-1);
  const __m128i zero8 = _mm_setzero_si128();
  const __m512 one = _mm512_set1_ps(1.0f);
  size_t weak_used = 0;
  size_t i = b;
  for (; i + 16 <= e; i += 16) {
    const size_t k = i - b;
    __m512i w = _mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(lo + i)));
    if (hi != nullptr)
      w = _mm512_or_si512(w, _mm512_slli_epi32(_mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(hi + i))), 8));
    __m512i v;
    if (arithmetic) {  // the table's values without a gather (see WordMap)
      __m512i g = w;
      if (is_xor) g = _mm512_mask_xor_epi32(g, _mm512_test_epi32_mask(w, base_bit), g, high);
      g = _mm512_xor_si512(g, _mm512_srli_epi32(g, 1));
      g = _mm512_xor_si512(g, _mm512_srli_epi32(g, 2));
      g = _mm512_xor_si512(g, _mm512_srli_epi32(g, 4));
      g = _mm512_xor_si512(g, _mm512_srli_epi32(g, 8));
      const __mmask16 in_range = _mm512_cmpgt_epi32_mask(length, g);
      if (doubled) g = _mm512_add_epi32(g, g);
      v = _mm512_mask_mov_epi32(minus1, in_range, g);
    } else {
      v = _mm512_i32gather_epi32(w, table, 4);
    }
    const __m128i ms = _mm_loadu_si128(reinterpret_cast<const __m128i*>(ms8 + i));
    const __m128i g8 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(gate + k));
    __mmask16 ok = _mm_cmpgt_epu8_mask(ms, g8) & _mm512_cmpgt_epi32_mask(v, minus1);
    __m128i m = ms;
    if (mw8 != nullptr) {
      const __m128i mw = _mm_loadu_si128(reinterpret_cast<const __m128i*>(mw8 + i));
      ok &= _mm_cmpgt_epu8_mask(mw, zero8);
      const __mmask16 tolerated = ok & static_cast<__mmask16>(~_mm_cmpgt_epu8_mask(mw, g8));
      weak_used += static_cast<size_t>(__builtin_popcount(static_cast<unsigned>(tolerated)));
      m = _mm_min_epu8(ms, mw);
    }
    if constexpr (kMaps) {
      _mm512_storeu_ps(coord + k, _mm512_mask_mov_ps(nan, ok, _mm512_cvtepi32_ps(v)));
      if (valid != nullptr)
        _mm_storeu_si128(reinterpret_cast<__m128i*>(valid + k), _mm_maskz_set1_epi8(ok, static_cast<char>(255)));
    } else {
      _mm512_storeu_si512(out + k, _mm512_mask_mov_epi32(minus1, ok, v));
    }
    if (confidence != nullptr) {
      const __m512 c = _mm512_mul_ps(_mm512_cvtepi32_ps(_mm512_cvtepu8_epi32(m)), _mm512_loadu_ps(inv_c + k));
      _mm512_storeu_ps(confidence + k, _mm512_min_ps(c, one));
    }
  }
  if (i < e) {
    weak_used += decode_code_scalar(s, st, table, i, e, row, i - b, out + (i - b),
                                    confidence != nullptr ? confidence + (i - b) : nullptr);
    if constexpr (kMaps)
      index_maps(out + (i - b), e - i, coord + (i - b), valid != nullptr ? valid + (i - b) : nullptr);
  }
  return weak_used;
}
#endif

}  // namespace

size_t decode_code(const DecodeContext& ctx, size_t c, const WordMap& map, size_t b, size_t e,
                   const BaseRow& row, int32_t* out, float* confidence) {
  const CodeState& st = ctx.s.code(c);
#ifdef PROCAM_SDK_X86
  if (ctx.s.u8() && st.folded[0] > 0 && avx512_active())
    return decode_code_u8_avx512<false>(ctx.s, st, map, b, e, row, out, confidence, nullptr,
                                        nullptr);
  if (ctx.s.u8() && st.folded[0] > 0 && simd_active())
    return decode_code_u8_avx2(ctx.s, st, map, b, e, row, out, confidence);
#endif
  return decode_code_scalar(ctx.s, st, map.table.data(), b, e, row, 0, out, confidence);
}

size_t decode_code_maps(const DecodeContext& ctx, size_t c, const WordMap& map, size_t b,
                        size_t e, const BaseRow& row, int32_t* scratch, float* coord,
                        uint8_t* valid, float* confidence) {
#ifdef PROCAM_SDK_X86
  const CodeState& st = ctx.s.code(c);
  if (ctx.s.u8() && st.folded[0] > 0 && avx512_active())
    return decode_code_u8_avx512<true>(ctx.s, st, map, b, e, row, scratch, confidence, coord,
                                       valid);
#endif
  const size_t weak = decode_code(ctx, c, map, b, e, row, scratch, confidence);
  index_maps(scratch, e - b, coord, valid);
  return weak;
}

uint32_t tolerable_mask(const std::vector<uint8_t>& tolerable, uint32_t bits) {
  uint32_t mask = 0;
  for (uint32_t p = 0; p < bits && p < tolerable.size(); ++p)
    if (tolerable[p] != 0) mask |= 1u << (bits - 1 - p);
  return mask;
}

size_t decode_uncertain(const DecodeContext& ctx, size_t c, const WordMap& words,
                        const UncertainRule& rule, size_t b, size_t e, const BaseRow& row,
                        float* coord, uint8_t* valid, float* uncertainty, FillRow* fill) {
  const BitPlaneStream& s = ctx.s;
  const CodeState& st = s.code(c);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const bool strict_any = st.folded[0] > 0;
  const bool tracked = st.tracked && strict_any;
  const uint8_t* lo = st.wbyte[0].get();
  const uint8_t* hi = st.wbyte[1].get();
  const int32_t* table = words.table.data();
  const float fs = s.full_scale();
  const int32_t scale = std::max(words.scale, 1);  // table value per coordinate unit
  constexpr int kT = CodeState::kTracked;
  size_t used = 0;
  for (size_t i = b; i < e; ++i) {
    const size_t k = i - b;
    // Margins against the pixel's threshold, as the kernels compare them
    // (8-bit: integer margin m is uncertain when m <= gate).
    int n_strict = kT + 1;  // uncertain strict planes (kT + 1: more than tracked)
    bool weak_unc = false, tie = false, clean = true;
    uint32_t word = 0;
    if (!strict_any) n_strict = 0;
    if (strict_any && !tracked)  // no tracking: certain strict planes, or too many to say
      n_strict = (s.u8() ? st.m8[0][i] > row.gate[k] : st.mf[0][i] > row.thr[k]) ? 0 : kT + 1;
    if (s.u8()) {
      const uint8_t g = row.gate[k];
      if (tracked)
        for (int j = 0; j <= kT; ++j)
          if (st.t8[j][i] > g) {
            n_strict = j;
            break;
          }
      weak_unc = st.has_weak && st.m8[1][i] <= g;
      tie = (n_strict > 0 && st.m8[0][i] == 0) || (weak_unc && st.m8[1][i] == 0);
      word = lo[i] | (hi != nullptr ? uint32_t{hi[i]} << 8 : 0u);
    } else {
      const float t = row.thr[k];
      clean = st.flags[i] == 0;
      if (tracked)
        for (int j = 0; j <= kT; ++j)
          if (st.tf[j][i] > t) {
            n_strict = j;
            break;
          }
      weak_unc = st.has_weak && !(st.mf[1][i] > t);
      tie = (n_strict > 0 && !(st.mf[0][i] > 0.0f)) || (weak_unc && !(st.mf[1][i] > 0.0f));
      word = st.word[i];
    }
    bool take = false;
    float centre = nan, half = nan;
    // An exact tie carries no sign: with rule.ties it is enumerated like any
    // uncertain plane, but only where the white is not clipped — a clipped
    // pair (L = L-bar = full scale) ties too, and there no plane can be
    // trusted. Off by default: on the sim's metal lamp (specular) ties are
    // mostly wrong elsewhere too (docs/report/real.md).
    const float white = s.u8() ? static_cast<float>(s.white8()[i]) : s.white_f()[i];
    const bool tie_ok = !tie || (rule.ties && white < fs);
    // The neighbour fill enumerates ties under an unclipped white whatever
    // rule.ties says: there the neighbours, not the tie, choose.
    const bool enumerable = row.base_ok[k] != 0 && clean && (n_strict > 0 || weak_unc) &&
                            n_strict <= kT && (!tie || (white < fs && (rule.fill_ties || rule.ties)));
    int32_t cand[1 << (kT + 2)];  // at most kT strict + 2 tolerable bits (Gray: 1)
    int32_t n_cand = 0;             // candidates kept for the fill
    if (enumerable && (tie_ok || fill != nullptr)) {
      uint32_t mask = weak_unc ? rule.weak_mask : 0u;
      for (int j = 0; j < n_strict; ++j) mask |= 1u << (st.bits - 1 - st.t_plane[j][i]);
      int32_t vlo = std::numeric_limits<int32_t>::max(), vhi = -1, count = 0;
      const bool room = __builtin_popcount(mask) <= kT + 2;
      for (uint32_t sub = mask;; sub = (sub - 1) & mask) {  // every subset, the empty one last
        const int32_t v = table[word ^ sub];
        if (v >= 0) {
          vlo = std::min(vlo, v);
          vhi = std::max(vhi, v);
          if (room) cand[count] = v;
          ++count;
        }
        if (sub == 0) break;
      }
      if (room) n_cand = count;
      // Every candidate a code word (a flip beyond the code's length is no
      // evidence for the others; the one-plane rule before required it of
      // the flipped word too), and contiguous (a flip that jumps is no
      // stripe edge; without it the sim's shower curtain had 8x the gross
      // errors): distinct words have distinct values, so
      // the candidates fill [lo, hi] exactly when there are
      // (hi - lo) / scale + 1 of them.
      if (tie_ok && vhi >= 0 && count == (int32_t{1} << __builtin_popcount(mask)) && (vhi - vlo) / scale + 1 == count) {
        half = 0.5f * static_cast<float>(vhi - vlo) / static_cast<float>(scale);
        centre = 0.5f * static_cast<float>(vlo + vhi) / static_cast<float>(scale);
        take = half <= rule.max_half;
      }
    }
    if (take) {
      coord[k] = centre;
      if (valid != nullptr) valid[k] = 255;
      uncertainty[k] = half;
      ++used;
    } else if (n_strict > 0 || weak_unc) {  // uncertain and not resolved: invalid
      if (fill != nullptr && n_cand > 0) {
        std::sort(cand, cand + n_cand);
        fill->x.push_back(static_cast<uint32_t>(k));
        fill->v.insert(fill->v.end(), cand, cand + n_cand);
        fill->begin.push_back(static_cast<uint32_t>(fill->v.size()));
      }
      coord[k] = nan;
      if (valid != nullptr) valid[k] = 0;
      uncertainty[k] = nan;
    } else {
      uncertainty[k] = std::isnan(coord[k]) ? nan : 0.0f;
    }
  }
  return used;
}

}  // namespace procam::sl
