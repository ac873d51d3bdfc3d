// SPDX-License-Identifier: MIT
// Ensemble vote, light-transport classification and error detection
// (thesis §3.3.3 and §3.4; TECHNIQUES.md C4–C6).
//
// Inputs per pixel: the projector columns decoded by the four codes in the
// order gray, xor02, xor04, minsw (NaN = that code's decode was invalid) and
// whether the pixel is lit (passes the contrast rule). Two codes *agree* when
// both are valid and |a − b| <= agree_px.
// Vote (C4): support(i) = number of other codes agreeing with code i.
//   - no code has support          -> error pixel (C6), invalid, class kError
//     (or kUnlit when the pixel is not lit);
//   - the only agreeing pair is {gray, minsw}  -> minsw's value, kSubsurface
//     (thesis: "if only the two Gray codes agree, return min-SW's value");
//   - the only agreeing pair is {xor02, xor04} -> xor04's value, kInterreflection;
//   - otherwise the value of the first code, in the order gray, xor04, xor02,
//     minsw, among those with the largest support; kAllAgree when all four
//     agree pairwise, else kPartial.
// confidence = (max support + 1) / 4 for valid pixels (0.5, 0.75, 1), else 0.
// Classification (C5): kAllAgree = direct light dominates; kInterreflection =
// only the logical (XOR) codes agree, long-range effects; kSubsurface = only
// the Gray codes agree, short-range effects (sub-surface scattering/defocus).
// Thread-safety: reentrant; callers partition pixels by band.
#pragma once

#include <cstddef>
#include <cstdint>

namespace procam::sl {

enum TransportClass : uint8_t {
  kUnlit = 0,
  kAllAgree = 1,
  kInterreflection = 2,
  kSubsurface = 3,
  kPartial = 4,
  kError = 5,
};
inline constexpr uint32_t kTransportClassCount = 6;
const char* transport_class_name(uint8_t c);

enum EnsembleCode : uint32_t { kGray = 0, kXor02 = 1, kXor04 = 2, kMinsw = 3, kEnsembleCodes = 4 };

// Votes pixels [begin, end). code[k] points at code k's column map.
void vote_pixels(const float* const code[kEnsembleCodes], const uint8_t* lit, size_t begin,
                 size_t end, float agree_px, float* coord, uint8_t* valid, float* confidence,
                 uint8_t* cls);

}  // namespace procam::sl
