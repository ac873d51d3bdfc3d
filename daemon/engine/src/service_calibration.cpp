// SPDX-License-Identifier: MIT
// Calibration records of the scan service (request calibrate_geometry,
// PROTOCOL.md 5.12; service.hpp submit_calibration): the checks on the
// scans a request names, and the worker's run of the job through
// ServiceConfig::calibrate_geometry. The fitting itself lives in
// procam::calibration (daemon/calibration), which procamd plugs in, so the
// engine does not depend on OpenCV.
#include <chrono>
#include <filesystem>

#include "procam/core/log.hpp"
#include "procam/engine/service.hpp"
#include "service_internal.hpp"

namespace procam::engine {
namespace fs = std::filesystem;

Result<nlohmann::json> ScanService::submit_calibration(const std::vector<std::string>& scan_ids, int board_cols,
                                                       int board_rows, double square_mm, const std::string& label,
                                                       const std::string& request_id) {
  return submit_calibration(scan_ids, {{"inner_corners", {board_cols, board_rows}}, {"square_mm", square_mm}}, label,
                            request_id);
}

Result<nlohmann::json> ScanService::submit_calibration(const std::vector<std::string>& scan_ids,
                                                       const nlohmann::json& board, const std::string& label,
                                                       const std::string& request_id) {
  ScanRequest req;
  req.plugin = kCalibrationPlugin;
  req.method = kCalibrationMethod;
  req.label = label;
  req.params = {{"scans", scan_ids}, {"board", board}};
  return submit(req, request_id);  // checks through check_calibration(), queues like a scan
}

Result<GeometryCalibrationJob> ScanService::check_calibration(const ScanRequest& req) const {
  if (!cfg_.calibrate_geometry)
    return Error(Code::failed_precondition, "this daemon cannot calibrate: it runs without geometric calibration",
                 "run `procam calibrate-geometry --captures` on the saved frames instead");
  GeometryCalibrationJob job;
  const nlohmann::json& p = req.params;
  try {
    job.scan_ids = p.at("scans").get<std::vector<std::string>>();
    const auto& board = p.at("board");
    job.board = board;
    // A ChArUco board is given by its squares (one more than inner corners).
    const bool charuco = board.contains("squares");
    const auto& grid = charuco ? board.at("squares") : board.at("inner_corners");
    job.board_cols = grid.at(0).get<int>() - (charuco ? 1 : 0);
    job.board_rows = grid.at(1).get<int>() - (charuco ? 1 : 0);
    job.square_mm = board.at("square_mm").get<double>();
  } catch (const std::exception& e) {
    return Error(Code::invalid_argument, std::string("calibration request: bad params: ") + e.what(),
                 "params are {\"scans\": [ids], \"board\": {\"inner_corners\": [c, r], \"square_mm\": s}}");
  }
  job.projector_width = rig_->projector_intrinsics().width;
  job.projector_height = rig_->projector_intrinsics().height;
  for (const std::string& id : job.scan_ids) {
    std::string state;
    {
      std::lock_guard lock(mu_);
      auto it = scans_.find(id);
      if (it == scans_.end())
        return Error(Code::invalid_argument, "calibrate_geometry: no scan with id '" + id + "'",
                     "list the finished pose scans with list_scans (procam scans --state done)");
      state = it->second->state;
    }
    if (state != "done")
      return Error(Code::failed_precondition, "calibrate_geometry: scan '" + id + "' is " + state + ", not done",
                   state == "failed" ? "scan this board pose again" : "wait until it is done, then ask again");
    auto m = manifest(id);
    if (!m) return m.status();
    const std::string plugin = service_detail::str_field(*m, "plugin"), method = service_detail::str_field(*m, "method");
    const nlohmann::json params = m->value("params", nlohmann::json::object());
    const bool rows = params.is_object() && params.value("rows", nlohmann::json(false)) == nlohmann::json(true);
    if (plugin != "structured-light" || method != "gray" || !rows)
      return Error(Code::failed_precondition,
                   "calibrate_geometry: scan '" + id + "' is " + plugin + "/" + method +
                       (rows ? "" : " without rows=true") +
                       "; calibration needs structured-light/gray with rows=true (projector columns and rows)",
                   "scan each pose with: procam scan --plugin structured-light --method gray --param rows=true "
                   "--save-frames 1");
    if (m->value("saved_frames", 0) <= 0)
      return Error(Code::failed_precondition, "calibrate_geometry: scan '" + id + "' has no saved frames",
                   "scan the pose again with save_frames (procam scan ... --save-frames 1): calibration needs "
                   "the raw frames, not only the decoded maps");
    job.scan_dirs.push_back((fs::path(cfg_.results_dir) / id).string());
  }
  return job;
}

void ScanService::run_calibration(Record& rec) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const std::string dir = (fs::path(cfg_.results_dir) / rec.id).string();
  nlohmann::json manifest = base_manifest(rec);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    finish(rec, Error(Code::io_error, "cannot create folder '" + dir + "': " + ec.message()), manifest);
    return;
  }
  // The scans are checked again: one may have been deleted (retention)
  // while this record waited in the queue.
  auto job = check_calibration(rec.req);
  if (!job) {
    finish(rec, job.status(), manifest);
    return;
  }
  job->out_dir = dir;
  {
    std::lock_guard lock(mu_);
    rec.state = "decoding";
    rec.progress = Progress{"decode", 1, 0, job->scan_ids.size(), "decoding the board poses and calibrating"};
  }
  emit(rec, "state", {{"state", "decoding"}});
  Result<nlohmann::json> out = Error(Code::internal, "calibration did not run");
  try {
    out = cfg_.calibrate_geometry(*job);
  } catch (const std::exception& e) {  // the contract says it must not throw; never let it kill the worker
    out = Error(Code::internal, std::string("calibration threw: ") + e.what());
  }
  if (!out) {
    finish(rec, out.status(), manifest);
    return;
  }
  manifest["calibration"] = std::move(*out);
  manifest["timing_ms"]["decode"] = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  manifest["timing_ms"]["total"] = manifest["timing_ms"]["decode"];
  PROCAM_LOG(engine, info) << "calibration " << rec.id << " from " << job->scan_ids.size() << " scans done";
  finish(rec, Status::Ok(), manifest);
}

}  // namespace procam::engine
