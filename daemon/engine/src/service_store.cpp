// SPDX-License-Identifier: MIT
// ScanService results store: the scan folders under results_dir (reload at
// start, durable writes, the files `fetch` may serve).
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <tuple>

#include "procam/core/log.hpp"
#include "procam/engine/results.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/proto/protocol.hpp"
#include "service_internal.hpp"

namespace procam::engine {
namespace fs = std::filesystem;
namespace service_detail {

// Makes the renames inside `dir` durable (power loss after a finished scan).
void fsync_dir(const std::string& dir) {
  int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

// The files `fetch` serves: everything in the folder but manifest.json (its
// content is the `result` reply), request.json (the daemon's record of the
// request, also in the manifest) and temporaries.
nlohmann::json scan_files(const std::string& dir) {
  nlohmann::json out = nlohmann::json::array();
  for (auto& f : list_files(dir)) {
    const std::string n = f.value("name", "");
    if (n != "manifest.json" && n != "request.json") out.push_back(f);
  }
  return out;
}

nlohmann::json request_to_json(const ScanRequest& req) {
  nlohmann::json inputs = nlohmann::json::object();
  for (const auto& [name, src] : req.inputs) inputs[name] = {{"scan", src.scan_id}, {"output", src.output}};
  return {{"procam", 1},         {"plugin", req.plugin},   {"method", req.method},
          {"label", req.label},  {"params", req.params},   {"rig_options", req.rig_options},
          {"save_frames", req.save_frames}, {"inputs", inputs}};
}

Result<ScanRequest> request_from_json(const nlohmann::json& j) {
  auto bad = [](const std::string& what) {
    return Error(Code::corrupt_data, "request.json: " + what, "the scan folder was changed by hand; scan again");
  };
  if (!j.is_object()) return bad("not a JSON object");
  ScanRequest r;
  for (const char* k : {"plugin", "method", "label"})
    if (!j.contains(k) || !j[k].is_string()) return bad(std::string("'") + k + "' is not a string");
  r.plugin = j["plugin"];
  r.method = j["method"];
  r.label = j["label"];
  for (const char* k : {"params", "rig_options", "inputs"})
    if (!j.contains(k) || !j[k].is_object()) return bad(std::string("'") + k + "' is not an object");
  r.params = j["params"];
  r.rig_options = j["rig_options"];
  if (!j.contains("save_frames") || !j["save_frames"].is_boolean()) return bad("'save_frames' is not a boolean");
  r.save_frames = j["save_frames"];
  for (auto it = j["inputs"].begin(); it != j["inputs"].end(); ++it) {
    const auto& v = *it;
    if (!v.is_object() || !v.contains("scan") || !v["scan"].is_string() || !v.contains("output") ||
        !v["output"].is_string())
      return bad("input '" + it.key() + "' is not {\"scan\", \"output\"}");
    r.inputs[it.key()] = {v["scan"], v["output"]};
  }
  return r;
}

Status persist_queued(const std::string& results_dir, const std::string& id, const ScanRequest& req,
                      nlohmann::json manifest) {
  const fs::path dir = fs::path(results_dir) / id;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec)
    return Error(Code::io_error, "cannot create scan folder '" + dir.string() + "': " + ec.message(),
                 "check that the results folder is writable and not full");
  manifest["state"] = "queued";
  Status st = write_file_atomic((dir / "request.json").string(), request_to_json(req).dump(2));
  if (st) st = write_file_atomic((dir / "manifest.json").string(), manifest.dump(2));
  if (!st) {
    fs::remove_all(dir, ec);
    return Error(st.code(), "cannot keep the queued scan on disk: " + st.message(),
                 "check that the results folder is writable and not full");
  }
  fsync_dir(dir.string());
  fsync_dir(results_dir);
  return Status::Ok();
}

std::optional<double> seconds_since_utc(const std::string& utc) {
  std::tm tm{};
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, sec = 0;
  if (std::sscanf(utc.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d", &y, &mo, &d, &h, &mi, &sec) != 6) return std::nullopt;
  tm.tm_year = y - 1900;
  tm.tm_mon = mo - 1;
  tm.tm_mday = d;
  tm.tm_hour = h;
  tm.tm_min = mi;
  tm.tm_sec = sec;
  const std::time_t t = timegm(&tm);
  if (t == static_cast<std::time_t>(-1)) return std::nullopt;
  return std::difftime(std::time(nullptr), t);
}

// A string field of a manifest read from disk, "" when absent or not a string.
std::string str_field(const nlohmann::json& j, const char* key) {
  if (!j.is_object()) return "";
  auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : "";
}

// Sum of "size_bytes" over the manifest's files.
uint64_t files_bytes(const nlohmann::json& manifest) {
  uint64_t n = 0;
  if (manifest.is_object() && manifest.contains("files") && manifest["files"].is_array())
    for (const auto& f : manifest["files"])
      if (f.is_object() && f.contains("size_bytes") && f["size_bytes"].is_number_unsigned())
        n += f["size_bytes"].get<uint64_t>();
  return n;
}

}  // namespace service_detail

using service_detail::files_bytes;
using service_detail::fsync_dir;
using service_detail::is_final;
using service_detail::request_from_json;
using service_detail::scan_files;
using service_detail::seconds_since_utc;
using service_detail::str_field;
using service_detail::error_json;

void ScanService::load_existing() {
  std::error_code ec;
  size_t interrupted = 0;
  std::vector<std::pair<std::shared_ptr<Record>, Result<ScanRequest>>> queued;
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
      if (const auto it = m->find("accepted_unix_ns"); it != m->end() && it->is_number_unsigned())
        rec->accepted_ns = it->get<uint64_t>();
      if (m->contains("params") && (*m)["params"].is_object()) rec->req.params = (*m)["params"];
    }
    if (m && m->is_object() && str_field(*m, "state") == "queued") {
      // Accepted but never started when the daemon died: restart_queued() decides.
      auto req = read_json_file((ent.path() / "request.json").string());
      queued.emplace_back(rec, req ? request_from_json(*req) : Result<ScanRequest>(req.status()));
      continue;
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
  restart_queued(std::move(queued));
}

void ScanService::restart_queued(std::vector<std::pair<std::shared_ptr<Record>, Result<ScanRequest>>> found) {
  // Their old order: acceptance time (seconds, then accepted_ns within a
  // second), then id.
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) {
    return std::tie(a.first->created_utc, a.first->accepted_ns, a.first->id) <
           std::tie(b.first->created_utc, b.first->accepted_ns, b.first->id);
  });
  size_t requeued = 0, failed = 0;
  for (auto& [rec, req] : found) {
    Status why;
    if (!req) {
      why = req.status().with_context("queued before a restart, but its request cannot be read");
    } else {
      rec->req = *req;
      const auto age = seconds_since_utc(rec->created_utc);
      if (!cfg_.run_queued_on_restart) {
        why = Error(Code::cancelled, "the daemon restarted before this scan started",
                    "scan again (procamd is configured with queued_scans.on_restart \"fail\")");
      } else if (!age || *age > static_cast<double>(cfg_.queued_max_age.count())) {
        why = Error(Code::cancelled,
                    "stale: queued at " + (rec->created_utc.empty() ? std::string("an unknown time") : rec->created_utc) +
                        ", more than " + std::to_string(cfg_.queued_max_age.count()) +
                        " s before the daemon restarted",
                    "scan again if still wanted (queued_scans.max_age_s in the daemon config)");
      } else if (service_detail::is_calibration(rec->req)) {
        if (auto job = check_calibration(rec->req); !job) {
          why = job.status().with_context("queued before a restart, but can no longer run");
        } else {
          std::lock_guard lock(mu_);
          scans_[rec->id] = rec;
          queue_.push_back(rec);
          ++requeued;
          continue;
        }
      } else if (auto session = make_session(rec->req); !session) {
        why = session.status().with_context("queued before a restart, but can no longer run");
      } else {
        rec->session.emplace(std::move(*session));
        std::lock_guard lock(mu_);
        scans_[rec->id] = rec;
        queue_.push_back(rec);
        ++requeued;
        continue;
      }
    }
    ++failed;
    {
      std::lock_guard lock(mu_);
      scans_[rec->id] = rec;
    }
    finish(*rec, why, {});
  }
  if (!found.empty())
    PROCAM_LOG(engine, info) << found.size() << " scans were queued when the daemon stopped: " << requeued
                             << " queued again, " << failed << " failed";
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
  // A scan id that cannot exist is an unknown scan (PROTOCOL.md 5.7:
  // not_found), not a bad file name.
  if (!proto::is_safe_file_name(id))
    return Error(Code::not_found, "no scan with id '" + id + "'", "use a scan_id from a `scan` reply or `status`");
  if (!proto::is_safe_file_name(file))
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

}  // namespace procam::engine
