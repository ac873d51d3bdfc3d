// SPDX-License-Identifier: MIT
// ScanService: the daemon's scan queue and worker for one rig. The ZeroMQ
// server (daemon/procamd) is a thin layer over it.
//
// Threads: one worker thread owns the Rig and runs scans in order. All public
// methods are thread-safe and return promptly (they never wait for a scan).
// Events are delivered through EventSink on the worker thread; the sink must
// not block and must not call back into the service.
// Persistence: each scan lives in <results_dir>/<scan_id>/ with a
// manifest.json written atomically when it ends; finished scans found there at
// start are served again, folders without a final manifest are reported as
// failed ("interrupted").
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

namespace procam::engine {

struct ServiceConfig {
  std::string results_dir;
  unsigned threads = 2;         // suggested to plugins
  size_t max_queue = 16;        // queued (not running) scans
  CaptureOptions capture;
  bool evaluate = true;         // compare with ground truth when the rig has it
};

struct ScanRequest {
  std::string plugin, method, label;
  nlohmann::json params = nlohmann::json::object();
  nlohmann::json rig_options = nlohmann::json::object();
};

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

  // Validates plugin/method/params (creates the plugin session now, so a bad
  // parameter is refused at once) and queues the scan.
  // → {"scan_id","state":"queued","queue_position":n}; unavailable when full.
  Result<nlohmann::json> submit(const ScanRequest& req);

  nlohmann::json daemon_status() const;
  Result<nlohmann::json> scan_summary(const std::string& scan_id) const;
  // The manifest of a finished (done or failed) scan.
  Result<nlohmann::json> manifest(const std::string& scan_id) const;
  // Path of a file listed in a finished scan's manifest.
  Result<std::string> file_path(const std::string& scan_id, const std::string& file) const;
  nlohmann::json rig_description() const;
  std::string rig_name() const;

private:
  struct Record;
  void worker_loop();
  void run_one(Record& rec);
  void finish(Record& rec, const Status& status, nlohmann::json manifest);
  void emit(Record& rec, const std::string& event, nlohmann::json fields);
  nlohmann::json summary_locked(const Record& rec) const;
  nlohmann::json base_manifest(const Record& rec) const;
  void load_existing();

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
  size_t done_ = 0, failed_ = 0;
  bool stopping_ = false;
  std::atomic<bool> cancel_running_{false};
  std::chrono::steady_clock::time_point started_;
  std::thread worker_;
};

// "2026-11-21T08:32:00Z"
std::string utc_now();

}  // namespace procam::engine
