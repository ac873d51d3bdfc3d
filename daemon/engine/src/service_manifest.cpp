// SPDX-License-Identifier: MIT
// ScanService manifests and status JSON: the manifest skeleton every scan
// starts from, scan summaries and the daemon status reply.
#include <algorithm>
#include <chrono>
#include <tuple>
#include <vector>

#include "procam/proto/protocol.hpp"
#include "service_internal.hpp"

namespace procam::engine {
namespace service_detail {

nlohmann::json error_json(const Status& s) {
  if (s.ok()) return nullptr;
  return proto::error_to_json(s);
}

bool is_final(const std::string& state) { return state == "done" || state == "failed"; }

}  // namespace service_detail

using service_detail::error_json;

// Every field proto/PROTOCOL.md requires, with "nothing yet" values; the
// scan fills them in as it goes.
nlohmann::json ScanService::base_manifest(const Record& rec) const {
  nlohmann::json inputs = nlohmann::json::object();  // what the scan was given (PROTOCOL.md 9)
  for (const auto& [name, src] : rec.req.inputs) inputs[name] = {{"scan", src.scan_id}, {"output", src.output}};
  nlohmann::json m = {{"procam", 1},
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
  if (!inputs.empty()) m["inputs"] = std::move(inputs);
  if (rec.accepted_ns != 0) m["accepted_unix_ns"] = rec.accepted_ns;
  return m;
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
          {"plugin_progress", r.plugin_progress ? nlohmann::json{{"fraction", r.plugin_progress->fraction},
                                                                 {"stage", r.plugin_progress->stage}}
                                                : nlohmann::json(nullptr)},
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
  j["metrics"] = metrics_locked();
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

nlohmann::json ScanService::rig_description() const {
  std::lock_guard lock(mu_);
  nlohmann::json d = rig_description_;
  if (cfg_.calibration_tables.is_object() && !cfg_.calibration_tables.empty())
    d["calibration_tables"] = cfg_.calibration_tables;  // PROTOCOL.md 8
  return d;
}

std::string ScanService::rig_name() const {
  std::lock_guard lock(mu_);
  return rig_description_.value("name", "");
}

nlohmann::json ScanService::list_scans(const std::optional<std::string>& state, uint32_t limit) const {
  std::vector<const Record*> match;
  std::lock_guard lock(mu_);
  for (const auto& [id, r] : scans_) {
    if (state && !(*state == "active" ? !service_detail::is_final(r->state) : r->state == *state)) continue;
    match.push_back(r.get());
  }
  std::sort(match.begin(), match.end(), [](const Record* a, const Record* b) {
    return std::tie(a->created_utc, a->accepted_ns, a->id) > std::tie(b->created_utc, b->accepted_ns, b->id);
  });
  nlohmann::json scans = nlohmann::json::array();
  for (size_t i = 0; i < match.size() && i < limit; ++i) scans.push_back(summary_locked(*match[i]));
  return {{"scans", std::move(scans)}, {"total", match.size()}, {"truncated", match.size() > limit}};
}

nlohmann::json ScanService::rig_options() const {
  return {{"rig", rig_name_}, {"options", rig_->scan_options()}};
}

}  // namespace procam::engine
