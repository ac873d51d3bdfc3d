// SPDX-License-Identifier: MIT
// Ground truth of a prepared view (depth, projector coordinates, lit mask) and
// writing it to files.
//
// Threads: reentrant. Errors are returned, never thrown.
#pragma once

#include <map>
#include <string>

#include "procam/core/status.hpp"
#include "procam/hw/rig.hpp"
#include "procam/hw/sim/renderer.hpp"

namespace procam::sim {

// depth_mm: camera-frame z (NaN where no surface); proj_col/proj_row: the
// visible point projected through the projector intrinsics (continuous, pixel
// centres at integers; NaN where not lit); lit: U8 255/0.
hw::GroundTruth ground_truth_from_view(const PreparedView& view);

// Writes <folder>/depth_mm.exr, proj_col.exr, proj_row.exr (F32, NaN where
// undefined) and lit.png (8-bit 0/255), creating the folder. `attributes` are
// stored as EXR string attributes (e.g. {"scene": "plane"}). io_error naming
// the file on failure.
Status write_ground_truth(const hw::GroundTruth& truth, const std::string& folder,
                          const std::map<std::string, std::string>& attributes = {});

}  // namespace procam::sim
