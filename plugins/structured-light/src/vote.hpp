// SPDX-License-Identifier: MIT
// Ensemble vote, light-transport classification and error detection
// (thesis §3.3.3 and §3.4; docs/techniques.md C4–C6).
//
// Inputs per pixel: the projector columns decoded by the four codes in the
// order gray, xor02, xor04, minsw (NaN = that code's decode was invalid) and
// whether the pixel is lit (passes the contrast rule). Two codes *agree* when
// both are valid and |a − b| <= agree_px.
// Vote (C4): support(i) = number of other codes agreeing with code i.
//   - no code has support          -> error pixel (C6), invalid, class kError
//     (or kUnlit when the pixel is not lit);
//   - the only agreeing pair is {gray, minsw}  -> minsw's value, kSubsurface
//     (thesis: "if only the two Gray codes agree, return min-SW's value"),
//     except when the two are a full agree_px apart: then their midpoint
//     (issue 18, session 15). Both are taken to lie within agree_px of the
//     truth; a column apart, the values within a column of both are the
//     span between them, and min-SW's value is its far end from gray:
//     where sub-surface light shifts min-SW's wide stripe edge by one code
//     column (1.25 projector columns at W = 1280) it is 1.5 off, the
//     midpoint 1 (val4-milkglass-soap-stack's skin cylinder: 79 of its
//     353 such pixels wrong, 5 with the midpoint);
//   - otherwise the *pick* is the first code, in the order gray, xor04, xor02,
//     minsw, among those with the largest support, and the value is the
//     median of the pick and every code agreeing with it when they are 3 or
//     4, else (2 codes) their midpoint; kInterreflection when the
//     only agreeing pair is {xor02, xor04}, kAllAgree when all four agree
//     pairwise, else kPartial.
//   Why the median: each code quantizes the column at its own stripe edges,
//   so at a camera pixel straddling two projector columns the agreeing codes
//   split between them (e.g. 1115, 1116, 1116, 1115.5 at a true 1116.2): the
//   first code's value can be a column off, their median 1115.75 is not. A
//   median, not a mean, so that a member agreeing with the pick only at the
//   edge of agree_px (2 columns from the others) does not pull the value.
//   Two members (issue 18): their midpoint, not the preferred code's value —
//   two codes a column apart straddle the truth; the midpoint is <= 0.5
//   from either (marble-slab: 3 084 -> 2 810 gross pixels). The session
//   then reports, where the vote is not unanimous, the row-refined column
//   instead (codes_session.cpp outputs()); this value is its fallback.
// confidence = (max support + 1) / 4 for valid pixels (0.5, 0.75, 1), else 0.
// Classification (C5): kAllAgree = direct light dominates; kInterreflection =
// only the logical (XOR) codes agree, long-range effects; kSubsurface = only
// the Gray codes agree, short-range effects (sub-surface scattering/defocus).
// Thread-safety: reentrant; callers partition pixels by band.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace procam::sl {

enum TransportClass : uint8_t {
  kUnlit = 0,
  kAllAgree = 1,
  kInterreflection = 2,
  kSubsurface = 3,
  kPartial = 4,
  kError = 5,
  kConflict = 6,  // invalid: only a correlated pair agrees against a dissenting code
                  // (label_conflicts(), correction.hpp); never written by the vote itself
};
inline constexpr uint32_t kTransportClassCount = 7;
const char* transport_class_name(uint8_t c);

enum EnsembleCode : uint32_t { kGray = 0, kXor02 = 1, kXor04 = 2, kMinsw = 3, kEnsembleCodes = 4 };

// Ensemble outputs of one round (width * height, row-major).
struct VoteMaps {
  std::vector<float> coord;       // voted projector column, NaN where invalid
  std::vector<uint8_t> valid;     // 255 / 0
  std::vector<float> confidence;  // (max support + 1) / 4, 0 where invalid
  std::vector<uint8_t> cls;       // TransportClass
};

// Votes pixels [begin, end). code[k] points at code k's column map.
void vote_pixels(const float* const code[kEnsembleCodes], const uint8_t* lit, size_t begin,
                 size_t end, float agree_px, float* coord, uint8_t* valid, float* confidence,
                 uint8_t* cls);

// The same vote on integer keys, branch-free: key = 2 x projector column
// (columns are integers or span centres, i.e. multiples of 0.5), -1 = invalid.
// Two codes agree when both keys are >= 0 and |a - b| <= agree2, with
// agree2 = floor(2 * agree_px) — exactly |a/2 - b/2| <= agree_px, so the
// outputs equal vote_pixels' on the columns key / 2 (vote_test in
// ensemble_test.cpp). Pixels [0, n) of the given pointers. AVX-512 / AVX2
// kernels where active (binarize.hpp), identical outputs (kernels_test.cpp).
void vote_keys(const int32_t* const key[kEnsembleCodes], const uint8_t* lit, size_t n,
               int32_t agree2, float* coord, uint8_t* valid, float* confidence, uint8_t* cls);
int32_t agree_key_threshold(float agree_px);  // floor(2 * agree_px), agree_px >= 0

// Per-pixel counts of final ensemble maps (multi_round.hpp VoteSpec::count):
// lit != 0, valid != 0, flagged (cls kError or kConflict: correction.hpp
// flagged()) and the transport-class histogram, classes >= kTransportClassCount - 1
// in the last entry.
struct PixelCounts {
  size_t lit = 0, valid = 0, flagged = 0;
  size_t cls[kTransportClassCount] = {};
};
// Adds pixels [0, n) of the three maps to `c`. AVX-512 (64 pixels per step,
// mask popcounts) where active (binarize.hpp), else scalar; the same counts
// (kernels_test.cpp). Issue 17: the scalar histogram was ~1 ms of the vote
// pass at 1920x1200.
void count_classes(const uint8_t* lit, const uint8_t* valid, const uint8_t* cls, size_t n, PixelCounts& c);

// The column the ensemble reports (issue 18, session 11; docs/structured-
// light.md "Ensemble vote"): where the vote is not unanimous (valid and
// confidence < 1), coord becomes the row-refined column `refined`
// (refine_columns, subpixel.hpp: clamped to +-1 column of the vote, the
// vote's value where the row has no consistent neighbours) rounded to the
// nearest half column, and then clamped to within 0.5 of the vote's value
// (issue 18, session 15); unanimous pixels keep their median. Why 0.5: the
// refinement corrects a shared code bias of about half a column (marble:
// no pixel needs more), but a line fit whose 11-pixel window crosses a
// crease follows the other face's slope and, at the old +-1 clamp, moved
// right votes a full column off (val4-near-box-far-floor: 307 of its 308
// wrong pixels had a right vote, 47 wrong with the 0.5 clamp). Pixels [0, n).
// AVX-512 where active (binarize.hpp), else scalar; the same bits
// (kernels_test.cpp).
void report_columns(float* coord, const uint8_t* valid, const float* confidence, const float* refined,
                    size_t n);

}  // namespace procam::sl
