// SPDX-License-Identifier: MIT
// PluginHost: finds decoder plugins, checks them before and while loading,
// and runs scan sessions through the C ABI (procam/plugin_abi.h).
//
// Loading a file, in order (details and every rejection reason: README.md):
//   1. read procam_plugin_info straight from the ELF file (no plugin code runs)
//      and check magic, ABI version, struct size, strings, name, machine;
//   2. probe in a forked child: dlopen, procam_plugin_create, vtable, describe()
//      -- a crash, hang or failure there rejects the plugin, the daemon lives;
//   3. dlopen in this process and repeat the checks of step 2.
//
// Threads: PluginHost is filled (load_*) on one thread, then read-only:
// plugins(), rejected(), find() and create_session() are safe from any thread.
// Probing fork()s, so load_* must run BEFORE the process starts threads
// (see LoadOptions::probe_in_child). A Session is used by one thread at a time.
//
// Errors: nothing throws; every failure is a Status naming the plugin and what
// was wrong. Everything a plugin returns is validated before use; a plugin
// returning garbage gives Code::plugin_error.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/log.hpp"
#include "procam/core/status.hpp"
#include "procam/plugin_abi.h"

namespace procam::host {

namespace detail {
struct LoadedPlugin;  // dlopen handle + vtable; defined in src/plugin_loader.hpp
class HostBridge;     // the session's procam_host_services; src/host_services.hpp
class WorkerProxy;    // an isolated session's worker process; src/worker_proxy.hpp
struct SparePool;     // a pre-started worker; src/worker_proxy.hpp
struct IdlePool;      // workers kept for reuse between sessions; src/worker_proxy.hpp
}

// One input a method declares in describe()'s "inputs" (plugin_abi.h "Scan
// inputs"), validated when the plugin loads.
struct InputSpec {
  std::string name;         // [a-z0-9_]{1,64}, e.g. "depth_mm"
  std::string kind;         // "image_f32": a 1-channel F32 map of camera 0's size
  std::string unit;         // e.g. "mm"; "" when not given
  bool required = true;
  std::string description;  // what the method does with it
};

// One method of a plugin. `describe` is that method's object from the
// plugin's describe() JSON array (it has at least "name"; parameters etc. are
// passed through as the plugin wrote them).
struct MethodInfo {
  std::string name;
  std::string description;  // describe()'s "description" for the method, or ""
  nlohmann::json describe;
  std::vector<InputSpec> inputs;  // empty: the method takes no inputs
};

// An input handed to create_session: a view the caller owns, read only during
// that call (the plugin copies what it keeps).
struct InputImage {
  std::string name;         // one of the method's InputSpec names
  std::string unit;         // passed to the plugin as the output's unit
  std::string description;  // where it came from, e.g. "depth_mm of scan 2026...-1a2b3c"
  procam_image image{};     // for kind image_f32: 1 channel, PROCAM_PIXEL_F32
};

struct PluginInfo {
  std::string name;                 // procam_plugin_info.name, matches [a-z0-9_-]{1,63}
  std::string version;              // procam_plugin_info.version
  uint32_t abi = PROCAM_PLUGIN_ABI_VERSION;  // plugin ABI it was built for (1, 2 or 3)
  std::string file;                 // path it was loaded from
  std::vector<MethodInfo> methods;  // in procam_plugin_info.methods order
};

struct Rejected {
  std::string file;  // the path (or directory) that was rejected
  Status error;      // abi_mismatch, corrupt_data, plugin_error, timeout, ...
};

struct LoadOptions {
  // Probe every plugin in a forked child first (see file comment). Turn off
  // only where fork() is forbidden or the process already runs threads: then a
  // plugin that crashes or hangs while loading takes the process down with it.
  bool probe_in_child = true;
  // How long the child may take (dlopen + create + describe) before it is
  // killed and the plugin rejected with Code::timeout.
  std::chrono::milliseconds probe_timeout{5000};
};

// Where sessions run (README.md "Process model"). Isolated (the default):
// each session gets its own procam-plugin-worker process, which loads the
// same .so with the same checks; a crash, hang, memory blow-up or garbage
// there fails that scan only. In-process: the plugin runs in this process
// (the last bit of speed, for plugins you trust).
enum class Isolation { process, in_process };

struct IsolationOptions {
  Isolation mode = Isolation::process;
  // Plugin names that run in-process even when mode is `process`.
  std::vector<std::string> trusted;
  // The worker executable; "" = find it (PROCAM_PLUGIN_WORKER, beside the
  // running executable, ../libexec/procam/, the build tree).
  std::string worker_path;
  // Per-call deadlines: every call gets call_timeout; end_round and
  // get_outputs get per_frame_timeout more per frame of the round. A worker
  // that misses one is killed and the call fails with Code::timeout.
  std::chrono::milliseconds call_timeout{30000};
  std::chrono::milliseconds per_frame_timeout{1000};
  // Spawn, load the plugin, session_create.
  std::chrono::milliseconds start_timeout{30000};
  // RLIMIT_AS of the worker in MiB (0: none). Allocations past it fail.
  uint64_t memory_limit_mb = 8192;
  // Slots of the shared frame ring (each one camera frame).
  uint32_t frame_slots = 2;
  // Least privilege (README.md "Least privilege"): a private scratch folder,
  // no capabilities, Landlock (writes only in the scratch folder, reads only
  // in the plugin's, system and scratch folders once the plugin is loaded,
  // no TCP, no signals out), seccomp (no new sockets).
  bool sandbox = true;
  // Folders (or files) a sandboxed worker may read besides those: where
  // plugins' parameter files live (e.g. medium's response_lut).
  std::vector<std::string> readable;
  // Where scratch folders are made ("" = $TMPDIR or /tmp); each is removed
  // when its session ends.
  std::string scratch_parent;
  // Keep one worker started ahead (exec'd, sandboxed, waiting for its
  // plugin), so a session does not wait for process start-up. It is a
  // child process for as long as the PluginHost lives (procamd: on).
  bool prestart = false;
  // Worker reuse (README.md "Worker reuse"): a worker whose session ended
  // cleanly (the scan finished, or stop(); no fault and no error from the
  // plugin on any call) waits idle for the next session of the same plugin,
  // which then finds the plugin loaded and its memory (the SDK's map cache)
  // warm. The scratch folder is emptied in between; a plugin's globals carry
  // over. At most `max_idle_workers` idle workers per plugin (0: no reuse,
  // every session gets a fresh worker); an idle worker is ended after
  // `idle_timeout` (checked when a session starts or ends, and when the
  // PluginHost goes) and after `max_sessions_per_worker` sessions.
  uint32_t max_idle_workers = 0;
  std::chrono::milliseconds idle_timeout{60000};
  uint32_t max_sessions_per_worker = 100;
  // With reuse on, the outputs come back in the worker's output arena. If
  // the worker's sandbox has the rules freezing relies on (seccomp and
  // Landlock's signal scope, README.md "Speed"), the daemon stops the worker
  // (SIGSTOP) after its outputs reply and hands out views into the arena
  // itself, no copy; the worker is resumed (SIGCONT) when the Session ends.
  // false, or a worker without those rules: the daemon copies the outputs
  // out of the arena (the worker keeps running).
  bool freeze_outputs = true;
};

// One frame of a round: show `pattern` on the projector, capture with `settings`.
struct PlannedFrame {
  std::string label;       // validated: 1..255 bytes, no '/', '\\' or control chars
  procam_image pattern{};  // 1-channel; view into plugin memory, valid until
                           // the next call on the Session
  procam_frame_settings settings{};
};

struct Plan {
  std::string note;  // why this round ("" if the plugin gave none)
  std::vector<PlannedFrame> frames;
};

// One named result. Views (image, points) point into plugin memory and stay
// valid until the Session dies.
struct Output {
  std::string name;  // lower_snake_case [a-z0-9_]{1,64}: safe as a file name
  std::string unit;
  std::string description;
  procam_output_kind kind = PROCAM_OUTPUT_SCALAR;
  procam_image image{};           // IMAGE
  double scalar = 0;              // SCALAR
  const float* points = nullptr;  // POINTS: point_count rows of point_stride floats
  uint64_t point_count = 0;
  uint32_t point_stride = 0;
  std::string point_fields;
  std::string json;  // JSON (validated to parse)
};

// A scan on one plugin method. Move-only RAII over procam_session*; keeps its
// plugin library loaded even if the PluginHost dies first.
// Protocol: loop { next_plan() -> plan: add_frame(i) for every i, end_round() }
// until next_plan() gives nullopt, then outputs(). Calls out of this order
// give failed_precondition without reaching the plugin. Not thread-safe: one
// thread at a time (it may move between threads between calls).
class Session {
public:
  // At most this many rounds per session; more is treated as a plugin bug.
  static constexpr uint32_t kMaxRounds = 1000;

  Session(Session&& other) noexcept;
  Session& operator=(Session&& other) noexcept;
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  ~Session();  // session_destroy

  const std::string& plugin_name() const;
  const std::string& method() const { return method_; }

  // Plugin log lines and decode progress (plugin_abi.h "Host services"),
  // for plugins whose table has session_set_host. Every line also goes to
  // the daemon log, category "plugins", as "plugin '<name>': <message>".
  // Handlers run on the thread calling this Session, inside next_plan,
  // add_frame, end_round or outputs; they must be quick and must not call
  // the Session. Messages arrive sanitised (<= 1 KiB, control characters
  // escaped); progress `fraction` in [0, 1], at most ~20 reports per second
  // (a new stage and fraction 1 always pass). No-ops for other plugins.
  using LogHandler = std::function<void(log::Level level, const std::string& message)>;
  using ProgressHandler = std::function<void(double fraction, const std::string& stage)>;
  void set_log_handler(LogHandler handler);
  void set_progress_handler(ProgressHandler handler);
  // True when the plugin accepted host services (its session_set_host ran).
  bool has_host_services() const { return bridge_ != nullptr; }
  // True when the plugin runs in a worker process; its pid (else -1).
  bool isolated() const { return proxy_ != nullptr; }
  int worker_pid() const;

  // The next round to capture, or nullopt when the scan needs no more frames.
  Result<std::optional<Plan>> next_plan();
  // Frame `index` of the current plan (any order, each exactly once). The
  // view must be valid (procam::validate_view); it is only read during the call.
  Status add_frame(uint32_t index, const procam_image& frame);
  // All frames of the round were added: the plugin decodes.
  // `after` says what the caller does next. AfterRound::next_plan promises
  // next_plan() (never stop()): an isolated session's worker then goes on
  // with next_plan, and after the last round with get_outputs, without
  // waiting to be asked, so their replies are already on their way when
  // the caller asks (WORKER_PROTOCOL.md "Replies ahead"; 0.2-0.4 ms less
  // after the last frame). The plugin sees the same calls in the same order
  // either way; in-process nothing changes. A stop() after that promise
  // gives failed_precondition.
  enum class AfterRound { next_plan_or_stop, next_plan };
  Status end_round(AfterRound after = AfterRound::next_plan_or_stop);
  // Results; call after next_plan() returned nullopt, or after stop().
  Result<std::vector<Output>> outputs();
  // The host runs no more rounds (an offline capture with fewer rounds than
  // a multi-round method plans): outputs() then gives those of the last
  // decoded round. failed_precondition during a round or before the first
  // round was decoded.
  Status stop();

private:
  friend class PluginHost;
  Session(std::shared_ptr<const detail::LoadedPlugin> plugin, procam_session* session,
          std::string method, std::unique_ptr<detail::HostBridge> bridge);
  Session(std::shared_ptr<const detail::LoadedPlugin> plugin, std::unique_ptr<detail::WorkerProxy> proxy,
          std::string method, std::unique_ptr<detail::HostBridge> bridge);
  bool moved_from() const { return session_ == nullptr && proxy_ == nullptr; }
  Status plugin_failure(const char* call, int rc, const procam_error& err) const;

  std::shared_ptr<const detail::LoadedPlugin> plugin_;
  procam_session* session_ = nullptr;
  std::string method_;
  bool in_round_ = false;  // next_plan gave a plan, end_round not yet called
  bool finished_ = false;  // next_plan gave nullopt
  bool plan_promised_ = false;  // end_round(AfterRound::next_plan), next_plan not yet called
  uint32_t rounds_ = 0;
  std::vector<bool> added_;  // per frame of the current plan
  std::unique_ptr<detail::HostBridge> bridge_;  // null: the plugin has no host services
  std::unique_ptr<detail::WorkerProxy> proxy_;  // set: isolated (session_ is null)
  // Where proxy_ goes when the session ends (IsolationOptions::max_idle_workers);
  // expired (the PluginHost is gone) or null: the worker is killed.
  std::weak_ptr<detail::IdlePool> idle_;
  void end_worker();  // gives proxy_ back to idle_ or kills it
};

class PluginHost {
public:
  explicit PluginHost(LoadOptions options = {});
  ~PluginHost();
  PluginHost(PluginHost&&) noexcept;
  PluginHost& operator=(PluginHost&&) noexcept;
  PluginHost(const PluginHost&) = delete;
  PluginHost& operator=(const PluginHost&) = delete;

  // Loads every regular file whose name ends in ".so" directly in each dir
  // (not recursive), in name order. Never fails as a whole: bad files go to
  // rejected(); a missing directory is logged and skipped, an unreadable one
  // is recorded in rejected(). A plugin whose name is already loaded is
  // rejected ("duplicate plugin name, first loaded from ...").
  // Forks when probing: call before the process starts threads.
  void load_directories(const std::vector<std::string>& dirs);
  // Loads one file with the same checks; records it in plugins() or
  // rejected() and returns the reason on failure. Forks when probing.
  Status load_file(const std::string& path);

  const std::vector<PluginInfo>& plugins() const { return plugins_; }
  const std::vector<Rejected>& rejected() const { return rejected_; }
  const PluginInfo* find(std::string_view name) const;

  // Where create_session runs sessions (default: isolated, see
  // IsolationOptions). Set before sessions are created, and after load_*:
  // with max_idle_workers > 0 it starts the idle pool's reaper thread.
  void set_isolation(IsolationOptions options);
  const IsolationOptions& isolation() const { return isolation_; }
  // True when sessions of `plugin` run in a worker process.
  bool runs_isolated(std::string_view plugin) const;

  // Starts a scan. not_found: unknown plugin (message lists the loaded ones)
  // or unknown method (lists the plugin's methods); invalid_argument: params
  // or rig is not a JSON object, or `inputs` do not match what the method
  // declares (an input it does not take, a required one missing, one given
  // twice, the wrong kind, inputs for an ABI 1 plugin) -- checked before any
  // plugin code runs; otherwise the plugin's own refusal with its message
  // (invalid_argument, failed_precondition, plugin_error, ...).
  // `inputs` are read only during the call.
  Result<Session> create_session(const std::string& plugin, const std::string& method,
                                 const std::string& params_json, const std::string& rig_json,
                                 const std::vector<InputImage>& inputs = {}) const;

private:
  Status load_file_impl(const std::string& path);

  LoadOptions options_;
  IsolationOptions isolation_;
  std::unique_ptr<detail::SparePool> spare_;  // IsolationOptions::prestart
  std::shared_ptr<detail::IdlePool> idle_;    // IsolationOptions::max_idle_workers
  std::vector<PluginInfo> plugins_;
  std::vector<std::shared_ptr<const detail::LoadedPlugin>> loaded_;  // parallel to plugins_
  std::vector<Rejected> rejected_;
};

}  // namespace procam::host
