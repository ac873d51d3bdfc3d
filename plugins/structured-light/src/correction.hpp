// SPDX-License-Identifier: MIT
// Error-correction rounds of the ensemble (thesis §3.4, after Xu & Aliaga):
// pixels left as errors (no two codes agree) are re-measured in another round
// while the projector pixels of already-resolved points are switched off,
// removing their global light. This file holds the algorithm — the stop rule,
// the projector mask, and which re-measured pixels may take their new column —
// so it is tested without a session; codes_session.cpp only calls it.
//
// Geometry: camera 0 and the projector of `rig` must be calibrated
// (rig.can_triangulate(0)); a camera pixel i = v * width + u that decoded to
// projector column `col` is triangulated (procam::triangulate_column) and
// projected into the projector (pixel centres at integers, rounded).
// Maps: row-major camera maps of width * height (cls: vote.hpp TransportClass,
// valid: 255 / 0, coord: column, NaN = invalid); masks: projector W * H,
// 255 = may be lit, 0 = switched off.
// Thread-safety: reentrant (pure functions of their arguments).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "procam/plugin_sdk.hpp"
#include "vote.hpp"

namespace procam::sl {

// A new value is taken only if the projector pixels within this distance (px)
// of the one it names are all still on, and the masked white frame still gives
// the pixel this fraction of its round-1 white light (merge_correction()).
// 0.35: masking removes the global light the round is for — on the glossy
// lamp a flagged pixel keeps 0.20–0.34 of its round-1 light (global/direct
// 2.8 -> 0.10), and 0.5 rejected nearly all; light scattered in from
// centimetres away (wax) stays far below it.
inline constexpr int64_t kCorrectionEdgeMarginPx = 2;
inline constexpr float kCorrectionMinLight = 0.35f;
// ... and the mask must have taken away at least this fraction of the
// pixel's round-1 white light: a pixel whose light did not change kept the
// global light that made its codes disagree, so a different answer in the
// masked round is chance, not a correction. 0.1: the white ratio of an 8-bit
// pixel at 100–200 DN carries 1–2 % shot + read noise (docs/sim.md sensor
// model), so 10 % is a change, not noise, at 5 sigma.
inline constexpr float kCorrectionMinDrop = 0.1f;
// ... and the new column must lie within this many columns of the estimate
// from its row (row_column_estimate(), valid pixels within
// kCorrectionNeighbourReachPx), where there is one: 6 camera px at the
// 1.1-1.5 projector px per camera px of the sim rig's geometry plus 2 px of
// slack; a mirror path lands tens of columns away.
inline constexpr uint32_t kCorrectionNeighbourReachPx = 6;
inline constexpr float kCorrectionNeighbourPx = 10.0f;

// Flagged pixels: what a correction round re-measures — errors (no two codes
// agree) and conflicts (label_conflicts()).
inline bool flagged(uint8_t cls) { return cls == kError || cls == kConflict; }

// Conflict rule (issue 18; applied after the vote, outside its SIMD kernels):
// a valid pixel whose vote rests on exactly two agreeing codes, gray and one
// XOR code, while a third valid code disagrees with them, is set invalid
// (class kConflict). XOR-02/04 planes are Gray planes XOR a base plane, so
// those two codes share the Gray structure and their errors are correlated:
// under a strong second light path (a mirror reflection, a glossy
// inter-reflection) they can both decode the same wrong column, and their
// agreement against an independent dissenting code is no evidence. On the
// development scenes (corner-wax, glossy-pipe, metal-lamp, marble-slab) such
// pixels were wrong 976 of 1265 times on the lamp and in every case on the
// corner and the pipe. Every other vote (the thesis's XOR pair, the Gray
// pair, 3–4 agreeing codes) stands. code[k]: column maps in vote.hpp order
// (NaN = invalid). Pixels [begin, end). Returns the number set to kConflict.
size_t label_conflicts(const float* const code[kEnsembleCodes], float agree_px, size_t begin,
                       size_t end, float* coord, uint8_t* valid, float* confidence, uint8_t* cls);
// The same rule on the vote's integer keys (vote.hpp vote_keys: key = 2 x
// column, -1 = invalid; agree2 = agree_key_threshold(agree_px)), pixels
// [0, n) of the maps: identical labels to label_conflicts on the maps
// key / 2 (NaN where key < 0) for every valid (so lit) pixel. finish_vote
// applies it in the vote's own pass (VoteSpec::conflicts), so the ensemble
// needs no per-code maps for it (issue 17).
size_t label_conflicts_keys(const int32_t* const key[kEnsembleCodes], int32_t agree2, size_t n,
                            float* coord, uint8_t* valid, float* confidence, uint8_t* cls);

// What the three-frame probe of codes_session.cpp (the next round's masked
// white Wm, masked finest xor02 plane L and its inverse L̄, stripes 2 px
// wide, all / full scale) says about a correction round before it is
// projected. Per flagged pixel, with r = Wm / round-1 white:
//   r < kCorrectionMinLight, or     own projector pixel switched off: unfixable
//   its column estimate (the valid  (merge_correction() would reject any answer
//   pixels beside it in its row)    next to the mask)
//   is not clear_of_mask()
//   r > 1 - kCorrectionMinDrop      the mask took none of its global light away
//   |L - L̄| < min_margin * Wm       its finest stripes still have too little
//                                   direct contrast under the mask: short-range
//                                   light (sub-surface, defocus), ambient or
//                                   noise the mask cannot remove
//   otherwise                       fixable: own light kept, global light gone
// With stripes 2 px wide, |L - L̄| ~ D (the direct light, Nayar et al.'s
// separation, thesis §2) and Wm = D + G' + ambient, so min_margin = 0.5 asks
// for D >= G' + ambient: the pixel is direct-dominated once masked, which is
// what every code needs to agree (Eq. 3.5, global light split evenly).
// merge_correction() then accepts only all-four-agree answers, so the
// forecast is an upper bound on what the round resolves.
//
// Too dark under the mask (issue 18, session 13): the masked round decodes
// a pixel only where its contrast C = Wm - B reaches min_contrast (decode.hpp
// rule 1, the same decoder and threshold as every round; B = 0 without a
// black frame, as the decoder assumes, else the probe's own B = L + L̄ - Wm,
// pattern + inverse = white + black). A pixel below it gets no answer from
// the round, whatever the other tests say: verdict "too dark", tested right
// after "own light off". Where this mattered: the chrome dish of
// val2-chrome-dish-post (diffuse albedo 0.03, lit mostly by its mirror path)
// has round-1 whites of ~10 DN; the mask halves them to ~5 DN, under the
// 7.65 DN of min_contrast 0.03, while noise and the mirror's own stripes pass
// the ratio and stripe tests (2 910 of the 3 532 pixels the probe called
// fixable; the round answered none of them).
struct RoundForecast {
  size_t flagged = 0, own_light_off = 0, unchanged = 0, blurred = 0, fixable = 0;
  size_t too_dark = 0;  // Wm - B < min_contrast: the masked round cannot decode it
  size_t lit = 0;
  double predicted_gain() const {  // fixable / lit pixels
    return lit > 0 ? static_cast<double>(fixable) / static_cast<double>(lit) : 0.0;
  }
};
RoundForecast forecast_round(const sdk::Rig& rig, const std::vector<uint8_t>& mask,
                             const std::vector<float>& coord,
                             const std::vector<uint8_t>& cls, const std::vector<uint8_t>& lit,
                             const std::vector<float>& masked_white,
                             const std::vector<float>& round1_white,
                             const std::vector<float>& masked_plane,
                             const std::vector<float>& masked_inverse, float min_margin,
                             float min_contrast, bool black_frame,
                             std::vector<uint8_t>* per_pixel = nullptr);
// min_contrast: the decoder's (fraction of full scale, like the frames);
// black_frame: the round projects a black frame (then B is estimated as above).
// per_pixel (optional, resized to cls.size()): 0 not flagged, then 1 own light
// off, 2 unchanged, 3 fine stripes lost, 4 fixable, 5 too dark under the mask.
// Tests in order 1, 5, 2, 3; the first that holds decides. An empty mask
// skips the column test (no rig geometry needed: unit tests of the light
// rules).

// Column estimate of camera pixel i for the forecast: linear interpolation
// between the nearest valid pixels (coord not NaN) left and right of it in its
// row within `reach` px, or the one found; NaN when there is none.
float row_column_estimate(const std::vector<float>& coord, size_t width, size_t i, uint32_t reach);
// True for a flagged pixel the forecast counts as fixable (r in range).
bool fixable_pixel(float masked_white, float round1_white);

// What the §3.4 stop rule looks at after a round.
struct CorrectionProgress {
  bool ensemble = true;             // more than one code (single codes never correct)
  uint32_t max_rounds = 0;          // correction_rounds parameter
  uint32_t rounds_done = 0;         // correction rounds run so far
  bool can_triangulate = false;     // the mask needs each resolved pixel's projector pixel
  size_t errors = 0, lit = 0;       // after the last round (errors: flagged pixels)
  size_t resolved_last = 0;         // pixels the last correction round resolved
  double min_progress = 0.0005;     // fraction of lit pixels
  double acceptance_last = 1.0;     // accepted / fixable of the last correction round
  double min_acceptance = 0.7;      // below: the round is discarded and correcting stops
};

struct CorrectionDecision {
  bool more = false;                // run another correction round
  const char* stop_reason = nullptr;  // why not (null: correction is off, nothing to report)
};

// §3.4 stop rule, before the probe: another round only for the ensemble,
// with a calibrated rig, flagged pixels left (errors + conflicts, at least
// min_progress of lit pixels), the round limit not reached, and, after a
// correction round, progress (resolved >= min_progress of lit pixels) at an
// acceptance rate (accepted / fixable) of at least min_acceptance: a round
// whose masked answers mostly fail merge_correction()'s tests is not
// fixing what it was predicted to fix, and another one would not either.
CorrectionDecision decide_correction(const CorrectionProgress& p);

// 1 where a flagged pixel (errors and conflicts) lies within `radius` camera px
// (square window, Chebyshev distance), else 0: a separable max filter.
std::vector<uint8_t> near_flagged(const std::vector<uint8_t>& cls, size_t width, size_t height,
                                uint32_t radius);

// Projector mask of a correction round: every valid camera pixel that is not
// within guard_px of an error pixel is triangulated, projected into the
// projector, and the projector pixels within dilate_px (square) of it are
// switched off. Guarded pixels stay on: the camera samples the projector more
// densely than one pixel per pixel, so a resolved neighbour names the error
// pixel's own projector pixel (without the guard 87 % of the lamp's error
// pixels were switched off with their neighbours and a round resolved none).
std::vector<uint8_t> correction_mask(const sdk::Rig& rig, const std::vector<float>& coord,
                                     const std::vector<uint8_t>& valid,
                                     const std::vector<uint8_t>& cls, uint32_t dilate_px,
                                     uint32_t guard_px);

// True when the projector pixel that camera pixel i decoded to `col` names,
// and every projector pixel within kCorrectionEdgeMarginPx of it, were on in
// `mask`; false when it cannot be located.
bool clear_of_mask(const sdk::Rig& rig, const std::vector<uint8_t>& mask, size_t i, float col);

// Merges a correction round's vote `v` into the running maps. A flagged pixel
// takes the new result only when every test that needs no ground truth
// passes (issue 18: a round must never make things worse):
//  - it is fixable_pixel(): the masked white frame (masked_white, white /
//    full scale) keeps at least kCorrectionMinLight of its round-1 white light
//    (round1_white) — a pixel whose own projector pixel was switched off sees
//    only light scattered in from the unmasked side and decodes to a column at
//    the mask's edge — and lost at least kCorrectionMinDrop of it;
//  - all four codes agree in the masked round (class kAllAgree): with its
//    global light gone the pixel must look like a direct-light pixel; a
//    masked pair or triple was wrong 14 % (partial) and 1.8 % (Gray pair) of
//    the time on the development scenes, all-four 0.02 % on the lamp;
//  - the new column is clear_of_mask();
//  - it agrees with its row's valid neighbours (row_column_estimate() within
//    kCorrectionNeighbourPx), where it has any: global light is smooth, so a
//    pixel that the first pass lost among valid neighbours lies between them.
//
// Re-check of first-pass claims (issue 18, session 14; recheck_claims, on by
// default; docs/structured-light.md "Error correction rounds", rule 3): the
// masked round re-decodes the first pass's valid pixels too. A valid,
// unflagged pixel that decodes in the round with all four codes agreeing
// (kAllAgree) more than kRefutedMovePx columns from its first-pass column
// (its claim) is *refuted*: a right claim is the pixel's direct light, and
// the mask only removes light, so either the claim's projector pixel is
// still on and the claim would still win, or it was switched off and the
// pixel keeps only global light, which does not make four codes of
// different structure agree on one column (the assumption; it fails where a
// strong glossy path from one column remains: val2's satin post). So the
// claim came from a global (mirror) path, whose source the mask switched
// off. The pixel takes the round's column when that passes the flagged
// pixels' geometric tests (clear_of_mask(), and the row-neighbour test
// against the row's valid pixels that are not refuted themselves); else it
// becomes invalid (kError), never keeping a column known to be a mirror's.
// The flagged pixels' neighbour test then reads the map with the refuted
// pixels already replaced: next to a mirror the first pass's neighbours are
// wrong together (session 14: 1 182 of the copper tube's 1 305 right masked
// answers were refused by it).
// Returns the number of flagged pixels resolved; counts (optional) gets the
// refuted ones; undo (optional) gets the previous values of every pixel the
// merge changed, to take the round back.
inline constexpr float kRefutedMovePx = 2.0f;
struct MergeCounts {
  size_t resolved = 0;       // flagged pixels that took a new column
  size_t refuted = 0;        // valid pixels whose claim the round refuted
  size_t refuted_moved = 0;  // ... of them, took the round's column (others: invalid)
};
struct MergeUndo {
  size_t i;
  float coord, confidence;
  uint8_t valid, cls;
  bool was_flagged;  // a flagged pixel resolved (else a refuted claim)
};
size_t merge_correction(const sdk::Rig& rig, const std::vector<uint8_t>& mask, const VoteMaps& v,
                        const std::vector<float>& masked_white,
                        const std::vector<float>& round1_white, std::vector<float>& coord,
                        std::vector<uint8_t>& valid, std::vector<float>& confidence,
                        std::vector<uint8_t>& cls, bool recheck_claims = true,
                        MergeCounts* counts = nullptr, std::vector<MergeUndo>* undo = nullptr);

}  // namespace procam::sl
