// SPDX-License-Identifier: MIT
// procamd configuration file (JSON) — see configs/procamd.json and README.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"

namespace procam::daemon {

struct Config {
  nlohmann::json rig;                     // the rig config object (loaded if given as a path)
  std::string rig_dir;                    // folder relative rig paths resolve against
  std::vector<std::string> plugin_paths;  // folders searched for *.so plugins
  std::vector<std::string> scene_dirs;    // where sim scene names are looked up
  std::string endpoint = "tcp://127.0.0.1:5560";
  std::string results_dir = "results";
  std::string log = "info";
  unsigned threads = 2;
  size_t max_queue = 16;
  bool probe_plugins = true;
};

// Parses a config file; relative paths resolve against the file's folder.
// Unknown keys and wrong types are errors naming the key.
Result<Config> load_config(const std::string& path);
// Same from an already-parsed object; `base_dir` for relative paths.
Result<Config> parse_config(const nlohmann::json& j, const std::string& base_dir);

}  // namespace procam::daemon
