// SPDX-License-Identifier: MIT
// The daemon side of an isolated session (README.md "Process model"): starts
// a procam-plugin-worker process for one session, speaks the control
// protocol (WORKER_PROTOCOL.md) to it, copies frames into the shared frame
// ring and maps plans and outputs from the blobs the worker sends back.
//
// Ownership: one WorkerProxy per isolated Session; it owns the worker
// process (killed and reaped on destruction), the socket, the frame ring and
// the mappings the Session's views point into (the plan's patterns until the
// next call, the outputs until destruction).
// Threads: like Session, one thread at a time.
// Errors: a worker that dies (signal, exit), misses its deadline or sends a
// malformed message is killed and reaped; the call fails with a Status that
// names the plugin, the call and the cause (plugin_error, or timeout), and
// every later call fails with failed_precondition. Nothing throws except
// std::bad_alloc.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"
#include "worker_wire.hpp"

namespace procam::host::detail {

class HostBridge;
class WorkerProxy;

// At most one pre-started worker, not yet bound to a plugin (PluginHost
// keeps it; guarded by `mu`).
struct SparePool {
  std::mutex mu;
  std::unique_ptr<WorkerProxy> spare;
  ~SparePool();
};

// Where the worker executable is: `configured` if not empty, else
// $PROCAM_PLUGIN_WORKER, else beside the running executable, else
// <exe dir>/../libexec/procam/, else the build tree's bin/ (README.md).
Result<std::string> find_worker(const std::string& configured);

class WorkerProxy {
public:
  // Spawns the worker, waits for its hello, sends the create request and
  // waits for the session (or its refusal, returned as the worker's Status).
  // `host_services` tells whether the plugin took the host services.
  // `spare`: a worker from spawn_spare() to use instead of a new one (if it
  // turns out dead, a new one is started).
  static Result<std::unique_ptr<WorkerProxy>> start(const IsolationOptions& options,
                                                    const wire::CreateRequest& request,
                                                    bool& host_services,
                                                    std::unique_ptr<WorkerProxy> spare = nullptr);
  // Spawns a worker and returns without waiting for it: its exec, dynamic
  // loading and sandbox run while the caller goes on (IsolationOptions::prestart).
  static Result<std::unique_ptr<WorkerProxy>> spawn_spare(const IsolationOptions& options);
  ~WorkerProxy();
  WorkerProxy(const WorkerProxy&) = delete;
  WorkerProxy& operator=(const WorkerProxy&) = delete;

  // Log lines and progress from the worker go here (may be null).
  void set_bridge(HostBridge* bridge) { bridge_ = bridge; }

  // The Session's calls, after its order checks. Results are re-validated
  // (session_checks.hpp) before they are returned.
  Result<std::optional<Plan>> next_plan(uint32_t round);
  Status add_frame(uint32_t index, const procam_image& frame);
  Status end_round(size_t frames);
  Result<std::vector<Output>> outputs();
  Status stop();  // the worker's Session::stop

  pid_t pid() const { return pid_; }

private:
  WorkerProxy(const IsolationOptions& options, std::string plugin);
  Status spawn(const std::string& worker_path);
  // Sends a request and waits for its ok (returned) or error reply, handling
  // log/progress messages meanwhile. Any failure but an error reply kills
  // the worker (see file comment).
  Result<wire::Message> call(wire::Msg type, const char* call_name, const std::string& payload, int fd,
                             std::chrono::milliseconds deadline);
  // Kills and reaps the worker; the Status for `call_name` failing by `cause`.
  Status fail(const char* call_name, Code code, const std::string& cause);
  std::string reap(bool kill_now);  // "" if it exited 0, else how it ended
  std::chrono::milliseconds round_deadline(size_t frames) const;
  Status read_hello(const wire::Message& hello);

  IsolationOptions options_;
  std::string plugin_;
  pid_t pid_ = -1;
  std::string scratch_;  // the worker's scratch folder, removed after it ends
  wire::UniqueFd sock_;
  uint32_t seq_ = 0;
  bool broken_ = false;
  std::string broken_reason_;
  HostBridge* bridge_ = nullptr;
  std::optional<wire::Ring> ring_;
  uint32_t next_slot_ = 0;
  size_t last_round_frames_ = 0;
  wire::Mapping plan_blob_;     // the current plan's patterns
  wire::Mapping outputs_blob_;  // the outputs' images and points
};

}  // namespace procam::host::detail
