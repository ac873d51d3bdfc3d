// SPDX-License-Identifier: MIT
// The separation plugin's methods (thesis §2.5; plugins/separation/README.md):
//   checker             S1, Nayar et al. 2006: shifted checkerboards at one focus
//   checker-pair        S1 with two frames: a checkerboard and its inverse
//   multi-focal         S2, §2.5.1: the checkerboards at F focus settings
//   one-focal-depth     S3, §2.5.2: one focus, a white frame and a depth map
//   calibrate-one-focal the table S3 needs (Eq. 2.19), from a plane and its depth
//
// Streaming: add_frame folds each frame into per-focus running max/min maps
// (extrema.hpp), so state is O(pixels × F) whatever the frame count;
// end_round only interpolates and maps.
// Units: frame units (DN) in, DN out; focus in mm; depth in mm.
// Threads: a session is thread-bound (docs/threading.md); it uses
// sdk::parallel_rows workers inside add_frame/end_round.
// Errors: sdk::Error, never exceptions out of a session call.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/plugin_sdk.hpp"

namespace procam::separation {

// Name of the calibration table S3 reads from the rig (and the calibration
// method writes).
inline constexpr const char* kOneFocalTable = "separation.one-focal-depth";

// describe() JSON array: one object per method, in PROCAM_DEFINE_PLUGIN order.
nlohmann::json describe_methods();

// The factory for every method (args.method is one of them).
sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

// As create_session, with the depth map (camera-sized, mm, NaN unknown) that
// one-focal-depth and calibrate-one-focal take as input `depth_mm`;
// create_session copies it from the scan inputs (CreateArgs::inputs, plugin
// ABI 2) and calls this. Tests call it directly with ground-truth depth.
sdk::Error create_session_with_depth(const sdk::CreateArgs& args, std::optional<std::vector<float>> depth_mm,
                                     std::unique_ptr<sdk::Session>& out);

}  // namespace procam::separation
