// SPDX-License-Identifier: MIT
// ScanService: the daemon's scan queue and worker for one rig. The ZeroMQ
// server (daemon/procamd) is a thin layer over it.
//
// Threads: one worker thread owns the Rig and runs scans in order. All public
// methods are thread-safe and return promptly (they never wait for a scan).
// Events are delivered through EventSink on the worker thread; the sink must
// not block and must not call back into the service.
// Persistence: each scan lives in <results_dir>/<scan_id>/ with a
// manifest.json written atomically (temp + rename + fsync of the folder) when
// it ends; finished scans found there at start are served again, folders
// without a final manifest are reported as failed ("interrupted") and get a
// manifest saying so. Queued scans are persisted when accepted
// (request.json + a "queued" manifest in their folder), so a crash or kill -9
// loses none: the next start queues them again in their old order (or fails
// them, ServiceConfig::run_queued_on_restart), with their old ids.
// Retries: submit() remembers (request id, content) → scan id for
// ServiceConfig::dedupe_window (at most dedupe_max entries), so a retried
// scan request is answered with the scan it already queued.
// Retention: after start and after every finished scan, the oldest finished
// scans are deleted while a limit of RetentionPolicy is exceeded — except
// scans a client fetched from within RetentionPolicy::download_grace.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

namespace procam::engine {

// Limits on kept finished scans; 0 disables a limit. Oldest (by finish time) go first.
struct RetentionPolicy {
  double max_age_days = 0;          // delete scans finished longer ago
  size_t max_scans = 0;             // keep at most this many finished scans
  uint64_t min_free_mb = 0;         // delete while the results disk has less free space
  std::chrono::seconds download_grace{600};  // never delete a scan fetched this recently
};

// Geometric calibration of the rig (request calibrate_geometry, PROTOCOL.md
// 5.12), run as a calibration record on the scan worker: the job the
// service hands to ServiceConfig::calibrate_geometry once it has checked
// every scan (finished, structured-light/gray with rows=true, saved frames).
struct GeometryCalibrationJob {
  std::vector<std::string> scan_ids;   // the board poses, in the request's order
  std::vector<std::string> scan_dirs;  // their folders (frame-r1-*.png inside), same order
  int board_cols = 0, board_rows = 0;  // inner corners
  double square_mm = 0;
  // The request's board object as sent (PROTOCOL.md 5.12: chessboard or
  // ChArUco); procam::calibration::board_from_json reads it.
  nlohmann::json board;
  uint32_t projector_width = 0, projector_height = 0;  // the rig's projector
  std::string out_dir;  // the calibration record's folder: write its result files here
};
// Runs the job on the worker thread and returns the manifest's
// "calibration" object; errors fail the record (failed_precondition: too few
// usable views, naming each rejected one). Must not throw.
using GeometryCalibrator = std::function<Result<nlohmann::json>(const GeometryCalibrationJob&)>;
// The pseudo plugin/method of calibration records in manifests and lists.
inline constexpr const char* kCalibrationPlugin = "procam";
inline constexpr const char* kCalibrationMethod = "calibrate_geometry";

struct ServiceConfig {
  std::string results_dir;
  unsigned threads = 2;         // suggested to plugins
  size_t max_queue = 16;        // queued (not running) scans
  CaptureOptions capture;
  bool evaluate = true;         // compare with ground truth when the rig has it
  RetentionPolicy retention;
  std::chrono::seconds dedupe_window{600};  // how long scan request ids are remembered
  size_t dedupe_max = 4096;                 // and how many at most
  // The rig's calibration tables (name -> table, engine/calibration_tables.hpp),
  // copied into every session's rig description and into describe_rig.
  nlohmann::json calibration_tables = nlohmann::json::object();
  // Scans still queued when the daemon died (crash, kill -9, power loss):
  // true → the next start queues them again (plugin, method and inputs are
  // checked again; one that no longer passes fails with the reason); false →
  // they fail with "the daemon restarted before this scan started". Either
  // way a scan accepted longer than queued_max_age ago fails as stale: a scan
  // cell's part has moved on by then. A clean stop() still cancels the queue.
  bool run_queued_on_restart = true;
  std::chrono::seconds queued_max_age{3600};
  // Geometric calibration (calibrate_geometry requests); unset: such
  // requests fail with failed_precondition. procamd sets it (procam::calibration).
  GeometryCalibrator calibrate_geometry;
};

// Where a scan input comes from: output `output` of the finished scan `scan_id`.
struct InputSource {
  std::string scan_id, output;
};

struct ScanRequest {
  std::string plugin, method, label;
  nlohmann::json params = nlohmann::json::object();
  nlohmann::json rig_options = nlohmann::json::object();
  bool save_frames = false;  // record the raw frames into the scan folder (CaptureOptions::record_dir)
  std::map<std::string, InputSource> inputs;  // input name -> earlier output (PROTOCOL.md 5.4)
};

class LoadedInputs;  // procam/engine/inputs.hpp

class RequestMemory;  // scan request de-duplication (src/service_dedupe.hpp)

// (scan_id, event name, fields) — fields exclude scan_id/seq, which the server adds.
using EventSink = std::function<void(const std::string&, const std::string&, nlohmann::json)>;

class ScanService {
public:
  ScanService(std::unique_ptr<hw::Rig> rig, const host::PluginHost& plugins, ServiceConfig cfg,
              EventSink sink);
  ~ScanService();
  ScanService(const ScanService&) = delete;
  ScanService& operator=(const ScanService&) = delete;

  // Loads finished scans from results_dir and starts the worker.
  Status start();
  // Cancels queued and running scans (they end "failed: cancelled: daemon
  // shutting down" with a manifest) and joins the worker. Idempotent.
  void stop();

  // Validates plugin/method/params and inputs (reads each input's stored map
  // and creates the plugin session now, so a bad parameter or input is
  // refused at once) and queues the scan. Input errors: not_found (unknown
  // scan, deleted scan, no such output), failed_precondition (the scan is not
  // finished or failed), invalid_argument (not a float map, wrong size, an
  // input the method does not take, a required one missing).
  // → {"scan_id","state":"queued","queue_position":n}; unavailable ("busy: N
  // scans ahead of you") when max_queue scans wait. A non-empty `request_id`
  // seen before with the same content returns that scan instead, with
  // "duplicate": true and its current state.
  Result<nlohmann::json> submit(const ScanRequest& req, const std::string& request_id = "");
  // A calibrate_geometry request (PROTOCOL.md 5.12): checks every scan now
  // (invalid_argument: unknown scan id; failed_precondition: a scan not done,
  // not structured-light/gray with rows=true, or without saved frames; each
  // with a hint) and queues a calibration record (plugin "procam", method
  // "calibrate_geometry", params {"scans", "board"}) that runs
  // cfg.calibrate_geometry on the worker. Reply and duplicates as submit().
  Result<nlohmann::json> submit_calibration(const std::vector<std::string>& scan_ids, int board_cols,
                                            int board_rows, double square_mm, const std::string& label,
                                            const std::string& request_id = "");
  // The same with the request's board object (chessboard or ChArUco,
  // proto::board_json), passed to the job as sent.
  Result<nlohmann::json> submit_calibration(const std::vector<std::string>& scan_ids, const nlohmann::json& board,
                                            const std::string& label, const std::string& request_id = "");
  // Cancels a queued scan (it ends failed/cancelled now) or the running one
  // (it stops before its next frame). → {"scan_id","previous_state","state"};
  // not_found / failed_precondition (already finished).
  Result<nlohmann::json> cancel(const std::string& scan_id);

  nlohmann::json daemon_status() const;
  // Scan summaries (as in status), newest first (created_utc, then id), at
  // most `limit`; only those in `state` when given ("active": not final).
  // → {"scans": [...], "total": <matching>, "truncated": <bool>}.
  nlohmann::json list_scans(const std::optional<std::string>& state, uint32_t limit) const;
  // The rig_options this rig accepts (hw::Rig::scan_options) and its name.
  nlohmann::json rig_options() const;
  double uptime_s() const;
  Result<nlohmann::json> scan_summary(const std::string& scan_id) const;
  // The manifest of a finished (done or failed) scan.
  Result<nlohmann::json> manifest(const std::string& scan_id) const;
  // Path of a file listed in a finished scan's manifest; always inside
  // <results_dir>/<scan_id>/ and a regular file (no symlinks). Marks the scan
  // as being downloaded (retention keeps it for download_grace).
  Result<std::string> file_path(const std::string& scan_id, const std::string& file) const;
  // Applies the retention policy now (also done after each scan). Returns
  // the number of scans deleted.
  size_t apply_retention();
  nlohmann::json rig_description() const;
  std::string rig_name() const;

private:
  struct Record;
  void worker_loop();
  void run_one(Record& rec);
  void finish(Record& rec, const Status& status, nlohmann::json manifest);
  void emit(Record& rec, const std::string& event, nlohmann::json fields);
  void forward_plugin_reports(Record& rec, host::Session& session);
  nlohmann::json summary_locked(const Record& rec) const;
  nlohmann::json base_manifest(const Record& rec) const;
  nlohmann::json metrics_locked() const;  // daemon_status()["metrics"]; mu_ held
  void load_existing();
  // Checks rig_options and inputs and creates the plugin session (submit and
  // the restart of persisted queued scans).
  Result<host::Session> make_session(const ScanRequest& req) const;
  // Calibration records (service_calibration.cpp): the checks of
  // submit_calibration on a request's params, the job they describe, and the
  // worker's run of one.
  Result<GeometryCalibrationJob> check_calibration(const ScanRequest& req) const;
  void run_calibration(Record& rec);
  // Queues again (or fails) the persisted queued scans load_existing found.
  void restart_queued(std::vector<std::pair<std::shared_ptr<Record>, Result<ScanRequest>>> found);
  Result<LoadedInputs> load_inputs(const ScanRequest& req) const;  // service_inputs.cpp
  Result<LoadedInputs> load_inputs_impl(const ScanRequest& req) const;

  std::unique_ptr<hw::Rig> rig_;
  const host::PluginHost& plugins_;
  ServiceConfig cfg_;
  EventSink sink_;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::map<std::string, std::shared_ptr<Record>> scans_;
  std::deque<std::shared_ptr<Record>> queue_;
  std::shared_ptr<Record> running_;
  nlohmann::json rig_description_;
  std::string rig_name_;             // immutable after construction
  nlohmann::json plugin_rig_json_;  // calibration for plugins; immutable after construction
  size_t done_ = 0, failed_ = 0, cancelled_ = 0, rejected_busy_ = 0;
  uint64_t frames_captured_ = 0, frames_dropped_ = 0;
  double decode_ms_last_ = 0, decode_ms_sum_ = 0, decode_ms_max_ = 0;
  size_t decode_count_ = 0;
  uint64_t results_bytes_ = 0;
  std::unique_ptr<RequestMemory> requests_;  // request id + content digest → scan (service_dedupe.hpp)
  bool stopping_ = false;
  std::atomic<bool> cancel_running_{false};
  std::string cancel_reason_;  // why cancel_running_ was set (guarded by mu_)
  std::chrono::steady_clock::time_point started_;
  std::thread worker_;
};

// "2026-11-21T08:32:00Z"
std::string utc_now();

}  // namespace procam::engine
