// SPDX-License-Identifier: MIT
// Per-frame binarization of bit planes (thesis §3.2, Eq. 3.1–3.5), streamed:
// each plane is folded into per-pixel state as soon as its image and its
// reference (the inverse image, or white + black) are available
// (bitplane_stream.hpp drives it).
//
// Binarization rule (Eq. 3.5): a pixel is "lit" in plane P when L > L̄, where
// L is the image under P and L̄ the image under the inverse pattern P̄. With
// direct light only (L_g = 0, α = 1, Eq. 3.3–3.4) L - L̄ = ±L_d, so the margin
// |L - L̄| equals the pixel's contrast white - black; global light and defocus
// shrink it (α ≈ 0.5, β ≈ 0.5), which is why the margin is kept per pixel and
// small margins are rejected at decode time (decode.hpp).
//
// Synthetic inverse (binarize "white"): footnote 2 of §3.2 forms L̄ = white - L.
// With a projector black level and ambient light (both present in the black
// image B) and linear light transport, the image of P̄ is exactly
// W + B - L: the light of P and P̄ adds up to the light of the white pattern
// (W - B) on top of the black frame B, i.e. L + L̄ = (W - B) + 2B. The
// footnote's form is the special case B = 0.
//
// Per-pixel state of one code: `word` (bit `position` set where L > L̄; ties
// give bit 0), the min over folded planes of the margin |L - L̄| (in input
// units) and, for float input, flags. Two kernel families, same results:
//  - 8-bit (U8, bit_depth 8): integer math on the raw bytes, never converted
//    to float. Synthetic: L - L̄ = 2L - (W + B) exactly. The margin is kept as
//    uint8, saturated at 255 (full scale): every use of it is unchanged by
//    that (contrast C = W - B <= 255, so min(margin / C, 1) = 1 and
//    margin > t * C for t <= 1 either way; the one case t = 1, C = 255 has
//    |2L - S| <= 255, no saturation). No flags: for integer samples <= full
//    scale, "L and L̄ both clipped" means L = L̄ = 255 (margin 0: rejected,
//    also on a tolerated weak plane, decode.hpp), and with the synthetic
//    inverse it needs W + B >= 510, i.e. C = 0 (rejected by rule 1).
//    The word is kept as a low and a high byte array (planes at bit
//    positions 0-7 / 8-15). AVX-512 and AVX2 kernels (chosen at run time,
//    __builtin_cpu_supports) and portable scalar kernels give bit-identical
//    state (kernels_test.cpp).
//  - float (U16, F32, U8 with bit_depth < 8): rows converted to float, margin
//    float, flags saturated / non-finite.
// `first`: the plane is the first folded into this margin array — the margin
// is stored instead of min-ed; `first_word`: the first plane of the word —
// the word is stored instead of OR-ed (the arrays need no initialisation).
// Thread-safety: functions are reentrant; callers partition pixels by band.
#pragma once

#include <cstddef>
#include <cstdint>

namespace procam::sl {

// Flags a pixel can collect while planes are folded in (float kernels).
enum PixelFlag : uint8_t {
  kFlagSaturated = 1,  // some plane had both L and L̄ at or above saturation
  kFlagNonFinite = 2,  // some plane had a NaN/inf value (F32 input)
};

// Float kernel: word |= (L > L̄) << position; min_margin = min(min_margin,
// |L - L̄|) (a NaN margin never lowers it; initialise min_margin to +inf);
// flags |= saturated / non-finite. `saturation` = full scale.
void fold_plane(const float* L, const float* L_bar, size_t n, uint32_t position, float saturation,
                uint16_t* word, float* min_margin, uint8_t* flags);

// 8-bit kernels: word byte |= (L > L̄) << position (0..7; a code's word is
// kept as a low and a high byte array, so a fold moves 1 byte per pixel of
// word state, not 2) and the margin (saturated at 255, see above) folded
// into min_margin, for n pixels. Synthetic:
// L̄ = W + B - L (B == nullptr: B = 0). Inverse: L̄ given.
void fold_u8_synthetic(const uint8_t* L, const uint8_t* W, const uint8_t* B, size_t n,
                       uint32_t position, bool first, bool first_word, uint8_t* word,
                       uint8_t* min_margin);
void fold_u8_inverse(const uint8_t* L, const uint8_t* L_bar, size_t n, uint32_t position,
                     bool first, bool first_word, uint8_t* word, uint8_t* min_margin);

// The portable scalar versions of the 8-bit kernels (what the dispatching
// functions above run without AVX2 / AVX-512); exposed for the equivalence test.
void fold_u8_synthetic_scalar(const uint8_t* L, const uint8_t* W, const uint8_t* B, size_t n,
                              uint32_t position, bool first, bool first_word, uint8_t* word,
                              uint8_t* min_margin);
void fold_u8_inverse_scalar(const uint8_t* L, const uint8_t* L_bar, size_t n, uint32_t position,
                            bool first, bool first_word, uint8_t* word, uint8_t* min_margin);
// True when the AVX2 kernels (binarize, decode, vote) run: the CPU has AVX2
// and they are not disabled. avx512_active(): the AVX-512 (F + BW + VL)
// kernels run instead — the CPU has them and neither hook disabled them;
// same results as AVX2 and scalar. set_simd_enabled(false) is a test hook
// that forces the portable scalar kernels, set_avx512_enabled(false) one that
// forces AVX2 (where present); not to be called while decoding.
bool simd_active();
bool avx512_active();
void set_simd_enabled(bool enabled);
void set_avx512_enabled(bool enabled);

// out[i] = clamp(src[i] * inv_scale, 0, 1) for n 8-bit pixels (the intensity
// map of the white frame, inv_scale = 1 / full scale); AVX-512 where active,
// identical results.
void intensity_u8(const uint8_t* src, size_t n, float inv_scale, float* out);

// Uncertain-plane tracking (decode.hpp, decode_uncertain): per pixel the
// kTrackedPlanes smallest margins over a code's strict planes in ascending
// order, m[0] <= m[1] <= m[2], the planes p[0..2] they came from, and the
// next smallest m[3] — so "exactly planes p[0..j-1] are uncertain" is
// m[j-1] <= thr < m[j], j <= 3. 8-bit: margins saturated at 255 as above,
// d = L - L̄ (inverse) or 2L - W - B (synthetic, B may be null); float: a NaN
// margin never lowers them. `first`: the first strict plane of the code
// (stored, the others = max). Plain loops without branches (the vectorizer
// compiles them); no intrinsics, so there is no SIMD twin to keep identical.
inline constexpr int kTrackedPlanes = 3;
template <class T>
struct TrackRow {
  T* m[kTrackedPlanes + 1];      // ascending margins, then the next smallest
  uint8_t* p[kTrackedPlanes];    // plane of m[j]
  // The row at pixel offset `off` of per-pixel arrays (anything with get()).
  template <class A, class P>
  static TrackRow at(A (&m)[kTrackedPlanes + 1], P (&p)[kTrackedPlanes], size_t off) {
    TrackRow r{};
    for (int j = 0; j <= kTrackedPlanes; ++j) r.m[j] = m[j].get() + off;
    for (int j = 0; j < kTrackedPlanes; ++j) r.p[j] = p[j].get() + off;
    return r;
  }
};
void track_u8(const uint8_t* L, const uint8_t* R, const uint8_t* B, bool synthetic, size_t n,
              uint8_t plane, bool first, const TrackRow<uint8_t>& t);
void track_f(const float* L, const float* L_bar, size_t n, uint8_t plane, bool first,
             const TrackRow<float>& t);

// L̄ = W + B - L for n pixels (synthetic inverse, see above; B may be null = 0).
void synthesize_inverse(const float* L, const float* white, const float* black, size_t n,
                        float* L_bar);

}  // namespace procam::sl
