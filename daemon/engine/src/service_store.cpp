// SPDX-License-Identifier: MIT
// ScanService results store: the scan folders under results_dir (reload at
// start, durable writes, the files `fetch` may serve).
#include <fcntl.h>
#include <unistd.h>

#include <filesystem>

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
// content is the `result` reply) and temporaries.
nlohmann::json scan_files(const std::string& dir) {
  nlohmann::json out = nlohmann::json::array();
  for (auto& f : list_files(dir))
    if (f.value("name", "") != "manifest.json") out.push_back(f);
  return out;
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
using service_detail::scan_files;
using service_detail::str_field;
using service_detail::error_json;

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

}  // namespace procam::engine
