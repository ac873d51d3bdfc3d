// SPDX-License-Identifier: MIT
// Calibration tables of the defocus methods (procam/sdk/calibration_table.hpp,
// docs/calibration.md): a cue (fbar, Omega or E/mean) -> depth in mm, made
// from a plane whose per-pixel depth is known (structured light on a normal
// rig; the sim's ground truth in tests), used through lookup() (linear, NaN
// outside the table: never extrapolated).
//
// A table is only valid for the focus settings it was made with: fbar is an
// index into them and Omega/E depend on them. So every table records them in
// extra.focus_mm, and a scan whose settings differ is refused at
// session_create with a message saying which settings to use.
// Threads: reentrant. Errors: sdk::Error (INVALID_ARGUMENT).
#pragma once

#include <string>
#include <vector>

#include "procam/plugin_sdk.hpp"
#include "procam/sdk/calibration_table.hpp"

namespace procam::defocus {

// The cue of a depth method and the name of its table.
struct CueKind {
  const char* table_name;  // "defocus.multi-focal"
  const char* x_name;      // "fbar"
  const char* x_unit;      // "index"
  const char* method;      // the scan method that uses the table, "multi-focal"
};
inline constexpr CueKind kMultiFocal{"defocus.multi-focal", "fbar", "index", "multi-focal"};
inline constexpr CueKind kTwoFocal{"defocus.two-focal", "omega", "ratio", "two-focal"};
inline constexpr CueKind kSingleFocal{"defocus.single-focal", "modulation", "ratio", "single-focal"};

// Fits the table from per-pixel pairs (cue[i], depth_mm[i]) (NaN skipped)
// with sdk::fit_monotonic in `bins` equal-count bins; records focus_mm in
// extra. Errors name the table and say what to change.
sdk::Error make_table(const CueKind& kind, const std::vector<float>& cue, const std::vector<float>& depth_mm,
                      const std::vector<double>& focus_mm, size_t bins, sdk::CalibrationTable& out);

// The rig's table for `kind`, parsed and checked against `focus_mm`.
// A missing table or one made with other focus settings is an error that
// says how to make one / which settings it needs.
sdk::Error table_from_rig(const sdk::Rig& rig, const CueKind& kind, const std::vector<double>& focus_mm,
                          sdk::CalibrationTable& out);

// depth_mm[i] = table.lookup(cue[i]) (NaN where cue is NaN or outside the
// table). Returns the number of finite depths.
size_t depth_from_cue(const sdk::CalibrationTable& table, const std::vector<float>& cue, uint32_t threads,
                      std::vector<float>& depth_mm);

}  // namespace procam::defocus
