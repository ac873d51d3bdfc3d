// SPDX-License-Identifier: MIT
// The host side of the plugin log/progress callbacks (plugin_abi.h "Host
// services"): the procam_host_services table handed to one session, and the
// checks between the plugin's calls and the Session's handlers.
//
// Ownership: one HostBridge per Session, on the heap (its address is the
// table's ctx and must not move), destroyed after session_destroy.
// Threads: the callbacks are honoured only on the thread that is inside an
// ABI call of the session (CallScope); calls from any other thread, or
// between calls, are dropped and counted (a plugin bug; never a crash, never
// a handler running concurrently with the Session's caller).
// Limits: a log message is cut at kMaxLogBytes and its control characters
// escaped; at most kMaxLogLines lines per session; progress is forwarded at
// most every kProgressInterval, except a new stage and fraction 1 (always).
// Errors: nothing throws into the plugin; a handler that throws is ignored.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <string>
#include <thread>

#include "procam/host/plugin_host.hpp"
#include "procam/plugin_abi.h"

namespace procam::host::detail {

inline constexpr size_t kMaxLogBytes = 1024;
inline constexpr size_t kMaxLogLines = 10000;
inline constexpr std::chrono::milliseconds kProgressInterval{50};  // <= 20 reports/s

// A plugin's log message as one safe line: at most kMaxLogBytes bytes of it
// (cut at a UTF-8 character boundary, then "..."), bytes < 0x20, 0x7f and
// '\\' written as \xNN (so "\n" cannot forge a second log line); other
// bytes, UTF-8 included, kept. NULL gives "".
std::string sanitize_log_message(const char* message);

// procam_log level -> log::Level; unknown values are treated as info.
log::Level log_level_of(int plugin_level);

// The table's session_set_host if the vtable is long enough to have one
// (struct_size covers it) and it is set; else nullptr.
using SetHostFn = int (*)(procam_session*, const procam_host_services*, procam_error*);
SetHostFn set_host_of(const procam_plugin_vtable& vt);

class HostBridge {
public:
  explicit HostBridge(std::string plugin_name);
  HostBridge(const HostBridge&) = delete;
  HostBridge& operator=(const HostBridge&) = delete;

  const procam_host_services* table() const { return &table_; }
  void set_log_handler(Session::LogHandler h) { on_log_ = std::move(h); }
  void set_progress_handler(Session::ProgressHandler h) { on_progress_ = std::move(h); }

  // Marks the current thread as inside an ABI call of this session for the
  // scope's lifetime. `bridge` may be null (a plugin without host services).
  class CallScope {
  public:
    explicit CallScope(HostBridge* bridge);
    ~CallScope();
    CallScope(const CallScope&) = delete;
    CallScope& operator=(const CallScope&) = delete;

  private:
    HostBridge* bridge_;
  };

  // The same paths without the thread check, for lines and reports a worker
  // process already checked with its own HostBridge (worker_proxy.cpp calls
  // them on the thread inside the Session's call). `line` must already be
  // sanitised (sanitize_log_message); the line limit and progress rules apply.
  void deliver_log(int level, const std::string& line);
  void deliver_progress(double fraction, const char* stage);

  // Callbacks dropped because they came from another thread or outside a call.
  size_t dropped() const { return dropped_.load(); }

private:
  static void log_cb(void* ctx, int level, const char* message);
  static void progress_cb(void* ctx, double fraction, const char* stage);
  bool on_call_thread();  // counts a drop when false

  std::string plugin_;
  procam_host_services table_{};
  std::atomic<std::thread::id> call_thread_{};  // inside an ABI call: its thread
  std::atomic<size_t> dropped_{0};
  // Touched only on the call thread (guarded by the on_call_thread check):
  Session::LogHandler on_log_;
  Session::ProgressHandler on_progress_;
  size_t log_lines_ = 0;
  bool progress_sent_ = false;
  std::chrono::steady_clock::time_point last_progress_{};
  std::string last_stage_;
};

}  // namespace procam::host::detail
