// SPDX-License-Identifier: MIT
// Scan queue + worker (see service.hpp for the contract).
#include "procam/engine/service.hpp"

#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <random>

#include "procam/core/log.hpp"
#include "procam/engine/evaluate.hpp"
#include "procam/engine/results.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/proto/protocol.hpp"

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

nlohmann::json error_json(const Status& s) {
  if (s.ok()) return nullptr;
  return proto::error_to_json(s);
}

}  // namespace

struct ScanService::Record {
  std::string id;
  ScanRequest req;
  std::string state = "queued";
  std::string created_utc, finished_utc;
  Progress progress;
  Status error;
  std::optional<host::Session> session;  // until the scan runs
  nlohmann::json manifest;               // when finished
  uint64_t seq = 0;
};

ScanService::ScanService(std::unique_ptr<hw::Rig> rig, const host::PluginHost& plugins,
                         ServiceConfig cfg, EventSink sink)
    : rig_(std::move(rig)), plugins_(plugins), cfg_(std::move(cfg)), sink_(std::move(sink)) {
  rig_description_ = rig_->describe();
  rig_name_ = rig_description_.value("name", "");
  plugin_rig_json_ = plugin_rig_json(*rig_, cfg_.threads);
}

ScanService::~ScanService() { stop(); }

Status ScanService::start() {
  std::error_code ec;
  fs::create_directories(cfg_.results_dir, ec);
  if (ec)
    return Error(Code::io_error, "cannot create results folder '" + cfg_.results_dir + "': " + ec.message(),
                 "set results_dir in the daemon config to a writable folder");
  load_existing();
  started_ = std::chrono::steady_clock::now();
  worker_ = std::thread([this] { worker_loop(); });
  return Status::Ok();
}

void ScanService::stop() {
  {
    std::lock_guard lock(mu_);
    if (stopping_ && !worker_.joinable()) return;
    stopping_ = true;
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

void ScanService::load_existing() {
  std::error_code ec;
  for (const auto& ent : fs::directory_iterator(cfg_.results_dir, ec)) {
    if (!ent.is_directory()) continue;
    const std::string id = ent.path().filename().string();
    auto rec = std::make_shared<Record>();
    rec->id = id;
    auto m = read_json_file((ent.path() / "manifest.json").string());
    if (m && m->is_object() && (m->value("state", "") == "done" || m->value("state", "") == "failed")) {
      rec->manifest = *m;
      rec->state = m->value("state", "failed");
      rec->req.plugin = m->value("plugin", "");
      rec->req.method = m->value("method", "");
      rec->req.label = m->value("label", "");
      rec->created_utc = m->value("created_utc", "");
      rec->finished_utc = m->value("finished_utc", "");
      if (rec->state == "failed") {
        const auto& e = (*m)["error"];
        rec->error = Error(Code::internal, e.is_object() ? e.value("message", "failed") : "failed");
      }
    } else {
      rec->state = "failed";
      rec->error = Error(Code::cancelled, "interrupted: the daemon stopped before this scan finished");
      rec->manifest = base_manifest(*rec);
      rec->manifest["state"] = "failed";
      rec->manifest["error"] = error_json(rec->error);
      rec->manifest["files"] = list_files(ent.path().string());
    }
    scans_[id] = rec;
  }
  if (!scans_.empty()) {
    PROCAM_LOG(engine, info) << "found " << scans_.size() << " earlier scans in " << cfg_.results_dir;
  }
}

Result<nlohmann::json> ScanService::submit(const ScanRequest& req) {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return Error(Code::unavailable, "the daemon is shutting down");
    if (queue_.size() >= cfg_.max_queue)
      return Error(Code::unavailable,
                   "busy: " + std::to_string(queue_.size() + (running_ ? 1 : 0)) + " scans ahead of you",
                   "retry later");
  }
  auto session = plugins_.create_session(req.plugin, req.method, req.params.dump(), plugin_rig_json_.dump());
  if (!session) return session.status();
  auto rec = std::make_shared<Record>();
  rec->id = new_scan_id();
  rec->req = req;
  rec->created_utc = utc_now();
  rec->session.emplace(std::move(*session));
  nlohmann::json reply;
  {
    std::lock_guard lock(mu_);
    while (scans_.count(rec->id)) rec->id = new_scan_id();
    scans_[rec->id] = rec;
    queue_.push_back(rec);
    reply = {{"scan_id", rec->id}, {"state", "queued"},
             {"queue_position", queue_.size() - 1 + (running_ ? 1 : 0)}};
  }
  cv_.notify_all();
  PROCAM_LOG(engine, info) << "scan " << rec->id << " queued: " << req.plugin << "/" << req.method;
  return reply;
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
    }
    run_one(*rec);
    std::lock_guard lock(mu_);
    running_.reset();
  }
}

void ScanService::emit(Record& rec, const std::string& event, nlohmann::json fields) {
  if (sink_) sink_(rec.id, event, std::move(fields));
}

void ScanService::run_one(Record& rec) {
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
  set_state("capturing");
  Status st = rig_->apply_scan_options(rec.req.rig_options);
  {
    std::lock_guard lock(mu_);
    rig_description_ = rig_->describe();
    manifest["rig"] = {{"name", rig_description_.value("name", "")},
                       {"state", rig_description_.value("state", nlohmann::json::object())}};
  }
  if (!st) {
    finish(rec, st.with_context("rig_options"), manifest);
    return;
  }
  host::Session& session = *rec.session;
  std::string last_stage;
  auto progress = [&](const Progress& p) {
    {
      std::lock_guard lock(mu_);
      rec.progress = p;
      if (p.stage == "decode" && rec.state != "decoding") rec.state = "decoding";
      else if (p.stage == "capture" && rec.state != "capturing") rec.state = "capturing";
    }
    emit(rec, "progress", {{"stage", p.stage}, {"round", p.round}, {"done", p.done}, {"total", p.total},
                           {"message", p.message}});
  };
  auto outcome = run_scan(*rig_, session, cfg_.capture, progress, cancel_running_);
  if (!outcome) {
    finish(rec, outcome.status(), manifest);
    return;
  }
  nlohmann::json rounds = nlohmann::json::array();
  for (const auto& r : outcome->rounds) rounds.push_back({{"note", r.note}, {"frames", r.frames}});
  manifest["plan"] = {{"rounds", rounds}, {"patterns", outcome->patterns}};

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
  if (cfg_.evaluate) {
    auto truth = rig_->ground_truth(0);
    if (truth) {
      const host::Output* col = nullptr;
      const host::Output* depth = nullptr;
      for (const auto& o : *outs) {
        if (o.kind != PROCAM_OUTPUT_IMAGE) continue;
        if (o.name == "proj_col_px") col = &o;
        if (o.name == "depth_mm") depth = &o;
      }
      if (col) {
        Image c = Image::copy_of(col->image);
        Image d = depth ? Image::copy_of(depth->image) : Image();
        manifest["evaluation"] = evaluate_correspondence(c, depth ? &d : nullptr, *truth);
        manifest["evaluation"]["truth"] = "simulated rig ground truth, camera 0";
      }
    }
  }
  const double write_ms = std::chrono::duration<double, std::milli>(Clock::now() - tw).count();
  manifest["timing_ms"] = {{"capture", outcome->capture_ms}, {"decode", outcome->decode_ms},
                           {"write", write_ms},
                           {"total", std::chrono::duration<double, std::milli>(Clock::now() - t0).count()}};
  manifest["frames_retried"] = outcome->frames_retried;
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
  manifest["files"] = list_files(dir);  // manifest.json itself is the `result` reply
  Status ws = write_file_atomic((fs::path(dir) / "manifest.json").string(), manifest.dump(2));
  if (!ws) PROCAM_LOG(engine, error) << "scan " << rec.id << ": " << ws.to_string();
  rec.session.reset();  // release plugin memory (patterns, outputs)
  {
    std::lock_guard lock(mu_);
    rec.state = state;
    rec.error = status;
    rec.finished_utc = manifest["finished_utc"];
    rec.manifest = std::move(manifest);
    (status.ok() ? done_ : failed_)++;
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

// Every field proto/PROTOCOL.md requires, with "nothing yet" values; the
// scan fills them in as it goes.
nlohmann::json ScanService::base_manifest(const Record& rec) const {
  return {{"procam", 1},
          {"scan_id", rec.id},
          {"state", rec.state},
          {"plugin", rec.req.plugin},
          {"method", rec.req.method},
          {"params", rec.req.params},
          {"label", rec.req.label},
          {"rig", {{"name", rig_name_}, {"state", nlohmann::json::object()}}},
          {"created_utc", rec.created_utc.empty() ? nlohmann::json(nullptr) : nlohmann::json(rec.created_utc)},
          {"finished_utc", nullptr},
          {"plan", {{"rounds", nlohmann::json::array()}, {"patterns", 0}}},
          {"timing_ms", {{"capture", 0}, {"decode", 0}, {"write", 0}, {"total", 0}}},
          {"outputs", nlohmann::json::array()},
          {"previews", nlohmann::json::array()},
          {"files", nlohmann::json::array()},
          {"error", nullptr}};
}

nlohmann::json ScanService::summary_locked(const Record& r) const {
  return {{"scan_id", r.id},
          {"state", r.state},
          {"plugin", r.req.plugin},
          {"method", r.req.method},
          {"label", r.req.label},
          {"created_utc", r.created_utc},
          {"finished_utc", r.finished_utc.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.finished_utc)},
          {"progress", r.progress.stage.empty()
                           ? nlohmann::json(nullptr)
                           : nlohmann::json{{"stage", r.progress.stage}, {"round", r.progress.round},
                                            {"done", r.progress.done}, {"total", r.progress.total}}},
          {"error", error_json(r.error)}};
}

nlohmann::json ScanService::daemon_status() const {
  std::lock_guard lock(mu_);
  const double up = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  nlohmann::json j = {{"version", "procamd 0.1.0"},
                      {"uptime_s", up},
                      {"state", running_ ? "scanning" : "idle"},
                      {"scans", {{"done", done_}, {"failed", failed_}, {"queued", queue_.size()}}},
                      {"plugins", plugins_.plugins().size()},
                      {"rig", rig_description_.value("name", "")}};
  if (running_) j["current"] = summary_locked(*running_);
  return j;
}

Result<nlohmann::json> ScanService::scan_summary(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = scans_.find(id);
  if (it == scans_.end()) return Error(Code::not_found, "no scan with id '" + id + "'", "ask `status` without scan_id or list results");
  return summary_locked(*it->second);
}

Result<nlohmann::json> ScanService::manifest(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = scans_.find(id);
  if (it == scans_.end()) return Error(Code::not_found, "no scan with id '" + id + "'");
  const Record& r = *it->second;
  if (r.state != "done" && r.state != "failed")
    return Error(Code::failed_precondition, "scan '" + id + "' is still " + r.state,
                 "wait for its final state event or poll status");
  return r.manifest;
}

Result<std::string> ScanService::file_path(const std::string& id, const std::string& file) const {
  auto m = manifest(id);
  if (!m) return m.status();
  for (const auto& f : (*m)["files"])
    if (f.value("name", "") == file) return (fs::path(cfg_.results_dir) / id / file).string();
  return Error(Code::not_found, "scan '" + id + "' has no file '" + file + "'", "see the manifest's \"files\"");
}

nlohmann::json ScanService::rig_description() const {
  std::lock_guard lock(mu_);
  return rig_description_;
}

std::string ScanService::rig_name() const {
  std::lock_guard lock(mu_);
  return rig_description_.value("name", "");
}

}  // namespace procam::engine
