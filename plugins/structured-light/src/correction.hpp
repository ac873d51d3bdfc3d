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

// What the §3.4 stop rule looks at after a round.
struct CorrectionProgress {
  bool ensemble = true;             // more than one code (single codes never correct)
  uint32_t max_rounds = 0;          // correction_rounds parameter
  uint32_t rounds_done = 0;         // correction rounds run so far
  bool can_triangulate = false;     // the mask needs each resolved pixel's projector pixel
  size_t errors = 0, lit = 0;       // after the last round
  size_t resolved_last = 0;         // pixels the last correction round resolved
  double min_progress = 0.0005;     // fraction of lit pixels
};

struct CorrectionDecision {
  bool more = false;                // run another correction round
  const char* stop_reason = nullptr;  // why not (null: correction is off, nothing to report)
};

// §3.4 stop rule: another round only for the ensemble, with a calibrated rig,
// error pixels left, the round limit not reached, and progress in the last
// round (errors and, after the first correction, resolved pixels at least
// min_progress of lit pixels).
CorrectionDecision decide_correction(const CorrectionProgress& p);

// 1 where an error pixel (cls == kError) lies within `radius` camera px
// (square window, Chebyshev distance), else 0: a separable max filter.
std::vector<uint8_t> near_error(const std::vector<uint8_t>& cls, size_t width, size_t height,
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

// Merges a correction round's vote `v` into the running maps: only pixels
// still in error take the new result, and only where their new column is
// clear_of_mask() and the masked white frame (masked_white, white / full
// scale) keeps at least kCorrectionMinLight of the round-1 white light
// (round1_white). A pixel whose own projector pixel was switched off sees
// only light scattered in from the unmasked side and decodes to a column at
// the mask's edge; it stays an error. Returns the number of pixels resolved.
size_t merge_correction(const sdk::Rig& rig, const std::vector<uint8_t>& mask, const VoteMaps& v,
                        const std::vector<float>& masked_white,
                        const std::vector<float>& round1_white, std::vector<float>& coord,
                        std::vector<uint8_t>& valid, std::vector<float>& confidence,
                        std::vector<uint8_t>& cls);

}  // namespace procam::sl
