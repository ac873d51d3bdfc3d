// SPDX-License-Identifier: MIT
// procamd config parsing with strict keys and path resolution.
#include "config.hpp"

#include <filesystem>
#include <set>

#include "procam/engine/calibration_tables.hpp"
#include "procam/engine/rig_json.hpp"

namespace procam::daemon {
namespace fs = std::filesystem;

namespace {
std::string resolve(const std::string& base, const std::string& p) {
  if (p.empty() || fs::path(p).is_absolute()) return p;
  return (fs::path(base) / p).lexically_normal().string();
}

// "plugins": {"isolation": "process" | "in_process", "trusted": [names],
// "worker": path, "call_timeout_ms", "per_frame_timeout_ms", "memory_limit_mb", "sandbox", "prestart",
// "max_idle_workers", "idle_timeout_ms", "max_sessions_per_worker", "freeze_outputs", "readable": [folders]}.
Status parse_plugins(const nlohmann::json& pv, const std::string& base_dir, PluginsConfig& out) {
  const char* example =
      "{\"isolation\": \"process\", \"trusted\": [\"structured-light\"], \"memory_limit_mb\": 8192}";
  if (!pv.is_object()) return Error(Code::invalid_argument, "daemon config: 'plugins' must be an object", example);
  for (auto it = pv.begin(); it != pv.end(); ++it) {
    const std::string key = "plugins." + it.key();
    const nlohmann::json& v = *it;
    if (it.key() == "isolation") {
      if (!v.is_string() || (v != "process" && v != "in_process"))
        return Error(Code::invalid_argument, "daemon config: '" + key + "' must be \"process\" or \"in_process\"",
                     "\"process\" (the default) runs each scan's plugin in its own worker process");
      out.isolated = v == "process";
    } else if (it.key() == "trusted") {
      if (!v.is_array()) return Error(Code::invalid_argument, "daemon config: '" + key + "' must be an array of plugin names");
      for (const auto& n : v) {
        if (!n.is_string() || n.get<std::string>().empty())
          return Error(Code::invalid_argument, "daemon config: '" + key + "' must hold plugin names (strings)");
        out.trusted.push_back(n.get<std::string>());
      }
    } else if (it.key() == "readable") {
      if (!v.is_array()) return Error(Code::invalid_argument, "daemon config: '" + key + "' must be an array of folders");
      for (const auto& p : v) {
        if (!p.is_string() || p.get<std::string>().empty())
          return Error(Code::invalid_argument, "daemon config: '" + key + "' must hold folder paths (strings)",
                       "folders plugin workers may read besides the plugin's, the system's and their scratch folder");
        out.readable.push_back(resolve(base_dir, p.get<std::string>()));
      }
    } else if (it.key() == "sandbox" || it.key() == "prestart" || it.key() == "freeze_outputs") {
      if (!v.is_boolean()) return Error(Code::invalid_argument, "daemon config: '" + key + "' must be true or false");
      (it.key() == "sandbox" ? out.sandbox : it.key() == "prestart" ? out.prestart : out.freeze_outputs) = v.get<bool>();
    } else if (it.key() == "worker") {
      if (!v.is_string() || v.get<std::string>().empty())
        return Error(Code::invalid_argument, "daemon config: '" + key + "' must be a path to procam-plugin-worker");
      out.worker = resolve(base_dir, v.get<std::string>());
    } else if (it.key() == "call_timeout_ms" || it.key() == "per_frame_timeout_ms" ||
               it.key() == "memory_limit_mb" || it.key() == "max_idle_workers" || it.key() == "idle_timeout_ms" ||
               it.key() == "max_sessions_per_worker") {
      if (!v.is_number_unsigned() || v.get<uint64_t>() > (uint64_t{1} << 32))
        return Error(Code::invalid_argument, "daemon config: '" + key + "' must be an integer 0..4294967296");
      const uint64_t n = v.get<uint64_t>();
      if (it.key() == "call_timeout_ms") {
        if (n == 0) return Error(Code::invalid_argument, "daemon config: '" + key + "' must be > 0");
        out.call_timeout_ms = n;
      } else if (it.key() == "per_frame_timeout_ms") {
        out.per_frame_timeout_ms = n;
      } else if (it.key() == "max_idle_workers") {
        if (n > 64) return Error(Code::invalid_argument, "daemon config: '" + key + "' must be 0..64");
        out.max_idle_workers = n;
      } else if (it.key() == "idle_timeout_ms") {
        out.idle_timeout_ms = n;
      } else if (it.key() == "max_sessions_per_worker") {
        if (n == 0) return Error(Code::invalid_argument, "daemon config: '" + key + "' must be > 0",
                                 "use max_idle_workers 0 to give every scan a fresh worker");
        out.max_sessions_per_worker = n;
      } else {
        out.memory_limit_mb = n;
      }
    } else if (it.key() != "comment") {
      return Error(Code::invalid_argument, "daemon config: unknown key '" + key + "'",
                   "known keys: isolation, trusted, worker, call_timeout_ms, per_frame_timeout_ms, memory_limit_mb, "
                   "sandbox, prestart, max_idle_workers, idle_timeout_ms, max_sessions_per_worker, freeze_outputs, "
                   "readable");
    }
  }
  return {};
}

}  // namespace

Result<Config> parse_config(const nlohmann::json& j, const std::string& base_dir) {
  if (!j.is_object()) return Error(Code::invalid_argument, "daemon config must be a JSON object");
  static const std::set<std::string> known = {"rig", "plugin_paths", "scene_dirs", "endpoint", "results_dir",
                                              "log", "threads", "max_queue", "probe_plugins", "plugins",
                                              "curve", "retention", "queued_scans", "comment"};
  for (auto it = j.begin(); it != j.end(); ++it)
    if (!known.count(it.key()))
      return Error(Code::invalid_argument, "daemon config: unknown key '" + it.key() + "'",
                   "known keys: rig, plugin_paths, scene_dirs, endpoint, results_dir, log, threads, max_queue, "
                   "probe_plugins, plugins, curve, retention, queued_scans");
  Config c;
  std::string key, rig_file;
  try {
    key = "rig";
    if (!j.contains("rig")) return Error(Code::invalid_argument, "daemon config: 'rig' is required", "e.g. \"rig\": \"rigs/sim.json\"");
    if (j["rig"].is_string()) {
      const std::string path = resolve(base_dir, j["rig"].get<std::string>());
      auto rig = engine::read_json_file(path);
      if (!rig) return rig.status().with_context("daemon config 'rig'");
      c.rig = *rig;
      c.rig_dir = fs::path(path).parent_path().string();
      rig_file = path;
    } else if (j["rig"].is_object()) {
      c.rig = j["rig"];
      c.rig_dir = base_dir;
      rig_file = "rig object in the daemon config";
    } else {
      return Error(Code::invalid_argument, "daemon config: 'rig' must be a path or an object");
    }
    key = "rig.calibration_tables";
    auto tables = engine::load_calibration_tables(c.rig, c.rig_dir, rig_file);
    if (!tables) return tables.status();
    c.calibration_tables = std::move(*tables);
    c.rig = engine::without_calibration_tables(std::move(c.rig));
    key = "plugin_paths";
    for (const auto& p : j.value("plugin_paths", std::vector<std::string>{})) c.plugin_paths.push_back(resolve(base_dir, p));
    key = "scene_dirs";
    for (const auto& p : j.value("scene_dirs", std::vector<std::string>{})) c.scene_dirs.push_back(resolve(base_dir, p));
    key = "endpoint";
    c.endpoint = j.value("endpoint", c.endpoint);
    key = "results_dir";
    c.results_dir = resolve(base_dir, j.value("results_dir", c.results_dir));
    key = "log";
    c.log = j.value("log", c.log);
    // Counts are read as JSON integers only: a float such as 1e60 would
    // otherwise be converted to an unsigned type, which is undefined
    // behaviour (found by fuzz_config in CI), and 2.5 would be truncated.
    key = "threads";
    if (j.contains("threads")) {
      const auto& v = j["threads"];
      if (!v.is_number_integer() || v.get<int64_t>() < 1 || v.get<int64_t>() > 256)
        return Error(Code::invalid_argument, "daemon config: 'threads' must be an integer 1..256, got " + v.dump().substr(0, 40),
                     "e.g. \"threads\": 2");
      c.threads = static_cast<decltype(c.threads)>(v.get<int64_t>());
    }
    key = "max_queue";
    if (j.contains("max_queue")) {
      const auto& v = j["max_queue"];
      if (!v.is_number_integer() || v.get<int64_t>() < 1 || v.get<int64_t>() > 100000)
        return Error(Code::invalid_argument,
                     "daemon config: 'max_queue' must be an integer 1..100000, got " + v.dump().substr(0, 40),
                     "e.g. \"max_queue\": 16");
      c.max_queue = static_cast<decltype(c.max_queue)>(v.get<int64_t>());
    }
    key = "probe_plugins";
    c.probe_plugins = j.value("probe_plugins", c.probe_plugins);
    key = "plugins";
    if (j.contains("plugins") && !j["plugins"].is_null()) {
      Status st = parse_plugins(j["plugins"], base_dir, c.plugins);
      if (!st) return st;
    }
    key = "curve";
    if (j.contains("curve") && !j["curve"].is_null()) {
      const auto& cv = j["curve"];
      if (!cv.is_object())
        return Error(Code::invalid_argument, "daemon config: 'curve' must be an object",
                     "{\"secret_key_file\": \"server.secret\", \"authorized_keys\": \"authorized_keys\"}");
      for (auto it = cv.begin(); it != cv.end(); ++it)
        if (it.key() != "secret_key_file" && it.key() != "authorized_keys" && it.key() != "comment")
          return Error(Code::invalid_argument, "daemon config: unknown key 'curve." + it.key() + "'",
                       "known keys: secret_key_file, authorized_keys");
      key = "curve.secret_key_file";
      if (!cv.contains("secret_key_file") || !cv.contains("authorized_keys"))
        return Error(Code::invalid_argument, "daemon config: 'curve' needs 'secret_key_file' and 'authorized_keys'",
                     "make a key pair with `procam keygen --out server`");
      c.curve.secret_key_file = resolve(base_dir, cv["secret_key_file"].get<std::string>());
      key = "curve.authorized_keys";
      c.curve.authorized_keys = resolve(base_dir, cv["authorized_keys"].get<std::string>());
      c.curve.enabled = true;
    }
    key = "retention";
    if (j.contains("retention") && !j["retention"].is_null()) {
      const auto& rv = j["retention"];
      if (!rv.is_object())
        return Error(Code::invalid_argument, "daemon config: 'retention' must be an object",
                     "{\"max_age_days\": 30, \"max_scans\": 1000, \"min_free_mb\": 1024}");
      for (auto it = rv.begin(); it != rv.end(); ++it) {
        key = "retention." + it.key();
        if (it.key() == "max_age_days") {
          if (!it->is_number() || it->get<double>() < 0 || !(it->get<double>() < 1e6))
            return Error(Code::invalid_argument, "daemon config: 'retention.max_age_days' must be a number 0..1e6");
          c.retention_max_age_days = it->get<double>();
        } else if (it.key() == "max_scans" || it.key() == "min_free_mb") {
          if (!it->is_number_unsigned())
            return Error(Code::invalid_argument, "daemon config: '" + key + "' must be an integer >= 0");
          if (it.key() == "max_scans") c.retention_max_scans = it->get<size_t>();
          else c.retention_min_free_mb = it->get<uint64_t>();
        } else if (it.key() != "comment") {
          return Error(Code::invalid_argument, "daemon config: unknown key '" + key + "'",
                       "known keys: max_age_days, max_scans, min_free_mb");
        }
      }
    }
    key = "queued_scans";
    if (j.contains("queued_scans") && !j["queued_scans"].is_null()) {
      const auto& qv = j["queued_scans"];
      if (!qv.is_object())
        return Error(Code::invalid_argument, "daemon config: 'queued_scans' must be an object",
                     "{\"on_restart\": \"run\", \"max_age_s\": 3600}");
      for (auto it = qv.begin(); it != qv.end(); ++it) {
        key = "queued_scans." + it.key();
        if (it.key() == "on_restart") {
          const std::string v = it->is_string() ? it->get<std::string>() : "";
          if (v != "run" && v != "fail")
            return Error(Code::invalid_argument, "daemon config: 'queued_scans.on_restart' must be \"run\" or \"fail\"",
                         "\"run\" queues them again after a crash, \"fail\" reports them failed");
          c.run_queued_on_restart = v == "run";
        } else if (it.key() == "max_age_s") {
          if (!it->is_number_unsigned() || it->get<uint64_t>() > 365ull * 86400)
            return Error(Code::invalid_argument, "daemon config: 'queued_scans.max_age_s' must be an integer 0..31536000");
          c.queued_max_age_s = it->get<uint64_t>();
        } else if (it.key() != "comment") {
          return Error(Code::invalid_argument, "daemon config: unknown key '" + key + "'",
                       "known keys: on_restart, max_age_s");
        }
      }
    }
  } catch (const std::exception& e) {
    return Error(Code::invalid_argument, "daemon config: '" + key + "' has the wrong type: " + e.what());
  }
  if (c.threads == 0 || c.threads > 256) return Error(Code::invalid_argument, "daemon config: 'threads' must be 1..256");
  if (c.max_queue == 0 || c.max_queue > 100000)
    return Error(Code::invalid_argument, "daemon config: 'max_queue' must be 1..100000");
  if (c.endpoint.empty()) return Error(Code::invalid_argument, "daemon config: 'endpoint' must not be empty");
  return c;
}

bool is_local_endpoint(const std::string& ep) {
  if (ep.rfind("ipc://", 0) == 0 || ep.rfind("inproc://", 0) == 0) return true;
  if (ep.rfind("tcp://", 0) != 0) return false;
  const std::string host = ep.substr(6, ep.rfind(':') == std::string::npos || ep.rfind(':') < 6 ? std::string::npos
                                                                                             : ep.rfind(':') - 6);
  return host.rfind("127.", 0) == 0 || host == "localhost" || host == "[::1]" || host == "lo";
}

Result<Config> load_config(const std::string& path) {
  auto j = engine::read_json_file(path);
  if (!j) return j.status();
  auto c = parse_config(*j, fs::absolute(path).parent_path().string());
  if (!c) return c.status().with_context(path);
  return c;
}

}  // namespace procam::daemon
