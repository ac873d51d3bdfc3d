// SPDX-License-Identifier: MIT
// ScanService internals shared by its source files (not installed, not public):
// the per-scan Record and the small helpers the queue, store and manifest use.
//
// Threads: Record fields are guarded by ScanService::mu_ unless noted; the
// helpers below are pure or touch only the file system and never lock.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "procam/engine/service.hpp"

namespace procam::engine {

// The latest decode progress a plugin reported (host services).
struct PluginProgress {
  double fraction = 0;  // 0..1 of the current round's decode
  std::string stage;    // the plugin's name for its current step
};

struct ScanService::Record {
  std::string id;
  ScanRequest req;
  std::string state = "queued";
  std::string created_utc, finished_utc;
  // Acceptance order: created_utc has whole seconds and ids are random after
  // their time, so scans accepted within one second need this to keep their
  // order (listing, and the queue after a restart). Nanoseconds since the
  // Unix epoch, strictly increasing within a daemon; 0 in manifests written
  // before it existed (those sort by created_utc, then id).
  uint64_t accepted_ns = 0;
  Progress progress;
  std::optional<PluginProgress> plugin_progress;  // plugins with host services only
  Status error;
  std::optional<host::Session> session;  // until the scan runs
  // When finished: the manifest lives in <results_dir>/<id>/manifest.json and
  // is read from there on request (memory stays flat over thousands of
  // scans); kept here only if writing it failed.
  nlohmann::json manifest;
  bool manifest_on_disk = false;
  uint64_t seq = 0;
  uint64_t bytes = 0;                    // files of a finished scan
  // Last fetch (retention keeps recently downloaded scans); guarded by mu_.
  mutable std::optional<std::chrono::steady_clock::time_point> last_download;
};

namespace service_detail {

// A calibration record (ScanService::submit_calibration), not a plugin scan.
inline bool is_calibration(const ScanRequest& req) {
  return req.plugin == kCalibrationPlugin && req.method == kCalibrationMethod;
}

// --- manifest (service_manifest.cpp) ---
// The error object of a failed Status for JSON (proto::error_to_json), null when ok.
nlohmann::json error_json(const Status& s);
// "done" and "failed" are final; every other state is still running.
bool is_final(const std::string& state);

// --- store (service_store.cpp) ---
// Makes the renames inside `dir` durable (power loss after a finished scan).
void fsync_dir(const std::string& dir);
// The files `fetch` serves: everything in the folder but manifest.json (its
// content is the `result` reply) and temporaries.
nlohmann::json scan_files(const std::string& dir);
// A string field of a manifest read from disk, "" when absent or not a string.
std::string str_field(const nlohmann::json& j, const char* key);
// Sum of "size_bytes" over a manifest's "files" (0 when it has none).
uint64_t files_bytes(const nlohmann::json& manifest);
// A queued scan on disk: <results_dir>/<id>/request.json (the whole request,
// request_to_json) and manifest.json (`manifest` with state "queued"), both
// written atomically and the folder fsync'd. io_error naming the folder.
Status persist_queued(const std::string& results_dir, const std::string& id, const ScanRequest& req,
                      nlohmann::json manifest);
nlohmann::json request_to_json(const ScanRequest& req);
// corrupt_data saying which field is wrong.
Result<ScanRequest> request_from_json(const nlohmann::json& j);
// Seconds since an RFC 3339 UTC time "YYYY-MM-DDTHH:MM:SSZ"; nullopt if unreadable.
std::optional<double> seconds_since_utc(const std::string& utc);

}  // namespace service_detail
}  // namespace procam::engine
