// SPDX-License-Identifier: MIT
// The daemon's geometric calibration (request calibrate_geometry,
// PROTOCOL.md 5.12): engine::GeometryCalibrationJob -> decode each pose
// scan's saved frames (structured-light/gray, rows on), calibrate
// (geometric.hpp), write the result files into the calibration record's
// folder:
//   rig-calibration.json   the rig-config calibration (to_rig_json), as
//                          `procam calibrate-geometry` writes it;
//   calibration-report.md  the per-view table (report_markdown).
// Returns the manifest's "calibration" object: {"result_file",
// "report_file", "scans": [ids], "board", "views" (per view: scan id, used,
// why rejected, corners, RMS), "camera_rms_px", "projector_rms_px",
// "stereo_rms_px", "square_check", "rig"} ("rig" = the JSON of
// rig-calibration.json).
// Threads: called on the scan worker; uses `host` (create_session is
// thread-safe). Errors: the decode's (naming the scan), failed_precondition
// from calibrate() when too few views are usable (naming each rejected view
// by its scan id and why), io_error writing the files. Never throws.
#pragma once

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"
#include "procam/engine/service.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::calibration {

Result<nlohmann::json> run_daemon_job(const host::PluginHost& host, const engine::GeometryCalibrationJob& job,
                                      unsigned threads = 2);

}  // namespace procam::calibration
