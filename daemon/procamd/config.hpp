// SPDX-License-Identifier: MIT
// procamd configuration file (JSON) — see configs/procamd.json and README.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"

namespace procam::daemon {

// Remote access: ZeroMQ CURVE with an allowlist (README "Remote access with CURVE keys").
struct CurveConfig {
  bool enabled = false;
  std::string secret_key_file;   // the daemon's secret key (Z85, from `procam keygen`), mode 0600
  std::string authorized_keys;   // file: one client public key (Z85) per line, '#' comments
};

// Where plugin sessions run (daemon/plugin_host/README.md "Process model");
// main.cpp turns this into host::IsolationOptions. Plain fields so the
// config parser builds without the plugin host (the fuzzer links it alone).
struct PluginsConfig {
  bool isolated = true;                 // "isolation": "process" (default) | "in_process"
  std::vector<std::string> trusted;     // plugin names that run in-process anyway
  std::string worker;                   // procam-plugin-worker path; "" = beside procamd
  uint64_t call_timeout_ms = 30000;     // per-call deadline of a worker
  uint64_t per_frame_timeout_ms = 1000; // + this per frame for end_round / get_outputs
  uint64_t memory_limit_mb = 8192;      // worker RLIMIT_AS; 0 = none
  bool sandbox = true;                  // least privilege for workers (scratch folder, Landlock, seccomp)
  bool prestart = true;                 // keep one worker started ahead
  // Worker reuse (daemon/plugin_host/README.md "Worker reuse"): idle
  // workers kept per plugin (0: a fresh worker per scan), how long one
  // waits, how many scans one serves.
  uint64_t max_idle_workers = 1;
  uint64_t idle_timeout_ms = 60000;
  uint64_t max_sessions_per_worker = 100;
  // With reuse on: stop the worker (SIGSTOP) while the daemon reads its
  // outputs in place, instead of copying them (README.md "Speed").
  bool freeze_outputs = true;
  std::vector<std::string> readable;  // more folders a sandboxed worker may read
};

struct Config {
  nlohmann::json rig;                     // the rig config object (loaded if given as a path)
  std::string rig_dir;                    // folder relative rig paths resolve against
  // The rig config's "calibration_tables", loaded and checked
  // (engine/calibration_tables.hpp): table name -> table. The key is removed
  // from `rig` (hardware backends do not know it).
  nlohmann::json calibration_tables = nlohmann::json::object();
  std::vector<std::string> plugin_paths;  // folders searched for *.so plugins
  std::vector<std::string> scene_dirs;    // where sim scene names are looked up
  std::string endpoint = "tcp://127.0.0.1:5560";
  std::string results_dir = "results";
  std::string log = "info";
  unsigned threads = 2;
  size_t max_queue = 16;
  bool probe_plugins = true;
  PluginsConfig plugins;
  CurveConfig curve;
  // Retention of finished scans (0 = no limit); see engine::RetentionPolicy.
  double retention_max_age_days = 0;
  size_t retention_max_scans = 0;
  uint64_t retention_min_free_mb = 0;
  // "queued_scans": {"on_restart": "run" | "fail", "max_age_s": 3600}: what a
  // start does with scans that were queued when the daemon died
  // (engine::ServiceConfig::run_queued_on_restart / queued_max_age).
  bool run_queued_on_restart = true;
  uint64_t queued_max_age_s = 3600;
};

// True for endpoints only this machine can reach: ipc://, inproc://,
// tcp://127.x.x.x, tcp://[::1], tcp://localhost.
bool is_local_endpoint(const std::string& endpoint);

// Parses a config file; relative paths resolve against the file's folder.
// Unknown keys and wrong types are errors naming the key. Never throws (the
// parser is fuzzed: tests/fuzz/).
Result<Config> load_config(const std::string& path);
// Same from an already-parsed object; `base_dir` for relative paths.
Result<Config> parse_config(const nlohmann::json& j, const std::string& base_dir);

}  // namespace procam::daemon
