// SPDX-License-Identifier: MIT
// procamd: the long-running scan daemon. Loads the config, the rig and the
// plugins, then serves ZeroMQ requests until SIGTERM/SIGINT.
#include <signal.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "config.hpp"
#include "procam/core/log.hpp"
#include "procam/core/strings.hpp"
#include "procam/calibration/daemon_job.hpp"
#include "procam/engine/service.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"
#include "server.hpp"

#ifndef PROCAM_DEFAULT_PLUGIN_DIRS
#define PROCAM_DEFAULT_PLUGIN_DIRS ""
#endif

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: procamd --config FILE [--endpoint EP] [--results DIR] [--plugins DIR]...\n"
               "               [--log SPEC] [--no-probe]\n"
               "  --config FILE   daemon config (e.g. configs/procamd.json)\n"
               "  --endpoint EP   ZeroMQ endpoint to bind (default from config, tcp://127.0.0.1:5560)\n"
               "  --results DIR   where scans are written\n"
               "  --plugins DIR   add a plugin folder (also PROCAM_PLUGIN_PATH, colon-separated)\n"
               "  --log SPEC      log levels, e.g. info or daemon=debug,engine=info\n"
               "  --no-probe      load plugins without the crash-isolating probe process\n");
}

int fail(const procam::Status& s, int code) {
  std::fprintf(stderr, "procamd: %s\n", s.to_string().c_str());
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace procam;
  // Block the stop signals in every thread (threads inherit the mask) and
  // receive them through a signalfd in the server's poll loop.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  signal(SIGPIPE, SIG_IGN);

  std::string config_path, endpoint, results, log_spec;
  std::vector<std::string> extra_plugins;
  bool no_probe = false;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&](const char* what) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "procamd: %s needs a value\n", what);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--config") config_path = next("--config");
    else if (a == "--endpoint") endpoint = next("--endpoint");
    else if (a == "--results") results = next("--results");
    else if (a == "--plugins") extra_plugins.push_back(next("--plugins"));
    else if (a == "--log") log_spec = next("--log");
    else if (a == "--no-probe") no_probe = true;
    else if (a == "-h" || a == "--help") { usage(); return 0; }
    else {
      std::fprintf(stderr, "procamd: unknown option '%s'\n", a.c_str());
      usage();
      return 2;
    }
  }
  if (config_path.empty()) {
    usage();
    return 2;
  }
  auto cfg = daemon::load_config(config_path);
  if (!cfg) return fail(cfg.status(), 2);
  if (!endpoint.empty()) cfg->endpoint = endpoint;
  if (!results.empty()) cfg->results_dir = results;
  if (!log_spec.empty()) cfg->log = log_spec;
  if (no_probe) cfg->probe_plugins = false;
  if (!log::configure(cfg->log)) return fail(Error(Code::invalid_argument, "bad log spec '" + cfg->log + "'"), 2);
  for (auto& p : extra_plugins) cfg->plugin_paths.push_back(p);
  if (const char* env = std::getenv("PROCAM_PLUGIN_PATH"))
    for (auto& p : split_nonempty(env)) cfg->plugin_paths.push_back(p);
  if (cfg->plugin_paths.empty()) cfg->plugin_paths = split_nonempty(PROCAM_DEFAULT_PLUGIN_DIRS);

  PROCAM_LOG(daemon, info) << "procamd 0.1.0 starting (config " << config_path << ")";
  hw::RigContext rctx{cfg->rig_dir, cfg->scene_dirs};
  auto rig = hw::create_rig(cfg->rig, rctx);
  if (!rig) return fail(rig.status().with_context("creating the rig"), 3);

  // Plugins are probed in child processes (fork): do it before any thread starts.
  host::LoadOptions lo;
  lo.probe_in_child = cfg->probe_plugins;
  host::PluginHost plugins(lo);
  plugins.load_directories(cfg->plugin_paths);
  {
    host::IsolationOptions iso;  // config "plugins" (daemon/plugin_host/README.md "Process model")
    iso.mode = cfg->plugins.isolated ? host::Isolation::process : host::Isolation::in_process;
    iso.trusted = cfg->plugins.trusted;
    iso.worker_path = cfg->plugins.worker;
    iso.call_timeout = std::chrono::milliseconds(cfg->plugins.call_timeout_ms);
    iso.per_frame_timeout = std::chrono::milliseconds(cfg->plugins.per_frame_timeout_ms);
    iso.memory_limit_mb = cfg->plugins.memory_limit_mb;
    iso.sandbox = cfg->plugins.sandbox;
    iso.prestart = cfg->plugins.prestart;
    iso.max_idle_workers = static_cast<uint32_t>(cfg->plugins.max_idle_workers);
    iso.idle_timeout = std::chrono::milliseconds(cfg->plugins.idle_timeout_ms);
    iso.readable = cfg->plugins.readable;
    iso.freeze_outputs = cfg->plugins.freeze_outputs;
    iso.max_sessions_per_worker = static_cast<uint32_t>(
        std::min<uint64_t>(cfg->plugins.max_sessions_per_worker, UINT32_MAX));
    plugins.set_isolation(std::move(iso));
    PROCAM_LOG(daemon, info) << "plugin sessions run "
                             << (cfg->plugins.isolated ? "in worker processes" : "in-process")
                             << (cfg->plugins.isolated && !cfg->plugins.trusted.empty()
                                     ? " (" + std::to_string(cfg->plugins.trusted.size()) + " trusted in-process)"
                                     : std::string());
  }
  for (const auto& p : plugins.plugins())
    PROCAM_LOG(daemon, info) << "plugin " << p.name << " " << p.version << " (" << p.methods.size()
                             << " methods) from " << p.file;
  for (const auto& r : plugins.rejected())
    PROCAM_LOG(daemon, warn) << "skipped plugin " << r.file << ": " << r.error.to_string();
  if (plugins.plugins().empty())
    PROCAM_LOG(daemon, warn) << "no plugins loaded from: " << [&] {
      std::string s;
      for (auto& p : cfg->plugin_paths) s += p + " ";
      return s;
    }() << "(scans will fail until plugins are installed)";

  int sfd = signalfd(-1, &stop_signals, SFD_CLOEXEC | SFD_NONBLOCK);
  if (sfd < 0) return fail(Error(Code::internal, std::string("signalfd: ") + std::strerror(errno)), 4);

  daemon::Server* server_ptr = nullptr;
  engine::ServiceConfig scfg;
  scfg.results_dir = cfg->results_dir;
  scfg.threads = cfg->threads;
  scfg.max_queue = cfg->max_queue;
  scfg.retention.max_age_days = cfg->retention_max_age_days;
  scfg.retention.max_scans = cfg->retention_max_scans;
  scfg.run_queued_on_restart = cfg->run_queued_on_restart;
  scfg.queued_max_age = std::chrono::seconds(static_cast<int64_t>(cfg->queued_max_age_s));
  scfg.retention.min_free_mb = cfg->retention_min_free_mb;
  scfg.calibration_tables = cfg->calibration_tables;
  // calibrate_geometry requests: decode the pose scans' saved frames with the
  // loaded plugins and fit (procam/calibration/daemon_job.hpp).
  scfg.calibrate_geometry = [&plugins, threads = cfg->threads](const engine::GeometryCalibrationJob& job) {
    return calibration::run_daemon_job(plugins, job, threads);
  };
  for (const auto& [name, table] : cfg->calibration_tables.items())
    PROCAM_LOG(daemon, info) << "calibration table " << name << " (" << table["samples"].size() << " samples)";
  engine::ScanService service(std::move(*rig), plugins, scfg,
                              [&](const std::string& id, const std::string& ev, nlohmann::json f) {
                                if (server_ptr) server_ptr->notify_event(id, ev, std::move(f));
                              });
  daemon::Server server(service, plugins);
  server_ptr = &server;
  if (cfg->curve.enabled) {
    if (auto s = server.enable_curve(cfg->curve); !s) return fail(s, 3);
  } else if (!daemon::is_local_endpoint(cfg->endpoint)) {
    PROCAM_LOG(daemon, warn) << "listening on non-local endpoint " << cfg->endpoint
                             << " WITHOUT authentication or encryption; configure \"curve\" (README "
                                "\"Remote access with CURVE keys\") unless this network is trusted";
  }
  if (auto s = server.bind(cfg->endpoint); !s) return fail(s, 3);
  if (auto s = service.start(); !s) return fail(s, 3);
  PROCAM_LOG(daemon, info) << "ready; results in " << cfg->results_dir;
  server.run(sfd);
  service.stop();
  ::close(sfd);
  PROCAM_LOG(daemon, info) << "stopped cleanly";
  return 0;
}
