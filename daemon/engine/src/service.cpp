// SPDX-License-Identifier: MIT
// Scan queue + worker (see service.hpp for the contract): scan records,
// submit/cancel, the worker loop that runs one scan after another.
// Split by concern: service_store.cpp (results folder), service_manifest.cpp
// (manifest + status JSON), service_retention.cpp, service_dedupe.cpp
// (request keys), service_metrics.cpp.
#include "procam/engine/service.hpp"

#include <chrono>
#include <cmath>
#include <ctime>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <random>
#include <vector>

#include "procam/core/log.hpp"
#include "procam/engine/evaluate.hpp"
#include "procam/engine/inputs.hpp"
#include "procam/engine/previews.hpp"
#include "procam/engine/results.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/proto/protocol.hpp"
#include "service_dedupe.hpp"
#include "service_internal.hpp"

namespace procam::engine {
namespace fs = std::filesystem;

std::string utc_now() {
  std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

namespace {

std::string new_scan_id() {
  static std::mt19937_64 rng{std::random_device{}()};
  static std::mutex mu;
  std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char ts[32];
  std::strftime(ts, sizeof ts, "%Y%m%d-%H%M%S", &tm);
  std::lock_guard lock(mu);
  char suffix[16];
  std::snprintf(suffix, sizeof suffix, "%06llx", static_cast<unsigned long long>(rng() & 0xffffff));
  return std::string(ts) + "-" + suffix;
}

}  // namespace

using service_detail::error_json;
using service_detail::files_bytes;
using service_detail::fsync_dir;
using service_detail::is_final;
using service_detail::persist_queued;
using service_detail::scan_files;

ScanService::ScanService(std::unique_ptr<hw::Rig> rig, const host::PluginHost& plugins,
                         ServiceConfig cfg, EventSink sink)
    : rig_(std::move(rig)),
      plugins_(plugins),
      cfg_(std::move(cfg)),
      sink_(std::move(sink)),
      requests_(std::make_unique<RequestMemory>(cfg_.dedupe_window, cfg_.dedupe_max)) {
  rig_description_ = rig_->describe();
  rig_name_ = rig_description_.value("name", "");
  plugin_rig_json_ = plugin_rig_json(*rig_, cfg_.threads);
  if (cfg_.calibration_tables.is_object() && !cfg_.calibration_tables.empty())
    plugin_rig_json_["calibration_tables"] = cfg_.calibration_tables;
}

ScanService::~ScanService() { stop(); }

Status ScanService::start() {
  std::error_code ec;
  fs::create_directories(cfg_.results_dir, ec);
  if (ec)
    return Error(Code::io_error, "cannot create results folder '" + cfg_.results_dir + "': " + ec.message(),
                 "set results_dir in the daemon config to a writable folder");
  for (const auto& ent : fs::directory_iterator(cfg_.results_dir, ec)) {
    const std::string n = ent.path().filename().string();
    std::error_code ec2;
    if (n.size() > 9 && n[0] == '.' && n.ends_with(".deleting")) fs::remove_all(ent.path(), ec2);
  }
  load_existing();
  apply_retention();
  started_ = std::chrono::steady_clock::now();
  worker_ = std::thread([this] { worker_loop(); });
  return Status::Ok();
}

void ScanService::stop() {
  {
    std::lock_guard lock(mu_);
    if (stopping_ && !worker_.joinable()) return;
    stopping_ = true;
    cancel_reason_ = "cancelled: the daemon is shutting down";
    cancel_running_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  // Anything still queued ends as cancelled, with a manifest.
  std::deque<std::shared_ptr<Record>> left;
  {
    std::lock_guard lock(mu_);
    left.swap(queue_);
  }
  for (auto& r : left) {
    r->session.reset();
    finish(*r, Error(Code::cancelled, "daemon shutting down before the scan started"), {});
  }
}

Result<nlohmann::json> ScanService::submit(const ScanRequest& req, const std::string& request_id) {
  using Clock = std::chrono::steady_clock;
  nlohmann::json inputs = nlohmann::json::object();
  for (const auto& [name, src] : req.inputs) inputs[name] = {{"scan", src.scan_id}, {"output", src.output}};
  const std::string content =
      nlohmann::json{{"plugin", req.plugin}, {"method", req.method}, {"params", req.params},
                     {"rig_options", req.rig_options}, {"label", req.label}, {"save_frames", req.save_frames},
                     {"inputs", inputs}}
          .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  {
    std::lock_guard lock(mu_);
    if (stopping_) return Error(Code::unavailable, "the daemon is shutting down", "retry when it is back");
    // Forget old request ids.
    const auto now = Clock::now();
    requests_->forget_old(now);
    const std::string key = request_key(request_id, content);
    if (!request_id.empty()) {
      if (const std::string* seen = requests_->find(key)) {
        auto sc = scans_.find(*seen);
        if (sc != scans_.end()) {
          const Record& r = *sc->second;
          size_t pos = 0;
          for (size_t k = 0; k < queue_.size(); ++k)
            if (queue_[k].get() == &r) pos = k + 1;
          if (pos > 0) pos = pos - 1 + (running_ ? 1 : 0);
          PROCAM_LOG(engine, info) << "scan request '" << request_id << "' repeated: answering with scan " << r.id;
          return nlohmann::json{{"scan_id", r.id}, {"state", r.state}, {"queue_position", pos}, {"duplicate", true}};
        }
      }
    }
    if (queue_.size() >= cfg_.max_queue) {
      ++rejected_busy_;
      return Error(Code::unavailable,
                   "busy: " + std::to_string(queue_.size() + (running_ ? 1 : 0)) + " scans ahead of you",
                   "the queue holds " + std::to_string(cfg_.max_queue) + " scans; retry later with back-off");
    }
  }
  auto rec = std::make_shared<Record>();
  if (service_detail::is_calibration(req)) {
    auto job = check_calibration(req);  // no plugin session: the worker decodes the scans' frames
    if (!job) return job.status();
  } else {
    auto session = make_session(req);
    if (!session) return session.status();
    rec->session.emplace(std::move(*session));
  }
  rec->id = new_scan_id();
  rec->req = req;
  rec->created_utc = utc_now();
  {
    static std::atomic<uint64_t> last{0};
    const auto now = static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                               std::chrono::system_clock::now().time_since_epoch())
                                               .count());
    uint64_t prev = last.load();
    uint64_t next = std::max(now, prev + 1);
    while (!last.compare_exchange_weak(prev, next)) next = std::max(now, prev + 1);
    rec->accepted_ns = next;
  }
  {
    // Reserve the id (state "queued", not yet in the queue: a cancel now is
    // "just starting", retry), persist the request outside the lock, then queue.
    std::lock_guard lock(mu_);
    if (stopping_) return Error(Code::unavailable, "the daemon is shutting down", "retry when it is back");
    while (scans_.count(rec->id)) rec->id = new_scan_id();
    scans_[rec->id] = rec;
  }
  if (Status ps = persist_queued(cfg_.results_dir, rec->id, req, base_manifest(*rec)); !ps) {
    std::lock_guard lock(mu_);
    scans_.erase(rec->id);
    return ps;
  }
  nlohmann::json reply;
  {
    std::lock_guard lock(mu_);
    if (stopping_) {
      scans_.erase(rec->id);
      return Error(Code::unavailable, "the daemon is shutting down", "retry when it is back");
    }
    queue_.push_back(rec);
    reply = {{"scan_id", rec->id}, {"state", "queued"},
             {"queue_position", queue_.size() - 1 + (running_ ? 1 : 0)}};
    if (!request_id.empty()) {
      const auto now = Clock::now();
      const std::string key = request_key(request_id, content);
      requests_->remember(key, rec->id, now);
    }
  }
  cv_.notify_all();
  PROCAM_LOG(engine, info) << "scan " << rec->id << " queued: " << req.plugin << "/" << req.method;
  return reply;
}

Result<host::Session> ScanService::make_session(const ScanRequest& req) const {
  // rig_options are checked now, not when the scan runs: a bad one is the
  // client's error (invalid_argument) and must never be queued.
  PROCAM_TRY(rig_->check_scan_options(req.rig_options));
  auto inputs_loaded = load_inputs(req);  // service_inputs.cpp; read now, released after create
  if (!inputs_loaded) return inputs_loaded.status();
  return plugins_.create_session(req.plugin, req.method, req.params.dump(), plugin_rig_json_.dump(),
                                 inputs_loaded->views());
}

Result<nlohmann::json> ScanService::cancel(const std::string& scan_id) {
  std::shared_ptr<Record> rec;
  std::string previous;
  {
    std::lock_guard lock(mu_);
    auto it = scans_.find(scan_id);
    if (it == scans_.end())
      return Error(Code::not_found, "no scan with id '" + scan_id + "'", "ask `status` without scan_id for the current scan");
    rec = it->second;
    previous = rec->state;
    if (is_final(previous))
      return Error(Code::failed_precondition, "scan '" + scan_id + "' has already finished (" + previous + ")",
                   "nothing to cancel; delete nothing, its results stay available");
    if (running_ == rec) {
      cancel_reason_ = "cancelled by a client";
      cancel_running_ = true;
      PROCAM_LOG(engine, info) << "scan " << scan_id << ": cancel requested while " << previous;
      return nlohmann::json{{"scan_id", scan_id}, {"previous_state", previous}, {"state", previous}};
    }
    auto q = std::find(queue_.begin(), queue_.end(), rec);
    if (q == queue_.end())  // between the queue and running_: the worker is picking it up
      return Error(Code::unavailable, "scan '" + scan_id + "' is just starting", "retry the cancel in a moment");
    queue_.erase(q);
  }
  rec->session.reset();
  finish(*rec, Error(Code::cancelled, "cancelled by a client before it started", "scan again if still wanted"), {});
  return nlohmann::json{{"scan_id", scan_id}, {"previous_state", previous}, {"state", "failed"}};
}

void ScanService::worker_loop() {
  for (;;) {
    std::shared_ptr<Record> rec;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      rec = queue_.front();
      queue_.pop_front();
      running_ = rec;
      cancel_running_ = false;
      cancel_reason_.clear();
    }
    run_one(*rec);
    {
      std::lock_guard lock(mu_);
      running_.reset();
    }
    apply_retention();
  }
}

// Plugin host services (plugin_abi.h): the plugin's log lines become `log`
// events (debug stays in the daemon log), its decode progress `progress`
// events of stage "plugin" (done/total in thousandths, message = its step)
// and the scan record's plugin_progress, which `status` shows. Called on the
// worker thread; the handlers run there too, inside the plugin's calls.
void ScanService::forward_plugin_reports(Record& rec, host::Session& session) {
  session.set_log_handler([this, &rec](log::Level level, const std::string& message) {
    if (level == log::Level::debug) return;
    const char* name = level == log::Level::error ? "error" : level == log::Level::warn ? "warn" : "info";
    emit(rec, "log", {{"level", name}, {"message", message}});
  });
  session.set_progress_handler([this, &rec](double fraction, const std::string& stage) {
    int round = 1;
    {
      std::lock_guard lock(mu_);
      rec.plugin_progress = PluginProgress{fraction, stage};
      round = rec.progress.round;
    }
    emit(rec, "progress", {{"stage", "plugin"}, {"round", round},
                           {"done", static_cast<int>(std::lround(fraction * 1000.0))}, {"total", 1000},
                           {"message", stage}});
  });
}

void ScanService::emit(Record& rec, const std::string& event, nlohmann::json fields) {
  if (sink_) sink_(rec.id, event, std::move(fields));
}

void ScanService::run_one(Record& rec) {
  if (service_detail::is_calibration(rec.req)) return run_calibration(rec);  // service_calibration.cpp
  using Clock = std::chrono::steady_clock;
  auto t0 = Clock::now();
  auto set_state = [&](const std::string& s) {
    {
      std::lock_guard lock(mu_);
      rec.state = s;
    }
    emit(rec, "state", {{"state", s}});
  };
  const std::string dir = (fs::path(cfg_.results_dir) / rec.id).string();
  std::error_code ec;
  fs::create_directories(dir, ec);
  nlohmann::json manifest = base_manifest(rec);
  if (ec) {
    finish(rec, Error(Code::io_error, "cannot create scan folder '" + dir + "': " + ec.message()), manifest);
    return;
  }
  {
    // What was asked, on disk from the start: after a crash the restarted
    // daemon reports this scan as interrupted with its plugin, label, params.
    nlohmann::json running = manifest;
    running["state"] = "capturing";
    Status ws = write_file_atomic((fs::path(dir) / "manifest.json").string(), running.dump(2));
    if (!ws) PROCAM_LOG(engine, warn) << "scan " << rec.id << ": " << ws.to_string();
  }
  {
    // status shows where the scan is from its first moment, not null until
    // the first frame arrives.
    std::lock_guard lock(mu_);
    rec.progress = Progress{"capture", 1, 0, 0, "preparing the rig"};
  }
  set_state("capturing");
  Status st = rig_->apply_scan_options(rec.req.rig_options);
  {
    std::lock_guard lock(mu_);
    rig_description_ = rig_->describe();
    manifest["rig"] = {{"name", rig_description_.value("name", "")},
                       {"state", rig_description_.value("state", nlohmann::json::object())}};
  }
  if (!st) {
    finish(rec, st, manifest);  // its message names rig_options already
    return;
  }
  host::Session& session = *rec.session;
  std::string last_stage;
  auto progress = [&](const Progress& p) {
    std::string changed;  // the state this progress moves the scan into, if any
    {
      std::lock_guard lock(mu_);
      rec.progress = p;
      if (p.stage == "decode" && rec.state != "decoding") changed = rec.state = "decoding";
      else if (p.stage == "capture" && rec.state != "capturing") changed = rec.state = "capturing";
    }
    // Every state change is a state event (PROTOCOL.md 7), decoding included.
    if (!changed.empty()) emit(rec, "state", {{"state", changed}});
    emit(rec, "progress", {{"stage", p.stage}, {"round", p.round}, {"done", p.done}, {"total", p.total},
                           {"message", p.message}});
  };
  forward_plugin_reports(rec, session);
  CaptureOptions capture = cfg_.capture;
  if (rec.req.save_frames) capture.record_dir = dir;  // frame-r<round>-<index>.png beside the outputs
  auto outcome = run_scan(*rig_, session, capture, progress, cancel_running_);
  auto cancelled = [&]() -> std::optional<Status> {
    if (!cancel_running_.load()) return std::nullopt;
    std::lock_guard lock(mu_);
    return Error(Code::cancelled, "scan " + (cancel_reason_.empty() ? std::string("cancelled") : cancel_reason_),
                 "scan again if still wanted");
  };
  if (!outcome) {
    auto c = outcome.status().code() == Code::cancelled ? cancelled() : std::nullopt;
    finish(rec, c ? *c : outcome.status(), manifest);
    return;
  }
  {
    std::lock_guard lock(mu_);
    frames_captured_ += outcome->patterns;
    frames_dropped_ += outcome->frames_retried;
    decode_ms_last_ = outcome->decode_ms;
    decode_ms_sum_ += outcome->decode_ms;
    decode_ms_max_ = std::max(decode_ms_max_, outcome->decode_ms);
    ++decode_count_;
  }
  if (auto c = cancelled()) {
    finish(rec, *c, manifest);
    return;
  }
  nlohmann::json rounds = nlohmann::json::array();
  for (const auto& r : outcome->rounds) rounds.push_back({{"note", r.note}, {"frames", r.frames}});
  manifest["plan"] = {{"rounds", rounds}, {"patterns", outcome->patterns}};
  if (rec.req.save_frames) manifest["saved_frames"] = outcome->patterns;

  set_state("writing");
  auto outs = session.outputs();
  if (!outs) {
    finish(rec, outs.status().with_context("reading decoder outputs"), manifest);
    return;
  }
  auto tw = Clock::now();
  auto written = write_outputs(dir, *outs);
  if (!written) {
    finish(rec, written.status(), manifest);
    return;
  }
  manifest["outputs"] = written->outputs;
  manifest["previews"] = written->previews;
  if (cfg_.evaluate) {  // evaluators chosen by the outputs (evaluate.hpp); none apply: no "evaluation"
    auto truth = rig_->ground_truth(0);
    if (truth) {
      nlohmann::json e = evaluate_outputs(*outs, *truth);
      if (!e["evaluators"].empty()) {
        e["truth"] = "simulated rig ground truth, camera 0";
        manifest["evaluation"] = std::move(e);
      }
    }
  }
  const double write_ms = std::chrono::duration<double, std::milli>(Clock::now() - tw).count();
  manifest["timing_ms"] = {{"capture", outcome->capture_ms}, {"decode", outcome->decode_ms},
                           {"write", write_ms},
                           {"total", std::chrono::duration<double, std::milli>(Clock::now() - t0).count()}};
  manifest["frames_retried"] = outcome->frames_retried;
  manifest["sync"] = outcome->sync;  // issue 5: sync engine report (mode, latencies, retries)
  finish(rec, Status::Ok(), manifest);
}

void ScanService::finish(Record& rec, const Status& status, nlohmann::json manifest) {
  const std::string dir = (fs::path(cfg_.results_dir) / rec.id).string();
  if (manifest.is_null()) manifest = base_manifest(rec);
  const std::string state = status.ok() ? "done" : "failed";
  manifest["state"] = state;
  manifest["finished_utc"] = utc_now();
  manifest["error"] = error_json(status);
  std::error_code ec;
  fs::create_directories(dir, ec);
  // The one-page report (previews + numbers) goes beside the outputs, failed
  // scans included (it then says why); listed in "files" like every output.
  if (Status rs = write_scan_report(dir, manifest); !rs)
    PROCAM_LOG(engine, warn) << "scan " << rec.id << ": report.html: " << rs.to_string();
  manifest["files"] = scan_files(dir);  // manifest.json itself is the `result` reply
  Status ws = write_file_atomic((fs::path(dir) / "manifest.json").string(), manifest.dump(2));
  if (!ws) PROCAM_LOG(engine, error) << "scan " << rec.id << ": " << ws.to_string();
  fsync_dir(dir);
  rec.session.reset();  // release plugin memory (patterns, outputs)
  {
    std::lock_guard lock(mu_);
    rec.state = state;
    rec.error = status;
    rec.finished_utc = manifest["finished_utc"];
    rec.bytes = files_bytes(manifest);
    rec.manifest_on_disk = ws.ok();
    rec.manifest = ws.ok() ? nlohmann::json(nullptr) : std::move(manifest);
    rec.req.params = nlohmann::json::object();       // in the manifest now
    rec.req.rig_options = nlohmann::json::object();
    (status.ok() ? done_ : failed_)++;
    if (!status.ok() && status.code() == Code::cancelled) ++cancelled_;
  }
  if (status.ok()) {
    PROCAM_LOG(engine, info) << "scan " << rec.id << " done";
  } else {
    PROCAM_LOG(engine, warn) << "scan " << rec.id << " failed: " << status.to_string();
  }
  nlohmann::json ev = {{"state", state}};
  if (!status.ok()) ev["error"] = error_json(status);
  emit(rec, "state", ev);
}

}  // namespace procam::engine
