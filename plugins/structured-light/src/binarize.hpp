// SPDX-License-Identifier: MIT
// Per-frame binarization of bit planes (thesis §3.2, Eq. 3.1–3.5), streamed:
// each plane is folded into a per-pixel accumulator as soon as its image and
// its reference (the inverse image, or white + black) are available.
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
// Thread-safety: functions are reentrant; callers partition pixels by band.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace procam::sl {

// Flags a pixel can collect while planes are folded in.
enum PixelFlag : uint8_t {
  kFlagSaturated = 1,  // some plane had both L and L̄ at or above saturation
  kFlagNonFinite = 2,  // some plane had a NaN/inf value (F32 input)
};

// Per-pixel state of one code (one axis) across its planes.
struct BitAccumulator {
  uint32_t bits = 0;
  std::vector<uint16_t> word;        // bit `position` set where L > L̄ (codes have <= 16 bits)
  std::vector<float> min_margin;     // min over folded planes of |L - L̄| (input units)
  std::vector<uint8_t> flags;        // PixelFlag bits
  std::vector<uint8_t> plane_done;   // per plane: folded in

  void reset(size_t pixels, uint32_t plane_count) {
    bits = plane_count;
    word.assign(pixels, 0);
    min_margin.assign(pixels, std::numeric_limits<float>::infinity());
    flags.assign(pixels, 0);
    plane_done.assign(plane_count, 0);
  }
};

// Folds one plane into pixels [0, n) of the accumulator arrays (pass pointers
// offset to a band): word |= (L > L̄) << position; min_margin = min(min_margin,
// |L - L̄|); flags |= saturated / non-finite. `saturation` is the value at
// which a sample counts as clipped (full scale). Ties (L == L̄) give bit 0
// with margin 0, which decode() rejects.
void fold_plane(const float* L, const float* L_bar, size_t n, uint32_t position, float saturation,
                uint16_t* word, float* min_margin, uint8_t* flags);

// Fast path of fold_plane for 8-bit frames with the synthetic inverse:
// L̄ = S - L with S = W + B (per pixel, integer), so L - L̄ = 2L - S exactly —
// the same word, margin and flags as fold_plane on the float values, without
// converting the frame. `saturation` is the integer full scale.
void fold_plane_u8_synthetic(const uint8_t* L, const uint16_t* sum, size_t n, uint32_t position,
                             int32_t saturation, uint16_t* word, float* min_margin,
                             uint8_t* flags);

// L̄ = W + B - L for n pixels (synthetic inverse, see above).
void synthesize_inverse(const float* L, const float* white, const float* black, size_t n,
                        float* L_bar);

}  // namespace procam::sl
