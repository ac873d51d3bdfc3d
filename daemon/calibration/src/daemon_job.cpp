// SPDX-License-Identifier: MIT
// calibrate_geometry in the daemon (procam/calibration/daemon_job.hpp).
#include "procam/calibration/daemon_job.hpp"

#include <filesystem>

#include "procam/calibration/captures.hpp"
#include "procam/calibration/geometric.hpp"
#include "procam/engine/rig_json.hpp"

namespace procam::calibration {
namespace fs = std::filesystem;

Result<nlohmann::json> run_daemon_job(const host::PluginHost& host, const engine::GeometryCalibrationJob& job,
                                      unsigned threads) {
  try {
    if (job.scan_ids.size() != job.scan_dirs.size())
      return Error(Code::internal, "calibration job: scan ids and folders differ in number");
    // The request's board (chessboard or ChArUco), checked before decoding.
    BoardSpec board{job.board_cols, job.board_rows, job.square_mm};
    if (job.board.is_object()) {
      auto b = board_from_json(job.board);
      if (!b) return b.status();
      board = *b;
    }
    DecodeOptions dec;
    dec.projector_width = job.projector_width;
    dec.projector_height = job.projector_height;
    dec.threads = threads;
    std::vector<View> views;
    for (size_t i = 0; i < job.scan_dirs.size(); ++i) {
      auto v = decode_capture(host, job.scan_dirs[i], dec);
      if (!v) return v.status().with_context("scan " + job.scan_ids[i]);
      v->name = job.scan_ids[i];  // the report names views by their scan
      views.push_back(std::move(*v));
    }
    auto r = calibrate(views, board, job.projector_width, job.projector_height);
    if (!r) return r.status();
    const nlohmann::json rig = to_rig_json(*r);
    const std::string result_file = "rig-calibration.json", report_file = "calibration-report.md";
    PROCAM_TRY(engine::write_file_atomic((fs::path(job.out_dir) / result_file).string(), rig.dump(2) + "\n"));
    PROCAM_TRY(engine::write_file_atomic((fs::path(job.out_dir) / report_file).string(),
                                         "# Geometric calibration\n\n" + report_markdown(*r)));
    const nlohmann::json& rep = rig["calibration_report"];
    return nlohmann::json{{"result_file", result_file},
                          {"report_file", report_file},
                          {"scans", job.scan_ids},
                          {"board", board_to_json(board)},
                          {"views", rep["views"]},
                          {"camera_rms_px", r->camera_rms_px},
                          {"projector_rms_px", r->projector_rms_px},
                          {"stereo_rms_px", r->stereo_rms_px},
                          {"square_check", rep["square_check"]},
                          {"rig", rig}};
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("calibration: ") + e.what());
  }
}

}  // namespace procam::calibration
