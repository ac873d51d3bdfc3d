// SPDX-License-Identifier: MIT
// Neighbour-consistent candidate selection (issue 16): a second look at the
// pixels decode_uncertain rejected although their own bits name a few
// candidate coordinates (too many uncertain planes for a narrow interval, a
// gap between the candidates, or an exact tie).
//
// Rule, per rejected pixel p with candidate values V(p) (every code word its
// uncertain planes allow, decode.hpp FillRow):
//   1. N = the coordinates of p's decoded 4-neighbours (a column, or an
//      interval's centre), each continued linearly through p when the next
//      pixel beyond it in the same direction is decoded and within
//      max_spread of it (with `extrapolate`: 2 n1 - n2, so a fill along a
//      slope of 1.3 columns per pixel does not lag a column per pixel);
//      |N| >= min_neighbours, and every n in N within
//      max_spread of m = median(N) (the neighbours agree: no fill across a
//      depth edge where they disagree);
//   2. S = { v in V(p) : |v - m| <= window }, non-empty, and S's values are
//      adjacent coordinates (no gap);
//   3. half = (max S - min S) / 2 <= max_half.
// Then p gets coord = (min S + max S) / 2, uncertainty = max(half, min_half)
// and confidence * confidence_scale (lower than a pixel decoded from its own
// bits alone). The neighbours never supply a value: they only choose among
// the values p's own certain planes allow, so a pixel whose certain planes
// contradict its neighbours (the far side of a depth edge) stays invalid.
// Passes: Jacobi-style — each pass decides every remaining pixel from the
// maps as they were at the start of the pass, then writes all decisions, so
// runs of rejected pixels fill inward from their edges, one pixel per pass
// and side, and the result does not depend on the thread count. At most
// `passes` passes (the fill distance); stops early when a pass adds nothing.
// Cost: O(rejected pixels) per pass, row bands on the pool.
// Thread-safety: uses `pool` (not reentrant with other jobs on it).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "decode.hpp"
#include "procam/base/work_pool.hpp"

namespace procam::sl {

struct NeighbourFillRule {
  uint32_t passes = 0;           // 0 = off
  uint32_t min_neighbours = 1;   // decoded 4-neighbours required
  float max_spread = 2.0f;       // coordinate units
  float window = 1.5f;           // coordinate units
  float max_half = 1.0f;         // coordinate units
  float min_half = 0.5f;         // reported uncertainty floor
  float confidence_scale = 0.5f;
  bool extrapolate = true;       // neighbour value continued by its own neighbour (rule 1)
};

// Fills rejected pixels of one axis in place (width x height maps; valid,
// confidence may be null, uncertainty not). rows: one FillRow per camera
// row (decode_uncertain's output, table values = scale * coordinate).
// Returns the number of pixels filled.
size_t fill_from_neighbours(WorkPool& pool, uint32_t width, uint32_t height, int32_t scale,
                            const NeighbourFillRule& rule, const std::vector<FillRow>& rows,
                            float* coord, uint8_t* valid, float* uncertainty, float* confidence);

}  // namespace procam::sl
