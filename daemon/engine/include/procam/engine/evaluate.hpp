// SPDX-License-Identifier: MIT
// Accuracy of decoded outputs against a simulated rig's ground truth.
#pragma once

#include <nlohmann/json.hpp>

#include "procam/core/image.hpp"
#include "procam/hw/rig.hpp"

namespace procam::engine {

// Compares a decoded projector-column map (F32, NaN = not decoded) and an
// optional depth map with the truth. Reported (all over the truth's lit pixels
// unless stated):
//   lit_pixels, decoded_fraction (decoded / lit),
//   within_1col_fraction (decoded and |col - truth| <= 1, over lit): the
//     headline accuracy; a decoded integer column is the projector pixel
//     whose centre is nearest, so |err| <= 0.5 when exact, 1 allows one
//     neighbouring column,
//   gross_error_fraction (|err| > 1, over decoded lit pixels),
//   col_rms_px (over decoded, non-gross), spurious_fraction (decoded pixels
//   the truth says are not lit, over all decoded),
//   depth_rms_mm / depth_median_abs_mm / depth_p99_abs_mm (over decoded
//   non-gross pixels with finite depth).
nlohmann::json evaluate_correspondence(const Image& proj_col, const Image* depth_mm,
                                       const hw::GroundTruth& truth);

}  // namespace procam::engine
