// SPDX-License-Identifier: MIT
// The daemon side of an isolated session (README.md "Process model"): starts
// a procam-plugin-worker process for one session, speaks the control
// protocol (WORKER_PROTOCOL.md) to it, copies frames into the shared frame
// ring and maps plans and outputs from the blobs the worker sends back.
//
// Ownership: one WorkerProxy per isolated Session; it owns the worker
// process (killed and reaped on destruction), the socket, the frame ring and
// the mappings the Session's views point into (the plan's patterns at least
// until the next call -- kept until the next plan arrives or the session
// ends, so their pages are not freed on the client's time -- the outputs
// until destruction).
// Threads: like Session, one thread at a time.
// Errors: a worker that dies (signal, exit), misses its deadline or sends a
// malformed message is killed and reaped; the call fails with a Status that
// names the plugin, the call and the cause (plugin_error, or timeout), and
// every later call fails with failed_precondition. Nothing throws except
// std::bad_alloc.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <condition_variable>
#include <thread>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"
#include "output_arena.hpp"
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

// Idle workers kept for the next session of the same plugin
// (IsolationOptions::max_idle_workers; README.md "Worker reuse"). PluginHost
// owns it (shared), each isolated Session points at it weakly: a Session
// that outlives its PluginHost kills its worker. Thread-safe (`mu`); workers
// are killed outside the lock. A reaper thread ends idle workers when their
// idle_timeout passes (so an idle daemon does not keep them); the destructor
// stops it and kills every idle worker.
struct IdlePool {
  explicit IdlePool(IsolationOptions o);
  ~IdlePool();
  // An idle worker of `plugin`, the most recently used first; null if none.
  // Expired workers are ended first.
  std::unique_ptr<WorkerProxy> take(const std::string& plugin);
  // A worker whose session just ended: ends the plugin session there
  // (end_session), empties its scratch folder and keeps it if
  // `session_clean`, it is still healthy, under max_sessions_per_worker and
  // the plugin has fewer than max_idle_workers idle; otherwise kills it.
  void give(std::unique_ptr<WorkerProxy> worker, bool session_clean);
  size_t idle_count();  // for tests

  const IsolationOptions options;
  std::mutex mu;
  struct Entry {
    std::unique_ptr<WorkerProxy> worker;
    std::chrono::steady_clock::time_point since;
  };
  std::vector<Entry> idle;  // oldest first

private:
  void reaper();
  std::condition_variable wake_;  // a worker went idle, or stop_
  bool stop_ = false;
  std::thread reaper_;            // last member: starts after the rest exists
  // Moves entries past idle_timeout into `out` (killed by the caller, unlocked).
  void expire_locked(std::vector<std::unique_ptr<WorkerProxy>>& out);
};

// Where the worker executable is: `configured` if not empty, else
// $PROCAM_PLUGIN_WORKER, else beside the running executable, else
// <exe dir>/../libexec/procam/, else the build tree's bin/ (README.md).
Result<std::string> find_worker(const std::string& configured);

// The folder workers make their scratch folders in: options.scratch_parent,
// else $TMPDIR, else /tmp.
std::string scratch_parent_of(const IsolationOptions& options);

// Removes scratch folders left behind by a daemon that was killed (SIGKILL:
// no destructor ran): every `procam-worker-<pid>-*` folder directly in
// `parent` whose <pid> (the daemon that started the worker) no longer
// exists. Folders of live daemons, of other names, or without a pid are
// left alone. Returns how many were removed; never throws.
size_t sweep_stale_scratch(const std::string& parent);

// Whether every thread of a stopped worker is stopped ('T') or done
// exiting (a zombie leader, or gone from /proc/PID/task): a thread that was
// already exiting when SIGSTOP came is not part of the group stop, and the
// kernel still writes its clear_child_tid word and robust-futex list
// (exit_mm) -- memory a plugin may have pointed into the arena. Those
// writes are done once the thread is released or a zombie. Keeps
// /proc/PID/task and up to kMaxOpen threads' stat files open between calls
// (a reused worker is frozen once per scan): the path lookups were most of
// the check's cost (~80 -> ~35 us for two threads on the project's VM).
// A kept file whose thread is gone (its tid perhaps reused) is opened again
// by name. One process at a time: another pid drops what was kept.
class ThreadStates {
public:
  bool settled(pid_t pid);
  void clear();
  static constexpr size_t kMaxOpen = 16;

private:
  pid_t pid_ = -1;
  wire::UniqueFd task_dir_;
  std::vector<std::pair<pid_t, wire::UniqueFd>> stat_;  // tid, its stat file
};

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
  // Starts the next session on a worker that ended one cleanly (IdlePool):
  // the create request again, on the plugin it already has loaded.
  Status reuse(const wire::CreateRequest& request, bool& host_services);
  // Ends the plugin session in the worker (end_session) and empties its
  // scratch folder; true when the worker may serve another session: no
  // fault and no error reply on any call, and it served fewer than
  // max_sessions_per_worker sessions. False leaves it to be killed.
  bool end_session_for_reuse();
  const std::string& plugin() const { return plugin_; }
  bool faulted() const { return broken_; }  // killed after a fault
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
  // `then_next_plan`: the Session's caller promised next_plan() next; the
  // worker sends that reply, and the outputs after the last round, ahead.
  Status end_round(size_t frames, bool then_next_plan);
  Result<std::vector<Output>> outputs();
  Status stop();  // the worker's Session::stop

  pid_t pid() const { return pid_; }
  bool frozen() const { return frozen_; }  // stopped after its outputs reply (tests)

private:
  // Freezing (README.md "Speed"): after the outputs reply, SIGSTOP and wait
  // until the kernel reports the whole thread group stopped (waitid
  // WSTOPPED, WNOWAIT: the report stays for reap()). True when it is
  // stopped (or already dead): no thread of it runs until thaw(). False if
  // the worker's sandbox lacks the rules this relies on, or the stop did
  // not complete within a second (the worker is resumed; the caller copies).
  bool freeze();
  // freeze() in two halves, so that work on private data can run while the
  // worker's threads stop: stop_begin() sends SIGSTOP (false: may not
  // freeze, or the signal failed; nothing to undo); stop_wait() waits for
  // the stop as freeze() does (false: it did not complete, the worker was
  // resumed).
  bool stop_begin();
  bool stop_wait();
  void thaw();  // SIGCONT if frozen; before any later request
  bool may_freeze() const;
  uint8_t outputs_mode() const;  // get_outputs' mode byte (WORKER_PROTOCOL.md)
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
  Status create(const wire::CreateRequest& request, bool& host_services);

  IsolationOptions options_;
  std::string plugin_;
  pid_t pid_ = -1;
  std::string scratch_;  // the worker's scratch folder, removed after it ends
  wire::UniqueFd sock_;
  uint32_t seq_ = 0;
  bool broken_ = false;
  uint32_t sandbox_flags_ = 0;  // from hello
  bool frozen_ = false;         // SIGSTOPped by freeze(), not yet resumed
  ThreadStates thread_states_;  // stop_wait's check that every thread stopped
  bool errored_ = false;   // an error reply came: the worker is not reused
  uint32_t sessions_ = 0;  // sessions created on this worker
  std::string broken_reason_;
  HostBridge* bridge_ = nullptr;
  std::optional<wire::Ring> ring_;
  uint32_t next_slot_ = 0;
  size_t last_round_frames_ = 0;
  // Replies the worker sends without a request (WORKER_PROTOCOL.md "Replies
  // ahead"): the next_plan reply after an end_round that asked for it, then
  // the get_outputs reply (in `ahead_mode_`) after "no more rounds".
  enum class Ahead : uint8_t { none, plan, outputs };
  Ahead ahead_ = Ahead::none;
  uint8_t ahead_mode_ = 0;
  wire::Mapping plan_blob_;     // the last plan's patterns, kept until the next plan or the session's end
  // The outputs' images and points: the worker's output arena itself while
  // the worker is frozen, else the daemon's private copy of it
  // (output_arena.hpp), kept across the sessions of a reused worker;
  // `outputs_` is what this session's outputs() returned (a second call
  // returns it again: the arena is read once per session).
  wire::OutputSnapshot outputs_copy_;
  wire::Mapping outputs_blob_;  // instead, with reuse off: a sealed blob per session
  std::optional<std::vector<Output>> outputs_;
};

}  // namespace procam::host::detail
