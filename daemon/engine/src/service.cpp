// SPDX-License-Identifier: MIT
// Scan queue + worker (see service.hpp for the contract).
#include "procam/engine/service.hpp"

#include <chrono>
#include <cmath>
#include <ctime>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <vector>

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

// Makes the renames inside `dir` durable (power loss after a finished scan).
void fsync_dir(const std::string& dir) {
  int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

// The files `fetch` serves: everything in the folder but manifest.json (its
// content is the `result` reply) and temporaries.
nlohmann::json scan_files(const std::string& dir) {
  nlohmann::json out = nlohmann::json::array();
  for (auto& f : list_files(dir))
    if (f.value("name", "") != "manifest.json") out.push_back(f);
  return out;
}

bool is_final(const std::string& state) { return state == "done" || state == "failed"; }

// A string field of a manifest read from disk, "" when absent or not a string.
std::string str_field(const nlohmann::json& j, const char* key) {
  if (!j.is_object()) return "";
  auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : "";
}

// The key under which a scan request is remembered: its id and a digest of
// its content (two different 64-bit hashes and the length).
std::string request_key(const std::string& id, const std::string& content) {
  uint64_t fnv = 1469598103934665603ull;
  for (char ch : content) fnv = (fnv ^ static_cast<unsigned char>(ch)) * 1099511628211ull;
  const uint64_t h = std::hash<std::string>{}(content);
  char buf[64];
  std::snprintf(buf, sizeof buf, "\n%016llx%016llx-%zu", static_cast<unsigned long long>(fnv),
                static_cast<unsigned long long>(h), content.size());
  return id + buf;
}

uint64_t files_bytes(const nlohmann::json& manifest) {
  uint64_t n = 0;
  if (manifest.is_object() && manifest.contains("files") && manifest["files"].is_array())
    for (const auto& f : manifest["files"])
      if (f.is_object() && f.contains("size_bytes") && f["size_bytes"].is_number_unsigned())
        n += f["size_bytes"].get<uint64_t>();
  return n;
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

void ScanService::load_existing() {
  std::error_code ec;
  size_t interrupted = 0;
  for (const auto& ent : fs::directory_iterator(cfg_.results_dir, ec)) try {
    std::error_code ec2;
    if (!ent.is_directory(ec2) || ent.is_symlink(ec2)) continue;
    const std::string id = ent.path().filename().string();
    if (id.empty() || id[0] == '.') continue;  // e.g. a folder being deleted
    // Leftover temporaries of a write the daemon did not finish.
    for (const auto& f : fs::directory_iterator(ent.path(), ec2)) {
      const std::string n = f.path().filename().string();
      if (n.size() > 1 && n[0] == '.' && n.find(".tmp") != std::string::npos) fs::remove(f.path(), ec2);
    }
    auto rec = std::make_shared<Record>();
    rec->id = id;
    auto m = read_json_file((ent.path() / "manifest.json").string());
    if (m && m->is_object()) {
      rec->req.plugin = str_field(*m, "plugin");
      rec->req.method = str_field(*m, "method");
      rec->req.label = str_field(*m, "label");
      rec->created_utc = str_field(*m, "created_utc");
      if (m->contains("params") && (*m)["params"].is_object()) rec->req.params = (*m)["params"];
    }
    if (m && m->is_object() && is_final(str_field(*m, "state"))) {
      rec->manifest = *m;
      rec->state = str_field(*m, "state");
      rec->finished_utc = str_field(*m, "finished_utc");
      if (!(*m)["files"].is_array()) rec->manifest["files"] = nlohmann::json::array();
      if (rec->state == "failed") {
        auto e = proto::error_from_json(m->value("error", nlohmann::json()));
        rec->error = e ? *e : Error(Code::internal, "failed (no error recorded)");
      }
    } else {
      // No final manifest: the daemon died while this scan ran. Say so on
      // disk too, so the answer is the same after every later restart.
      ++interrupted;
      rec->state = "failed";
      rec->error = Error(Code::cancelled, "interrupted: the daemon stopped before this scan finished",
                         "scan again");
      rec->finished_utc = utc_now();
      rec->manifest = base_manifest(*rec);
      rec->manifest["state"] = "failed";
      rec->manifest["finished_utc"] = rec->finished_utc;
      rec->manifest["error"] = error_json(rec->error);
      rec->manifest["files"] = scan_files(ent.path().string());
      Status ws = write_file_atomic((ent.path() / "manifest.json").string(), rec->manifest.dump(2));
      if (!ws) PROCAM_LOG(engine, error) << "scan " << id << ": " << ws.to_string();
      fsync_dir(ent.path().string());
    }
    rec->bytes = files_bytes(rec->manifest);
    if (fs::is_regular_file(ent.path() / "manifest.json", ec2)) {
      auto again = read_json_file((ent.path() / "manifest.json").string());
      if (again && again->is_object() && is_final(str_field(*again, "state"))) {
        rec->manifest = nullptr;
        rec->manifest_on_disk = true;
      }
    }
    rec->req.params = nlohmann::json::object();
    scans_[id] = rec;
  } catch (const std::exception& e) {  // a damaged folder must not stop the daemon
    PROCAM_LOG(engine, error) << "skipping '" << ent.path().string() << "': " << e.what();
  }
  if (!scans_.empty()) {
    PROCAM_LOG(engine, info) << "found " << scans_.size() << " earlier scans in " << cfg_.results_dir
                             << (interrupted ? " (" + std::to_string(interrupted) + " interrupted)" : "");
  }
}

Result<nlohmann::json> ScanService::submit(const ScanRequest& req, const std::string& request_id) {
  using Clock = std::chrono::steady_clock;
  const std::string content =
      nlohmann::json{{"plugin", req.plugin}, {"method", req.method}, {"params", req.params},
                     {"rig_options", req.rig_options}, {"label", req.label}, {"save_frames", req.save_frames}}
          .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  {
    std::lock_guard lock(mu_);
    if (stopping_) return Error(Code::unavailable, "the daemon is shutting down", "retry when it is back");
    // Forget old request ids.
    const auto now = Clock::now();
    while (!recent_order_.empty() &&
           (now - recent_order_.front().first > cfg_.dedupe_window || recent_order_.size() > cfg_.dedupe_max)) {
      auto it = recent_requests_.find(recent_order_.front().second);
      if (it != recent_requests_.end() && it->second.at == recent_order_.front().first) recent_requests_.erase(it);
      recent_order_.pop_front();
    }
    const std::string key = request_key(request_id, content);
    if (!request_id.empty()) {
      auto it = recent_requests_.find(key);
      if (it != recent_requests_.end()) {
        auto sc = scans_.find(it->second.scan_id);
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
    if (stopping_) return Error(Code::unavailable, "the daemon is shutting down", "retry when it is back");
    while (scans_.count(rec->id)) rec->id = new_scan_id();
    scans_[rec->id] = rec;
    queue_.push_back(rec);
    reply = {{"scan_id", rec->id}, {"state", "queued"},
             {"queue_position", queue_.size() - 1 + (running_ ? 1 : 0)}};
    if (!request_id.empty()) {
      const auto now = Clock::now();
      const std::string key = request_key(request_id, content);
      recent_requests_[key] = {rec->id, now};
      recent_order_.emplace_back(now, key);
    }
  }
  cv_.notify_all();
  PROCAM_LOG(engine, info) << "scan " << rec->id << " queued: " << req.plugin << "/" << req.method;
  return reply;
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
  {
    // What was asked, on disk from the start: after a crash the restarted
    // daemon reports this scan as interrupted with its plugin, label, params.
    nlohmann::json running = manifest;
    running["state"] = "capturing";
    Status ws = write_file_atomic((fs::path(dir) / "manifest.json").string(), running.dump(2));
    if (!ws) PROCAM_LOG(engine, warn) << "scan " << rec.id << ": " << ws.to_string();
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
  size_t stored = 0;
  for (const auto& [id, r] : scans_) stored += is_final(r->state);
  j["metrics"] = {{"scans_done", done_},
                  {"scans_failed", failed_},
                  {"scans_cancelled", cancelled_},
                  {"scans_rejected_busy", rejected_busy_},
                  {"queue_depth", queue_.size()},
                  {"queue_limit", cfg_.max_queue},
                  {"frames_captured", frames_captured_},
                  {"frames_dropped", frames_dropped_},
                  {"decode_ms", {{"last", decode_ms_last_},
                                 {"mean", decode_count_ ? decode_ms_sum_ / static_cast<double>(decode_count_) : 0.0},
                                 {"max", decode_ms_max_}}},
                  {"results_bytes", results_bytes_},
                  {"scans_stored", stored}};
  if (running_) j["current"] = summary_locked(*running_);
  return j;
}

double ScanService::uptime_s() const {
  std::lock_guard lock(mu_);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
}

Result<nlohmann::json> ScanService::scan_summary(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = scans_.find(id);
  if (it == scans_.end()) return Error(Code::not_found, "no scan with id '" + id + "'", "ask `status` without scan_id or list results");
  return summary_locked(*it->second);
}

Result<nlohmann::json> ScanService::manifest(const std::string& id) const {
  {
    std::lock_guard lock(mu_);
    auto it = scans_.find(id);
    if (it == scans_.end()) return Error(Code::not_found, "no scan with id '" + id + "'");
    const Record& r = *it->second;
    if (r.state != "done" && r.state != "failed")
      return Error(Code::failed_precondition, "scan '" + id + "' is still " + r.state,
                   "wait for its final state event or poll status");
    if (!r.manifest_on_disk) return r.manifest;
  }
  const fs::path path = fs::path(cfg_.results_dir) / id / "manifest.json";
  auto m = read_json_file(path.string());
  if (!m || !m->is_object()) {
    std::error_code ec;
    if (!fs::exists(path, ec)) return Error(Code::not_found, "scan '" + id + "' was deleted");
    return Error(Code::io_error, "cannot read the manifest of scan '" + id + "'",
                 "tell the operator: " + (m ? std::string("not a JSON object") : m.status().message()));
  }
  if (!(*m)["files"].is_array()) (*m)["files"] = nlohmann::json::array();
  return *m;
}

Result<std::string> ScanService::file_path(const std::string& id, const std::string& file) const {
  if (!proto::is_safe_file_name(file) || !proto::is_safe_file_name(id))
    return Error(Code::invalid_argument, "'" + file + "' is not a plain file name", "use a name from the manifest's \"files\"");
  auto m = manifest(id);
  if (!m) return m.status();
  bool listed = false;
  for (const auto& f : (*m)["files"]) listed |= f.is_object() && f.value("name", "") == file;
  if (!listed)
    return Error(Code::not_found, "scan '" + id + "' has no file '" + file + "'", "see the manifest's \"files\"");
  // The folder and file must really be inside results_dir: no symlinks out.
  const fs::path p = fs::path(cfg_.results_dir) / id / file;
  std::error_code ec;
  const auto st = fs::symlink_status(p, ec);
  const auto dst = fs::symlink_status(p.parent_path(), ec);
  if (!fs::is_regular_file(st) || !fs::is_directory(dst))
    return Error(Code::not_found, "file '" + file + "' of scan '" + id + "' is missing or not a regular file",
                 "tell the operator: the results folder was changed by hand");
  {
    std::lock_guard lock(mu_);
    auto it = scans_.find(id);
    if (it != scans_.end()) it->second->last_download = std::chrono::steady_clock::now();
  }
  return p.string();
}

size_t ScanService::apply_retention() {
  const auto& pol = cfg_.retention;
  struct Cand { std::string finished, id; uint64_t bytes; };
  std::vector<Cand> cands;
  uint64_t total = 0;
  const auto now = std::chrono::steady_clock::now();
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, r] : scans_) {
      if (!is_final(r->state)) continue;
      total += r->bytes;
      if (r->last_download && now - *r->last_download < pol.download_grace) continue;  // being downloaded
      cands.push_back({r->finished_utc, id, r->bytes});
    }
    results_bytes_ = total;
  }
  if (pol.max_age_days <= 0 && pol.max_scans == 0 && pol.min_free_mb == 0) return 0;
  std::sort(cands.begin(), cands.end(),
            [](const Cand& a, const Cand& b) { return std::tie(a.finished, a.id) < std::tie(b.finished, b.id); });
  size_t stored = 0;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, r] : scans_) stored += is_final(r->state);
  }
  const std::time_t cutoff =
      std::time(nullptr) - static_cast<std::time_t>(pol.max_age_days * 86400.0);
  char cutoff_utc[32] = "";
  if (pol.max_age_days > 0) {
    std::tm tm{};
    gmtime_r(&cutoff, &tm);
    std::strftime(cutoff_utc, sizeof cutoff_utc, "%Y-%m-%dT%H:%M:%S", &tm);
  }
  auto low_disk = [&] {
    if (pol.min_free_mb == 0) return false;
    std::error_code ec;
    auto sp = fs::space(cfg_.results_dir, ec);
    return !ec && sp.available < pol.min_free_mb * 1024 * 1024;
  };
  size_t deleted = 0;
  for (const auto& c : cands) {
    const bool too_old = pol.max_age_days > 0 && !c.finished.empty() && c.finished < std::string(cutoff_utc);
    const bool too_many = pol.max_scans > 0 && stored > pol.max_scans;
    if (!too_old && !too_many && !low_disk()) continue;
    {
      std::lock_guard lock(mu_);
      auto it = scans_.find(c.id);
      if (it == scans_.end()) continue;
      if (it->second->last_download && now - *it->second->last_download < pol.download_grace) continue;
      scans_.erase(it);
      results_bytes_ -= std::min(results_bytes_, c.bytes);
    }
    // Rename first so a half-deleted folder is never loaded as a scan.
    std::error_code ec;
    const fs::path dir = fs::path(cfg_.results_dir) / c.id;
    const fs::path doomed = fs::path(cfg_.results_dir) / ("." + c.id + ".deleting");
    fs::rename(dir, doomed, ec);
    fs::remove_all(ec ? dir : doomed, ec);
    --stored;
    ++deleted;
    PROCAM_LOG(engine, info) << "retention: deleted scan " << c.id << " (finished " << c.finished << ")"
                             << (too_old ? " [age]" : too_many ? " [count]" : " [disk]");
  }
  return deleted;
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
