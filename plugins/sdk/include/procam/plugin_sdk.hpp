// SPDX-License-Identifier: MIT
// procam plugin SDK (header-only): write a decoder plugin in C++ and get a
// correct C ABI (plugin_abi.h) — exported info struct, vtable, exception
// barrier, call-order checks and ownership of everything handed to the host.
//
// Writing a plugin (see plugins/README.md "How to add a plugin"):
//
//   class MySession : public procam::sdk::Session {
//     procam::sdk::Error next_plan(procam::sdk::Plan& plan, bool& has_round) override;
//     procam::sdk::Error add_frame(uint32_t index, const procam_image& frame) override;
//     procam::sdk::Error end_round() override;
//     procam::sdk::Error outputs(procam::sdk::Outputs& out) override;
//   };
//   std::string my_describe();   // JSON array of methods (sdk::describe_methods)
//   procam::sdk::Error my_create(const procam::sdk::CreateArgs& args,
//                                std::unique_ptr<procam::sdk::Session>& out);
//   PROCAM_DEFINE_PLUGIN("my-plugin", "0.1.0", "method_a,method_b", my_describe, my_create)
//
// What the SDK guarantees to the host, so the plugin need not:
//   - No exception crosses the ABI: std::bad_alloc -> PROCAM_ERR_NO_MEMORY,
//     any other exception -> PROCAM_ERR_INTERNAL with what() in the message.
//   - Messages are copied into procam_error, NUL-terminated, truncated safely.
//   - Call order (plugin_abi.h "Scan protocol") is enforced before the session
//     sees a call: add_frame/end_round without a round in progress, a frame
//     index outside the plan, a frame added twice, end_round with frames
//     missing, next_plan or get_outputs in the middle of a round, and
//     get_outputs before any round was decoded are PROCAM_ERR_STATE (bad index:
//     PROCAM_ERR_INVALID_ARGUMENT); structurally broken images (NULL data,
//     unknown pixel type, short stride) are PROCAM_ERR_BAD_FRAME.
//   - The method name is checked against METHODS_CSV (unknown method ->
//     PROCAM_ERR_INVALID_ARGUMENT listing the known ones) and params_json /
//     rig_json are parsed (not JSON -> PROCAM_ERR_INVALID_ARGUMENT) before the
//     factory runs.
//   - Scan inputs (ABI 2, plugin_abi.h "Scan inputs"): the table has
//     session_create2; the factory sees the inputs as CreateArgs::inputs
//     (sdk/inputs.hpp), views valid only during the factory call. Declare
//     them in describe() (MethodDescription::inputs); the host checks names,
//     required ones and kinds against that before calling, the factory checks
//     sizes (Inputs::image_f32).
//   - Lifetimes: a plan stays valid until the next next_plan call or
//     session_destroy; every outputs array stays valid until session_destroy.
//   - A session whose end_round/next_plan failed, or whose add_frame failed
//     with NO_MEMORY/INTERNAL, is poisoned: later calls (other than destroy)
//     return PROCAM_ERR_STATE quoting the first failure. A frame rejected with
//     BAD_FRAME/INVALID_ARGUMENT is not counted and may be added again.
//
// Threads: every Session method is called on one host thread at a time
// (thread-bound (docs/threading.md)). Sessions may run concurrently, so plugin globals must be
// immutable; a session may use threads internally (sdk::parallel_rows).
#pragma once

#include <cstdint>
#include <cstring>
#include <exception>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/plugin_abi.h"
#include "procam/sdk/error.hpp"
#include "procam/sdk/image.hpp"
#include "procam/sdk/inputs.hpp"
#include "procam/sdk/map_cache.hpp"
#include "procam/sdk/method.hpp"
#include "procam/sdk/outputs.hpp"
#include "procam/sdk/parallel.hpp"
#include "procam/sdk/params.hpp"
#include "procam/sdk/patterns.hpp"
#include "procam/sdk/plan.hpp"
#include "procam/sdk/rig.hpp"
#include "procam/sdk/standard_outputs.hpp"
#include "procam/sdk/timing.hpp"

namespace procam::sdk {

namespace detail {
template <class Traits>
struct Abi;

// Carries Session::log/progress to the host's procam_host_services
// (plugin_abi.h "Host services") and enforces its thread rule: a call on the
// thread that is inside an ABI call goes straight to the host; a call from
// any other thread (a plugin's worker) or between ABI calls is queued and
// delivered by the calling thread when the current ABI call returns (or at
// the start of the next one). At most kMaxQueuedLogs lines wait; more are
// counted and reported as one line. Progress keeps only the latest report.
// Thread-safe; never throws.
class HostLink {
 public:
  static constexpr size_t kMaxQueuedLogs = 256;

  void attach(const procam_host_services* host) noexcept {
    std::lock_guard lock(mu_);
    host_ = host;
  }
  bool attached() const noexcept {
    std::lock_guard lock(mu_);
    return host_ != nullptr;
  }
  // The calling thread enters / leaves an ABI call of this session.
  void enter() noexcept {
    std::lock_guard lock(mu_);
    caller_ = std::this_thread::get_id();
    flush_locked();
  }
  void leave() noexcept {
    std::lock_guard lock(mu_);
    flush_locked();
    caller_ = std::thread::id{};
  }
  void log(int level, std::string_view message) noexcept {
    std::lock_guard lock(mu_);
    if (host_ == nullptr || host_log() == nullptr) return;
    try {
      if (on_caller_locked()) {
        flush_locked();
        const std::string text(message);
        host_log()(host_->ctx, level, text.c_str());
      } else if (queued_logs_.size() < kMaxQueuedLogs) {
        queued_logs_.emplace_back(level, std::string(message));
      } else {
        ++dropped_;
      }
    } catch (...) {
      ++dropped_;  // out of memory: the line is lost
    }
  }
  void progress(double fraction, std::string_view stage) noexcept {
    std::lock_guard lock(mu_);
    if (host_ == nullptr || host_progress() == nullptr) return;
    try {
      if (on_caller_locked()) {
        flush_locked();
        const std::string text(stage);
        host_progress()(host_->ctx, fraction, text.c_str());
      } else {
        queued_progress_ = {fraction, std::string(stage)};
        has_queued_progress_ = true;
      }
    } catch (...) {
      // Out of memory: a progress report is not worth failing for.
    }
  }

 private:
  using LogFn = void (*)(void*, int, const char*);
  using ProgressFn = void (*)(void*, double, const char*);
  // Members the host's table has (its struct_size covers them), else nullptr.
  LogFn host_log() const noexcept {
    return host_->struct_size >= offsetof(procam_host_services, log) + sizeof(host_->log) ? host_->log
                                                                                          : nullptr;
  }
  ProgressFn host_progress() const noexcept {
    return host_->struct_size >= offsetof(procam_host_services, progress) + sizeof(host_->progress)
               ? host_->progress
               : nullptr;
  }
  bool on_caller_locked() const noexcept {
    return caller_ != std::thread::id{} && caller_ == std::this_thread::get_id();
  }
  // Delivers what workers queued; only on the calling thread, inside a call.
  void flush_locked() noexcept {
    if (host_ == nullptr || !on_caller_locked()) return;
    if (LogFn fn = host_log()) {
      for (const auto& [level, text] : queued_logs_) fn(host_->ctx, level, text.c_str());
      if (dropped_ > 0) {
        char line[96];
        std::snprintf(line, sizeof line, "%zu log lines from worker threads were dropped",
                      dropped_);
        fn(host_->ctx, PROCAM_LOG_WARN, line);
      }
    }
    queued_logs_.clear();
    dropped_ = 0;
    if (has_queued_progress_) {
      if (ProgressFn fn = host_progress())
        fn(host_->ctx, queued_progress_.first, queued_progress_.second.c_str());
      has_queued_progress_ = false;
    }
  }

  mutable std::mutex mu_;
  const procam_host_services* host_ = nullptr;  // host-owned; valid until session_destroy
  std::thread::id caller_;                      // inside an ABI call: its thread
  std::vector<std::pair<int, std::string>> queued_logs_;
  size_t dropped_ = 0;
  std::pair<double, std::string> queued_progress_;
  bool has_queued_progress_ = false;
};
}  // namespace detail

// One scan. The SDK creates it through the plugin's factory and calls it in
// protocol order only (see above); all calls come from one thread at a time.
class Session {
 public:
  virtual ~Session() = default;

  // Host services (plugin_abi.h "Host services"): a line for the daemon log
  // (`level` PROCAM_LOG_DEBUG/INFO/WARN/ERROR) and how far this round's
  // decode is (`fraction` 0..1, `stage` a short step name). No-ops when the
  // host offers none. Safe from any thread: calls from worker threads are
  // queued and reach the host when the current call (add_frame, end_round,
  // ...) returns. The host may cut long messages and thin out progress.
  void log(int level, std::string_view message) const noexcept { host_link_.log(level, message); }
  void progress(double fraction, std::string_view stage) const noexcept {
    host_link_.progress(fraction, stage);
  }

  // Describe the next round in `plan` (empty on entry) and set has_round =
  // true, or leave has_round (false on entry) when no round is left. Called once at
  // the start and once after every end_round.
  virtual Error next_plan(Plan& plan, bool& has_round) = 0;

  // Frame `index` (< plan size, each once, any order) of the current round.
  // `frame` passed check_image(); its pixels are valid only during the call:
  // copy what you keep. Check the size/format you need (check_frame) and
  // return bad_frame(...) on mismatch. Do per-frame work here so end_round is
  // light (streaming). On error leave the session as it was before the call:
  // the frame is not counted and the host may add it again.
  virtual Error add_frame(uint32_t index, const procam_image& frame) = 0;

  // Every frame of the round has been added: decode it.
  virtual Error end_round() = 0;

  // Fill `out` (empty on entry) with the results so far. Called after at
  // least one end_round, at most once per decoded round (the SDK reuses the
  // previous Outputs when nothing changed).
  virtual Error outputs(Outputs& out) = 0;

 private:
  template <class Traits>
  friend struct detail::Abi;
  mutable detail::HostLink host_link_;
};

// What session_create received, parsed.
struct CreateArgs {
  std::string method;      // one of the plugin's METHODS_CSV names
  nlohmann::json params;   // a JSON object ({} when the host passed NULL or "")
  nlohmann::json rig;      // the rig description (null when the host passed NULL or ""); see rig.hpp
  // Outputs of earlier scans the host passed (ABI 2); empty when none. Views
  // of host memory valid only during the factory call: copy with image_f32().
  Inputs inputs{};
};

using DescribeFn = std::string (*)();
using FactoryFn = Error (*)(const CreateArgs& args, std::unique_ptr<Session>& out);

namespace detail {

// True when `method` is one of the comma-separated names in `csv`.
inline bool csv_contains(std::string_view csv, std::string_view method) {
  size_t start = 0;
  while (start <= csv.size()) {
    size_t end = csv.find(',', start);
    if (end == std::string_view::npos) end = csv.size();
    if (csv.substr(start, end - start) == method) return true;
    start = end + 1;
  }
  return false;
}

// The session handle the host sees (procam_session is opaque to it).
struct SessionBox {
  enum class Phase { between_rounds, in_round, finished };
  std::unique_ptr<Session> impl;
  Phase phase = Phase::between_rounds;
  uint32_t rounds_decoded = 0;
  Plan plan;
  std::vector<uint8_t> added;  // per frame of the current plan: 1 once added
  uint32_t added_count = 0;
  std::vector<std::unique_ptr<Outputs>> outputs;  // all handed out, kept to destroy
  uint32_t outputs_round = 0;                      // rounds_decoded when outputs.back() was made
  std::string poisoned;                            // non-empty: first fatal failure
};

inline int fail(procam_error* err, const Error& e) {
  write_error(err, e.message.c_str());
  return e.code;
}

// Runs body() (returning Error) behind the exception barrier.
template <class Body>
int guarded(procam_error* err, const char* where, Body&& body) noexcept {
  try {
    Error e = body();
    if (!e.ok()) {
      if (e.message.empty()) e.message = std::string(where) + ": failed without a message";
      return fail(err, e);
    }
    return PROCAM_OK;
  } catch (const std::bad_alloc&) {
    write_error(err, (std::string(where) + ": out of memory").c_str());
    return PROCAM_ERR_NO_MEMORY;
  } catch (const std::exception& ex) {
    try {
      write_error(err, (std::string(where) + ": internal error: " + ex.what()).c_str());
    } catch (...) {
      write_error(err, "internal error (message lost: out of memory)");
    }
    return PROCAM_ERR_INTERNAL;
  } catch (...) {
    write_error(err, "internal error: unknown exception");
    return PROCAM_ERR_INTERNAL;
  }
}

inline SessionBox* box_of(procam_session* s) { return reinterpret_cast<SessionBox*>(s); }

// Records the first failure that left the session's state unknown: any failure
// of the plugin's own next_plan/end_round, and NO_MEMORY/INTERNAL anywhere.
// `reached_impl` says whether the failure came from (or after) plugin code;
// complaints about the caller's call order never poison.
inline void poison_if(SessionBox* box, int rc, const procam_error* err, bool reached_impl,
                      bool any_code) noexcept {
  if (box == nullptr || rc == PROCAM_OK || !reached_impl || !box->poisoned.empty()) return;
  if (!any_code && rc != PROCAM_ERR_NO_MEMORY && rc != PROCAM_ERR_INTERNAL) return;
  try {
    box->poisoned = (err != nullptr && err->message[0] != '\0') ? err->message : code_name(rc);
  } catch (...) {
    // Out of memory while recording: the next call may proceed; nothing better to do.
  }
}

inline Error check_usable(const SessionBox* box, const char* where) {
  if (box == nullptr) return invalid_argument(std::string(where) + ": session is NULL");
  if (!box->poisoned.empty())
    return state_error(std::string(where) + ": session is unusable after an earlier failure (" +
                       box->poisoned + "); destroy it and start a new scan");
  return ok();
}

// Marks one ABI call on a session for HostLink's thread rule.
class CallScope {
 public:
  explicit CallScope(HostLink* link) noexcept : link_(link) {
    if (link_ != nullptr) link_->enter();
  }
  ~CallScope() {
    if (link_ != nullptr) link_->leave();
  }
  CallScope(const CallScope&) = delete;
  CallScope& operator=(const CallScope&) = delete;

 private:
  HostLink* link_;
};

template <class Traits>
struct Abi {
  static HostLink* link_of(SessionBox* box) noexcept {
    return box != nullptr && box->impl ? &box->impl->host_link_ : nullptr;
  }

  static const char* describe() noexcept {
    // Built once (thread-safe static init); on failure a valid empty array.
    static const std::string text = []() noexcept -> std::string {
      try {
        return Traits::procam_sdk_describe_();
      } catch (...) {
        try {
          return "[]";
        } catch (...) {
          return {};
        }
      }
    }();
    return text.empty() ? "[]" : text.c_str();
  }

  static int session_create(const char* method, const char* params_json, const char* rig_json,
                            procam_session** out, procam_error* err) noexcept {
    return session_create2(method, params_json, rig_json, nullptr, 0, out, err);
  }

  static int session_create2(const char* method, const char* params_json, const char* rig_json,
                             const procam_output* inputs, uint32_t input_count,
                             procam_session** out, procam_error* err) noexcept {
    if (out != nullptr) *out = nullptr;
    return guarded(err, "session_create", [&]() -> Error {
      if (out == nullptr) return invalid_argument("session_create: out is NULL");
      if (method == nullptr || *method == '\0')
        return invalid_argument(std::string("session_create: no method given; this plugin offers: ") +
                                Traits::methods);
      if (!csv_contains(Traits::methods, method))
        return invalid_argument(std::string("unknown method '") + method +
                                "'; this plugin offers: " + Traits::methods);
      CreateArgs args;
      args.method = method;
      args.params = nlohmann::json::object();
      if (params_json != nullptr && *params_json != '\0') {
        args.params = nlohmann::json::parse(params_json, nullptr, false);
        if (args.params.is_discarded())
          return invalid_argument("params_json is not valid JSON");
        if (args.params.is_null()) args.params = nlohmann::json::object();
        if (!args.params.is_object())
          return invalid_argument("params_json must be a JSON object, got " +
                                  detail::shown(args.params));
      }
      if (rig_json != nullptr && *rig_json != '\0') {
        args.rig = nlohmann::json::parse(rig_json, nullptr, false);
        if (args.rig.is_discarded()) return invalid_argument("rig_json is not valid JSON");
      }
      if (input_count > 0 && inputs == nullptr)
        return invalid_argument("session_create2: input_count is " + std::to_string(input_count) +
                                " but inputs is NULL");
      args.inputs = Inputs::from_abi(inputs, input_count);
      std::unique_ptr<Session> impl;
      if (Error e = Traits::procam_sdk_create_(args, impl); !e.ok()) return e;
      if (!impl) return internal_error("session_create: factory returned no session");
      auto box = std::make_unique<SessionBox>();
      box->impl = std::move(impl);
      *out = reinterpret_cast<procam_session*>(box.release());
      return ok();
    });
  }

  static void session_destroy(procam_session* s) noexcept {
    // Destructors must not throw (C++ default noexcept); nothing to report.
    delete box_of(s);
  }

  static int next_plan(procam_session* s, const procam_plan** plan, procam_error* err) noexcept {
    SessionBox* box = box_of(s);
    CallScope scope(link_of(box));  // host services allowed during this call
    bool has_round = false;
    bool reached_impl = false;
    const int rc = guarded(err, "next_plan", [&]() -> Error {
      if (Error e = check_usable(box, "next_plan"); !e.ok()) return e;
      if (plan == nullptr) return invalid_argument("next_plan: plan is NULL");
      *plan = nullptr;
      if (box->phase == SessionBox::Phase::in_round)
        return state_error("next_plan: a round is in progress (" +
                           std::to_string(box->added_count) + " of " +
                           std::to_string(box->plan.size()) +
                           " frames added); add the rest and call end_round first");
      if (box->phase == SessionBox::Phase::finished) return ok();  // done stays done
      box->plan.clear();
      reached_impl = true;
      if (Error e = box->impl->next_plan(box->plan, has_round); !e.ok()) return e;
      if (!has_round) {
        box->phase = SessionBox::Phase::finished;
        return ok();
      }
      if (box->plan.empty())
        return internal_error("next_plan: the plugin returned a round with no frames");
      box->added.assign(box->plan.size(), 0);
      box->added_count = 0;
      *plan = box->plan.view();
      box->phase = SessionBox::Phase::in_round;
      return ok();
    });
    if (rc != PROCAM_OK) {
      poison_if(box, rc, err, reached_impl, true);
      return rc;
    }
    return has_round ? 1 : 0;
  }

  static int add_frame(procam_session* s, uint32_t index, const procam_image* frame,
                       procam_error* err) noexcept {
    SessionBox* box = box_of(s);
    CallScope scope(link_of(box));  // host services allowed during this call
    bool reached_impl = false;
    const int rc = guarded(err, "add_frame", [&]() -> Error {
      if (Error e = check_usable(box, "add_frame"); !e.ok()) return e;
      if (box->phase != SessionBox::Phase::in_round)
        return state_error(box->phase == SessionBox::Phase::finished
                               ? "add_frame: the scan is finished (next_plan returned 0)"
                               : "add_frame: no round in progress; call next_plan first");
      if (index >= box->plan.size())
        return invalid_argument("add_frame: frame index " + std::to_string(index) +
                                " is out of range; the plan has " +
                                std::to_string(box->plan.size()) + " frames");
      if (box->added[index])
        return state_error("add_frame: frame " + std::to_string(index) + " (" +
                           box->plan.label(index) + ") was already added");
      const std::string what =
          "frame " + std::to_string(index) + " (" + box->plan.label(index) + ")";
      if (Error e = check_image(frame, what); !e.ok()) return e;
      reached_impl = true;
      if (Error e = box->impl->add_frame(index, *frame); !e.ok()) return e;
      box->added[index] = 1;
      ++box->added_count;
      return ok();
    });
    poison_if(box, rc, err, reached_impl, false);
    return rc;
  }

  static int end_round(procam_session* s, procam_error* err) noexcept {
    SessionBox* box = box_of(s);
    CallScope scope(link_of(box));  // host services allowed during this call
    bool reached_impl = false;
    const int rc = guarded(err, "end_round", [&]() -> Error {
      if (Error e = check_usable(box, "end_round"); !e.ok()) return e;
      if (box->phase != SessionBox::Phase::in_round)
        return state_error(box->rounds_decoded > 0 &&
                                   box->phase == SessionBox::Phase::between_rounds
                               ? "end_round: called twice; this round is already decoded "
                                 "(call next_plan for the next round)"
                               : "end_round: no round in progress; call next_plan first");
      if (box->added_count != box->plan.size()) {
        std::string missing;
        uint32_t listed = 0;
        for (uint32_t i = 0; i < box->plan.size() && listed < 8; ++i)
          if (!box->added[i]) {
            missing += (listed++ ? ", " : "") + std::to_string(i);
          }
        return state_error("end_round: " + std::to_string(box->plan.size() - box->added_count) +
                           " of " + std::to_string(box->plan.size()) +
                           " frames not added yet (indices " + missing +
                           (box->plan.size() - box->added_count > listed ? ", ..." : "") + ")");
      }
      reached_impl = true;
      if (Error e = box->impl->end_round(); !e.ok()) return e;
      ++box->rounds_decoded;
      box->phase = SessionBox::Phase::between_rounds;
      return ok();
    });
    poison_if(box, rc, err, reached_impl, true);
    return rc;
  }

  static int get_outputs(procam_session* s, const procam_output** outputs, uint32_t* count,
                         procam_error* err) noexcept {
    SessionBox* box = box_of(s);
    CallScope scope(link_of(box));  // host services allowed during this call
    bool reached_impl = false;
    const int rc = guarded(err, "get_outputs", [&]() -> Error {
      if (Error e = check_usable(box, "get_outputs"); !e.ok()) return e;
      if (outputs == nullptr || count == nullptr)
        return invalid_argument("get_outputs: outputs or count is NULL");
      *outputs = nullptr;
      *count = 0;
      if (box->phase == SessionBox::Phase::in_round)
        return state_error("get_outputs: a round is in progress; call end_round first");
      if (box->rounds_decoded == 0)
        return state_error("get_outputs: no round has been decoded yet");
      if (box->outputs.empty() || box->outputs_round != box->rounds_decoded) {
        auto out = std::make_unique<Outputs>();
        reached_impl = true;
        if (Error e = box->impl->outputs(*out); !e.ok()) return e;
        box->outputs.push_back(std::move(out));
        box->outputs_round = box->rounds_decoded;
      }
      Outputs& latest = *box->outputs.back();
      *outputs = latest.view();
      *count = latest.size();
      return ok();
    });
    poison_if(box, rc, err, reached_impl, false);
    return rc;
  }

  // Keeps the host's services for Session::log/progress (plugin_abi.h).
  static int session_set_host(procam_session* s, const procam_host_services* host,
                              procam_error* err) noexcept {
    SessionBox* box = box_of(s);
    return guarded(err, "session_set_host", [&]() -> Error {
      if (HostLink* link = link_of(box)) {
        const bool usable =
            host != nullptr && host->struct_size >= offsetof(procam_host_services, ctx) + sizeof(host->ctx);
        link->attach(usable ? host : nullptr);
        return ok();
      }
      return invalid_argument("session_set_host: session is NULL");
    });
  }

  static const procam_plugin_vtable* vtable(uint32_t host_abi) noexcept {
    static constexpr procam_plugin_vtable table = {
        PROCAM_PLUGIN_ABI_VERSION, sizeof(procam_plugin_vtable), &describe, &session_create,
        &session_destroy,          &next_plan,                   &add_frame, &end_round,
        &get_outputs,              &session_set_host,            &session_create2};
    return host_abi == PROCAM_PLUGIN_ABI_VERSION ? &table : nullptr;
  }
};

}  // namespace detail
}  // namespace procam::sdk

// Defines the two exported symbols of a plugin (plugin_abi.h). Use once, at
// global scope, in one .cpp of the plugin.
//   NAME_STR     plugin name, e.g. "structured-light" (< 64 bytes)
//   VERSION_STR  plugin version, e.g. "0.1.0" (< 32 bytes)
//   METHODS_CSV  comma-separated method names, e.g. "gray,xor02" (< 1024 bytes)
//   DESCRIBE_FN  std::string() returning the describe() JSON array
//   FACTORY_FN   procam::sdk::Error(const CreateArgs&, std::unique_ptr<Session>&)
// procam_plugin_info is a constant-initialised const object, so its bytes sit
// in the file's .rodata and the host can read it without loading the library.
// Its C name clashes with the typedef of the same name in plugin_abi.h, so the
// C++ object gets another name and the asm label gives it the exported one.
// Oversized strings fail to compile ("initializer-string ... too long").
#define PROCAM_DEFINE_PLUGIN(NAME_STR, VERSION_STR, METHODS_CSV, DESCRIBE_FN, FACTORY_FN)     \
  extern "C" __attribute__((visibility("default"), used))                                  \
  const ::procam_plugin_info procam_sdk_plugin_info_ __asm__("procam_plugin_info") = {      \
      PROCAM_PLUGIN_MAGIC, PROCAM_PLUGIN_ABI_VERSION, sizeof(::procam_plugin_info), 0u,     \
      NAME_STR, VERSION_STR, METHODS_CSV};                                                  \
  namespace {                                                                               \
  struct procam_sdk_plugin_traits_ {                                                        \
    static constexpr const char* methods = METHODS_CSV;                                     \
    static constexpr ::procam::sdk::DescribeFn procam_sdk_describe_ = DESCRIBE_FN;          \
    static constexpr ::procam::sdk::FactoryFn procam_sdk_create_ = FACTORY_FN;              \
  };                                                                                        \
  }                                                                                         \
  extern "C" __attribute__((visibility("default"))) const ::procam_plugin_vtable*           \
  procam_plugin_create(uint32_t host_abi_version) {                                         \
    return ::procam::sdk::detail::Abi<procam_sdk_plugin_traits_>::vtable(host_abi_version); \
  }                                                                                         \
  static_assert(true, "require a semicolon after PROCAM_DEFINE_PLUGIN(...)")
