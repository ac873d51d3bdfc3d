// SPDX-License-Identifier: MIT
// Per-pixel decode of an accumulated code: binarized word -> projector
// coordinate, with the validity rules and a confidence per pixel.
//
// A pixel is valid only when all of these hold (otherwise it is reported
// invalid rather than guessed):
//   1. white W and black B are finite and the contrast C = W - B is positive
//      and at least min_contrast_abs (shadowed / unlit / low-albedo pixels);
//   2. no plane was saturated (L and L̄ both clipped) or non-finite;
//   3. every plane's margin |L - L̄| exceeds min_bit_margin * C (near ties;
//      under direct light the margin equals C, Eq. 3.3–3.5 with α = 1, L_g = 0);
//   4. the word is a code word of a coordinate < length (e.g. column < W).
// confidence = min over planes of |L - L̄| / C, clipped to [0, 1] (0 where
// C <= 0 or values are not finite), reported for every pixel.
// Thread-safety: reentrant; callers partition pixels by band.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "binarize.hpp"
#include "stripe_code.hpp"

namespace procam::sl {

struct DecodeThresholds {
  float min_contrast_abs = 0.0f;  // rule 1, in input units (min_contrast * full scale)
  float min_bit_margin = 0.1f;    // rule 3, fraction of the contrast
};

// Decodes pixels [begin, end) of `acc` (whose planes are all folded in).
// Writes coord[i] (the integer coordinate as float, NaN when invalid),
// valid[i] (255 / 0) and confidence[i] (see above).
void decode_pixels(const BitAccumulator& acc, const StripeCode& code, const float* white,
                   const float* black, size_t begin, size_t end, const DecodeThresholds& t,
                   float* coord, uint8_t* valid, float* confidence);

}  // namespace procam::sl
