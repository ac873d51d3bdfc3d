// SPDX-License-Identifier: MIT
// procamd config parsing with strict keys and path resolution.
#include "config.hpp"

#include <filesystem>
#include <set>

#include "procam/engine/rig_json.hpp"

namespace procam::daemon {
namespace fs = std::filesystem;

namespace {
std::string resolve(const std::string& base, const std::string& p) {
  if (p.empty() || fs::path(p).is_absolute()) return p;
  return (fs::path(base) / p).lexically_normal().string();
}
}  // namespace

Result<Config> parse_config(const nlohmann::json& j, const std::string& base_dir) {
  if (!j.is_object()) return Error(Code::invalid_argument, "daemon config must be a JSON object");
  static const std::set<std::string> known = {"rig", "plugin_paths", "scene_dirs", "endpoint", "results_dir",
                                              "log", "threads", "max_queue", "probe_plugins", "comment"};
  for (auto it = j.begin(); it != j.end(); ++it)
    if (!known.count(it.key()))
      return Error(Code::invalid_argument, "daemon config: unknown key '" + it.key() + "'",
                   "known keys: rig, plugin_paths, scene_dirs, endpoint, results_dir, log, threads, max_queue, probe_plugins");
  Config c;
  std::string key;
  try {
    key = "rig";
    if (!j.contains("rig")) return Error(Code::invalid_argument, "daemon config: 'rig' is required", "e.g. \"rig\": \"rigs/sim.json\"");
    if (j["rig"].is_string()) {
      const std::string path = resolve(base_dir, j["rig"].get<std::string>());
      auto rig = engine::read_json_file(path);
      if (!rig) return rig.status().with_context("daemon config 'rig'");
      c.rig = *rig;
      c.rig_dir = fs::path(path).parent_path().string();
    } else if (j["rig"].is_object()) {
      c.rig = j["rig"];
      c.rig_dir = base_dir;
    } else {
      return Error(Code::invalid_argument, "daemon config: 'rig' must be a path or an object");
    }
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
    key = "threads";
    c.threads = j.value("threads", c.threads);
    key = "max_queue";
    c.max_queue = j.value("max_queue", c.max_queue);
    key = "probe_plugins";
    c.probe_plugins = j.value("probe_plugins", c.probe_plugins);
  } catch (const std::exception& e) {
    return Error(Code::invalid_argument, "daemon config: '" + key + "' has the wrong type: " + e.what());
  }
  if (c.threads == 0 || c.threads > 256) return Error(Code::invalid_argument, "daemon config: 'threads' must be 1..256");
  if (c.max_queue == 0) return Error(Code::invalid_argument, "daemon config: 'max_queue' must be >= 1");
  return c;
}

Result<Config> load_config(const std::string& path) {
  auto j = engine::read_json_file(path);
  if (!j) return j.status();
  auto c = parse_config(*j, fs::absolute(path).parent_path().string());
  if (!c) return c.status().with_context(path);
  return c;
}

}  // namespace procam::daemon
