// SPDX-License-Identifier: MIT
// Daemon side of an isolated session (worker_proxy.hpp).
#include "worker_proxy.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/wait.h>

#include <algorithm>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <thread>
#include <atomic>
#include <string_view>

#include "host_services.hpp"
#include "procam/core/log.hpp"
#include "session_checks.hpp"

extern char** environ;

#ifndef PROCAM_WORKER_BUILD_PATH
#define PROCAM_WORKER_BUILD_PATH ""
#endif

namespace procam::host::detail {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

constexpr const char* kWorkerName = "procam-plugin-worker";

bool executable(const std::string& p) { return !p.empty() && ::access(p.c_str(), X_OK) == 0; }

std::string signal_text(int sig) {
  const char* abbrev = ::sigabbrev_np(sig);
  return "signal " + std::to_string(sig) + (abbrev ? std::string(" (SIG") + abbrev + ")" : std::string());
}

std::string ms_text(std::chrono::milliseconds ms) { return std::to_string(ms.count()) + " ms"; }

// Every worker is spawned from this one thread, which lives as long as the
// process (never joined, never destroyed). The worker's parent-death signal
// (SIGKILL, worker_main.cpp) fires when the *thread* that spawned it ends;
// spawned from a scan or client thread, a worker would be killed when that
// thread ends. From here it fires only when the daemon dies -- which is what
// ends a worker the daemon had stopped (freeze(): a stopped worker reads no
// EOF).
class Spawner {
public:
  static Spawner& get() {
    static Spawner* s = new Spawner;  // outlives every static destructor that may spawn
    return *s;
  }
  // Runs `job` on the spawner thread and returns its result.
  int run(const std::function<int()>& job) {
    Job j{&job, 0, false};
    std::unique_lock lock(mu_);
    queue_.push_back(&j);
    cv_.notify_all();
    cv_.wait(lock, [&] { return j.done; });
    return j.rc;
  }

private:
  struct Job {
    const std::function<int()>* fn;
    int rc;
    bool done;
  };
  Spawner() { std::thread([this] { loop(); }).detach(); }
  void loop() {
    std::unique_lock lock(mu_);
    for (;;) {
      cv_.wait(lock, [&] { return !queue_.empty(); });
      Job* j = queue_.front();
      queue_.erase(queue_.begin());
      lock.unlock();
      const int rc = (*j->fn)();
      lock.lock();
      j->rc = rc;
      j->done = true;
      cv_.notify_all();
    }
  }
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<Job*> queue_;
};

}  // namespace

Result<std::string> find_worker(const std::string& configured) {
  if (!configured.empty()) {
    if (executable(configured)) return configured;
    return Error(Code::not_found, "the plugin worker '" + configured + "' (configured) is not an executable file",
                 "fix plugins.worker in procamd.json, leave it out to use the one installed beside procamd, or "
                 "run plugins in-process (plugins.isolation \"in_process\")");
  }
  std::vector<std::string> tried;
  if (const char* env = std::getenv("PROCAM_PLUGIN_WORKER"); env != nullptr && *env != '\0') {
    if (executable(env)) return std::string(env);
    tried.push_back(std::string(env) + " ($PROCAM_PLUGIN_WORKER)");
  }
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    for (const fs::path& p : {exe.parent_path() / kWorkerName,
                              exe.parent_path() / ".." / "libexec" / "procam" / kWorkerName}) {
      if (executable(p.string())) return p.lexically_normal().string();
      tried.push_back(p.lexically_normal().string());
    }
  }
  if (executable(PROCAM_WORKER_BUILD_PATH)) return std::string(PROCAM_WORKER_BUILD_PATH);
  std::string list;
  for (const auto& t : tried) list += (list.empty() ? "" : ", ") + t;
  return Error(Code::not_found, std::string("cannot find the plugin worker ") + kWorkerName + " (looked at: " + list + ")",
               "install it beside procamd, set plugins.worker in procamd.json, or run plugins in-process "
               "(plugins.isolation \"in_process\")");
}

std::string scratch_parent_of(const IsolationOptions& options) {
  if (!options.scratch_parent.empty()) return options.scratch_parent;
  const char* tmp = std::getenv("TMPDIR");
  return tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
}

size_t sweep_stale_scratch(const std::string& parent) {
  constexpr std::string_view prefix = "procam-worker-";
  size_t removed = 0;
  std::error_code ec;
  for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) != 0 || !it->is_directory(ec) || it->is_symlink(ec)) continue;
    // procam-worker-<daemon pid>-XXXXXX (worker/sandbox.cpp)
    const size_t dash = name.find('-', prefix.size());
    if (dash == std::string::npos || dash == prefix.size()) continue;
    const std::string digits = name.substr(prefix.size(), dash - prefix.size());
    if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const pid_t owner = static_cast<pid_t>(std::stol(digits));
    if (owner <= 0 || ::kill(owner, 0) == 0 || errno != ESRCH) continue;  // alive (or not ours to judge)
    std::error_code rm;
    fs::remove_all(it->path(), rm);  // does not follow symlinks left inside
    if (rm) {
      PROCAM_LOG(plugins, warn) << "cannot remove the stale worker scratch folder '" << it->path().string()
                                << "': " << rm.message();
      continue;
    }
    ++removed;
  }
  if (removed > 0)
    PROCAM_LOG(plugins, info) << "removed " << removed << " scratch folder(s) of plugin workers whose daemon "
                              << "is gone (killed?) from '" << parent << "'";
  return removed;
}

WorkerProxy::WorkerProxy(const IsolationOptions& options, std::string plugin)
    : options_(options), plugin_(std::move(plugin)) {}

WorkerProxy::~WorkerProxy() {
  sock_ = wire::UniqueFd();
  // Nothing of the worker's is worth keeping: kill it rather than wait for
  // its exit (static destructors, unmapping) on the caller's time.
  if (pid_ > 0) (void)reap(/*kill_now=*/true);
  if (!scratch_.empty()) {
    std::error_code ec;
    fs::remove_all(scratch_, ec);  // does not follow symlinks the plugin left there
    if (ec) PROCAM_LOG(plugins, warn) << "cannot remove the worker's scratch folder '" << scratch_ << "': " << ec.message();
  }
}

Status WorkerProxy::read_hello(const wire::Message& hello) {
  wire::Reader r(reinterpret_cast<const uint8_t*>(hello.payload.data()), hello.payload.size());
  const uint32_t flags = r.u32("sandbox flags");
  const std::string scratch(r.str("scratch folder", 4096));
  const std::string problems(r.str("sandbox problems", 8192));
  if (!r.ok()) return Error(Code::corrupt_data, r.error());
  sandbox_flags_ = flags;  // sent before any plugin code ran in the worker
  // Only a folder of the name the worker makes, where it makes them.
  const fs::path sp(scratch);
  const fs::path parent = scratch_parent_of(options_);
  std::error_code ec1, ec2;
  if (!scratch.empty() && fs::weakly_canonical(sp.parent_path(), ec1) == fs::weakly_canonical(parent, ec2) &&
      !ec1 && !ec2 && sp.filename().string().rfind("procam-worker-", 0) == 0)
    scratch_ = scratch;
  static std::atomic<bool> logged{false};
  if (options_.sandbox && !logged.exchange(true)) {
    if (problems.empty())
      PROCAM_LOG(plugins, info) << "plugin workers run sandboxed (flags 0x" << std::hex << flags << std::dec
                                << "; README.md \"Least privilege\")";
    else
      PROCAM_LOG(plugins, warn) << "plugin workers run with a partial sandbox: " << problems;
  }
  // The worker's shared heap (version 5), mapped once; without it (or if
  // it is unusable) outputs are copied into the arena as before.
  outputs_copy_.set_pages_stay(options_.sandbox && (flags & wire::kSandboxPagesStay) != 0);
  if (hello.fd) {
    if (Status st = outputs_copy_.adopt_heap(hello.fd.get()); !st)
      PROCAM_LOG(plugins, warn) << "plugin '" << plugin_ << "': its worker's shared heap is not used: " << st.message();
  }
  return {};
}

std::string WorkerProxy::reap(bool kill_now) {
  if (pid_ <= 0) return "";
  const pid_t pid = std::exchange(pid_, -1);
  if (kill_now) ::kill(pid, SIGKILL);
  int st = 0;
  // A worker that got EOF exits at once; give it a moment, then kill it.
  const auto give_up = Clock::now() + std::chrono::milliseconds(kill_now ? 5000 : 200);
  for (;;) {
    const pid_t w = ::waitpid(pid, &st, WNOHANG);
    if (w == pid) break;
    if (w < 0 && errno != EINTR) return "its exit status is unknown (SIGCHLD ignored?)";
    if (Clock::now() > give_up) {
      ::kill(pid, SIGKILL);
      while (::waitpid(pid, &st, 0) < 0 && errno == EINTR) {
      }
      return "it was killed (it did not exit after its connection closed)";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (WIFSIGNALED(st)) return "killed by " + signal_text(WTERMSIG(st));
  if (WIFEXITED(st) && WEXITSTATUS(st) != 0) return "exited with status " + std::to_string(WEXITSTATUS(st));
  return "";
}

Status WorkerProxy::fail(const char* call_name, Code code, const std::string& cause) {
  broken_ = true;
  if (pid_ > 0) (void)reap(/*kill_now=*/true);
  sock_ = wire::UniqueFd();
  const std::string message = "plugin '" + plugin_ + "' " + cause + " in " + call_name;
  broken_reason_ = message;
  PROCAM_LOG(plugins, warn) << message;
  return Error(code, message,
               "procamd is unaffected and the next scan gets a fresh worker; frames saved with save_frames "
               "can be decoded again offline (procam decode)");
}

std::chrono::milliseconds WorkerProxy::round_deadline(size_t frames) const {
  return options_.call_timeout + options_.per_frame_timeout * static_cast<int64_t>(frames);
}

Status WorkerProxy::spawn(const std::string& worker_path) {
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0)
    return Error(Code::unavailable, std::string("socketpair for the plugin worker: ") + std::strerror(errno));
  sock_ = wire::UniqueFd(sv[0]);
  // The child's end goes to fd 3; keep its number clear of 0..3 first.
  wire::UniqueFd child(::fcntl(sv[1], F_DUPFD_CLOEXEC, 10));
  ::close(sv[1]);
  if (!child) return Error(Code::unavailable, std::string("fcntl: ") + std::strerror(errno));
  posix_spawn_file_actions_t fa;
  posix_spawnattr_t attr;
  posix_spawn_file_actions_init(&fa);
  posix_spawnattr_init(&attr);
  posix_spawn_file_actions_adddup2(&fa, child.get(), wire::kControlFd);
  // Default signal mask and dispositions: procamd blocks its stop signals for
  // signalfd and may ignore some; the worker must die normally on faults.
  sigset_t none, defaults;
  sigemptyset(&none);
  sigemptyset(&defaults);
  for (int s : {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGTERM, SIGINT, SIGHUP, SIGCHLD})
    sigaddset(&defaults, s);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  // Its own process group: the daemon's group may become orphaned (its
  // parent, a shell, exits), and the kernel then sends SIGCONT to every
  // stopped member -- which would resume a frozen worker (freeze()). The
  // worker's own group is orphaned only when the daemon is gone.
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETPGROUP);
  std::vector<std::string> args = {worker_path, "--memory-limit-mb", std::to_string(options_.memory_limit_mb),
                                   "--sandbox", options_.sandbox ? "1" : "0", "--parent-pid",
                                   std::to_string(::getpid())};
  if (!options_.scratch_parent.empty()) {
    args.push_back("--scratch-parent");
    args.push_back(options_.scratch_parent);
  }
  for (const std::string& r : options_.readable) {
    args.push_back("--readable");
    args.push_back(r);
  }
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  const int rc = Spawner::get().run(
      [&] { return ::posix_spawn(&pid, worker_path.c_str(), &fa, &attr, argv.data(), environ); });
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  if (rc != 0)
    return Error(Code::unavailable, "cannot start the plugin worker '" + worker_path + "': " + std::strerror(rc));
  pid_ = pid;
  return {};
}

SparePool::~SparePool() = default;

Result<std::unique_ptr<WorkerProxy>> WorkerProxy::spawn_spare(const IsolationOptions& options) {
  auto path = find_worker(options.worker_path);
  if (!path) return path.status();
  std::unique_ptr<WorkerProxy> p(new WorkerProxy(options, ""));
  PROCAM_TRY(p->spawn(*path));
  return p;
}

Result<std::unique_ptr<WorkerProxy>> WorkerProxy::start(const IsolationOptions& options,
                                                        const wire::CreateRequest& request, bool& host_services,
                                                        std::unique_ptr<WorkerProxy> spare) {
  std::unique_ptr<WorkerProxy> p = std::move(spare);
  Result<wire::Message> hello = Error(Code::unavailable, "no spare worker");
  if (p) {
    p->plugin_ = request.plugin_name;
    hello = wire::recv_msg(p->sock_.get(), static_cast<int>(options.start_timeout.count()));
    if (!hello) p.reset();  // died or stuck while waiting: start afresh below
  }
  if (!p) {
    auto path = find_worker(options.worker_path);
    if (!path) return path.status();
    p.reset(new WorkerProxy(options, request.plugin_name));
    PROCAM_TRY(p->spawn(*path));
    // hello: the worker runs and speaks our protocol version.
    hello = wire::recv_msg(p->sock_.get(), static_cast<int>(options.start_timeout.count()));
  }
  if (!hello) {
    const Code c = hello.status().code();
    return p->fail("start", c == Code::timeout ? Code::timeout : Code::plugin_error,
                   c == Code::timeout   ? "worker did not start within " + ms_text(options.start_timeout)
                   : c == Code::unavailable ? "worker ended before saying hello (" + p->reap(false) + ")"
                   // A worker of another build: say so rather than "malformed".
                   : hello.status().message().rfind("protocol version", 0) == 0
                       ? "worker speaks another " + hello.status().message() +
                             " (a procam-plugin-worker from another build: install procamd and its worker "
                             "together, or point plugins.worker at the matching one)"
                       : "worker sent a malformed hello (" + hello.status().message() + ")");
  }
  if (hello->type != static_cast<uint16_t>(wire::Msg::hello))
    return p->fail("start", Code::plugin_error, std::string("worker sent '") + wire::msg_name(hello->type) +
                                                    "' instead of hello");
  if (Status st = p->read_hello(*hello); !st)
    return p->fail("start", Code::plugin_error, "worker sent a malformed hello (" + st.message() + ")");
  PROCAM_TRY(p->create(request, host_services));
  return p;
}

Status WorkerProxy::create(const wire::CreateRequest& request, bool& host_services) {
  auto blob = wire::make_sealed_blob(wire::encode_create(request), "procam-create");
  if (!blob) return blob.status();
  ++sessions_;
  auto ok = call(wire::Msg::create, "session_create", {}, blob->get(), options_.start_timeout);
  if (!ok) return ok.status();
  wire::Reader r(reinterpret_cast<const uint8_t*>(ok->payload.data()), ok->payload.size());
  host_services = r.u8("host services flag") != 0;
  if (!r.ok()) return fail("session_create", Code::plugin_error, "worker sent a malformed reply (" + r.error() + ")");
  return {};
}

Status WorkerProxy::reuse(const wire::CreateRequest& request, bool& host_services) {
  if (request.plugin_name != plugin_)
    return Error(Code::internal, "worker of plugin '" + plugin_ + "' offered for plugin '" + request.plugin_name + "'");
  return create(request, host_services);
}

bool WorkerProxy::end_session_for_reuse() {
  bridge_ = nullptr;  // the Session's bridge dies with it
  plan_blob_ = wire::Mapping();
  outputs_.reset();  // the Session (and every view of its outputs) is gone
  thaw();            // so the worker may run and write its arena again
  outputs_blob_ = wire::Mapping();
  last_round_frames_ = 0;
  if (broken_ || errored_ || sessions_ >= options_.max_sessions_per_worker) return false;
  if (!call(wire::Msg::end_session, "end_session", {}, -1, options_.call_timeout)) return false;
  if (errored_) return false;
  // Nothing of this scan's files for the next one: empty the scratch folder
  // (kept itself: the worker's Landlock rule is bound to it). remove_all
  // does not follow the symlinks a plugin may have left there.
  if (!scratch_.empty()) {
    std::error_code ec;
    for (fs::directory_iterator it(scratch_, ec), end; !ec && it != end; it.increment(ec)) {
      fs::remove_all(it->path(), ec);
      if (ec) break;
    }
    if (ec || !fs::is_empty(scratch_, ec) || ec) {
      PROCAM_LOG(plugins, warn) << "cannot empty the worker's scratch folder '" << scratch_
                                << "'; the worker is not reused" << (ec ? ": " + ec.message() : std::string());
      return false;
    }
  }
  return true;
}

Result<wire::Message> WorkerProxy::call(wire::Msg type, const char* call_name, const std::string& payload, int fd,
                                        std::chrono::milliseconds deadline) {
  if (broken_)
    return Error(Code::failed_precondition, "this session's worker is gone: " + broken_reason_,
                 "start a new scan");
  // Only end_session follows a freeze (stop() answers itself while frozen;
  // Session sends nothing else after outputs()), and it thaws first. Kept
  // as a net: a frozen worker would never answer, and its deadline must not
  // count time it was kept stopped.
  thaw();
  // Replies ahead (WORKER_PROTOCOL.md): after an end_round that asked for
  // them, the worker sends the next_plan reply, and after "no more rounds"
  // the get_outputs reply, without waiting for the requests. The call that
  // expects one sends nothing and takes it; any other call first takes the
  // pending ones (and drops them: its caller did not ask).
  const bool unasked = (type == wire::Msg::next_plan && ahead_ == Ahead::plan) ||
                       (type == wire::Msg::get_outputs && ahead_ == Ahead::outputs);
  if (!unasked && ahead_ != Ahead::none) {
    if (ahead_ == Ahead::plan) {
      auto dropped = call(wire::Msg::next_plan, "next_plan", {}, -1, options_.call_timeout);
      if (!dropped && broken_) return dropped.status();
    }
    if (ahead_ == Ahead::outputs) {  // pending, or the plan said "no more rounds"
      auto outs = call(wire::Msg::get_outputs, "get_outputs", {}, -1, round_deadline(last_round_frames_));
      if (!outs && broken_) return outs.status();
      // A new output arena comes with the reply that first needs it: keep
      // it, or the next session's outputs would be read from the old one.
      if (outs && outs->fd && ahead_mode_ != 0) {
        if (Status s = outputs_copy_.adopt(outs->fd.get()); !s)
          return fail("get_outputs", Code::plugin_error, "sent bad outputs: " + s.message());
      }
    }
  }
  const Ahead was = std::exchange(ahead_, Ahead::none);
  const uint32_t seq = ++seq_;
  if (!unasked) {
    if (Status s = wire::send_msg(sock_.get(), type, seq, payload, fd); !s) {
      const std::string how = reap(false);
      return fail(call_name, Code::plugin_error, "worker is gone (" + (how.empty() ? s.message() : how) + ")");
    }
  }
  const auto until = Clock::now() + deadline;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    auto m = wire::recv_msg(sock_.get(), static_cast<int>(std::max<int64_t>(0, left.count())));
    if (!m) {
      switch (m.status().code()) {
        case Code::timeout:
          (void)reap(true);
          return fail(call_name, Code::timeout,
                      "did not answer within " + ms_text(deadline) + " (worker killed)");
        case Code::unavailable: {
          const std::string how = reap(false);
          std::string cause = how.empty() ? std::string("closed its worker's control connection")
                                          : "crashed: worker " + how;
          if (options_.memory_limit_mb > 0 && !how.empty())
            cause += " (the worker's address-space limit is " + std::to_string(options_.memory_limit_mb) +
                     " MiB; a plugin that exceeds it sees failed allocations)";
          return fail(call_name, Code::plugin_error, cause);
        }
        default:
          (void)reap(true);
          return fail(call_name, Code::plugin_error,
                      "sent garbage on the control channel (" + m.status().message() + "; worker killed)");
      }
    }
    if (m->seq != seq) {
      (void)reap(true);
      return fail(call_name, Code::plugin_error,
                  "sent garbage on the control channel (a reply to request " + std::to_string(m->seq) +
                      " while waiting for " + std::to_string(seq) + "; worker killed)");
    }
    wire::Reader r(reinterpret_cast<const uint8_t*>(m->payload.data()), m->payload.size());
    switch (static_cast<wire::Msg>(m->type)) {
      case wire::Msg::ok:
        // "No more rounds" ahead: the outputs follow unasked.
        if (was == Ahead::plan && !m->payload.empty() && m->payload[0] == '\0') ahead_ = Ahead::outputs;
        return m;
      case wire::Msg::error: {
        Status st;
        if (Status bad = wire::decode_error(m->payload, st); !bad)
          return fail(call_name, Code::plugin_error,
                      "sent garbage on the control channel (" + bad.message() + "; worker killed)");
        errored_ = true;  // the plugin refused something: this worker is not reused
        if (options_.memory_limit_mb > 0 && st.message().find("PROCAM_ERR_NO_MEMORY") != std::string::npos)
          st = Error(st.code(), st.message() + " (the worker's address-space limit is " +
                                    std::to_string(options_.memory_limit_mb) + " MiB)", st.hint());
        return st;
      }
      case wire::Msg::log: {
        const int level = r.i32("log level");
        std::string line(r.str("log line", 8 * 1024));
        if (!r.ok()) break;
        // The worker sanitised it; a hostile one may not have.
        for (char c : line)
          if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
            line = sanitize_log_message(line.c_str());
            break;
          }
        if (bridge_ != nullptr) bridge_->deliver_log(level, line);
        continue;
      }
      case wire::Msg::progress: {
        const double fraction = r.f64("progress");
        const std::string stage(r.str("stage", 1024));
        if (!r.ok()) break;
        if (bridge_ != nullptr) bridge_->deliver_progress(fraction, stage.c_str());
        continue;
      }
      default:
        r.fail(std::string("unexpected message type ") + std::to_string(m->type));
    }
    (void)reap(true);
    return fail(call_name, Code::plugin_error,
                "sent garbage on the control channel (" + r.error() + "; worker killed)");
  }
}

Result<std::optional<Plan>> WorkerProxy::next_plan(uint32_t round) {
  // The previous plan's blob stays mapped until a new plan replaces it (or
  // the session ends): unmapping it is the last reference to 32 MB of
  // shared memory for the ensemble (41 patterns), and freeing those pages
  // must not fall on the closing next_plan, which the client waits for
  // after the last frame (README.md "Speed"). The Plan contract (views valid
  // until the next call) holds: they stay valid longer.
  auto m = call(wire::Msg::next_plan, "next_plan", {}, -1, options_.call_timeout);
  if (!m) return m.status();
  wire::Reader r(reinterpret_cast<const uint8_t*>(m->payload.data()), m->payload.size());
  const bool has = r.u8("plan flag") != 0;
  if (!r.ok() || (has && !m->fd))
    return fail("next_plan", Code::plugin_error, "sent a malformed plan reply (worker killed)");
  if (!has) return std::optional<Plan>{};
  auto blob = wire::map_sealed_blob(m->fd.get());
  if (!blob) return fail("next_plan", Code::plugin_error, "sent a bad plan: " + blob.status().message());
  plan_blob_ = std::move(*blob);
  wire::AbiPlan abi;
  if (Status s = wire::decode_plan(plan_blob_, abi); !s)
    return fail("next_plan", Code::plugin_error, "sent a bad plan: " + s.message());
  auto plan = plan_from_abi(&abi.plan, "plugin '" + plugin_ + "'", round);
  if (!plan) return plan.status();
  last_round_frames_ = plan->frames.size();
  return std::optional<Plan>(std::move(*plan));
}

Status WorkerProxy::add_frame(uint32_t index, const procam_image& frame) {
  const size_t row = wire::packed_row_bytes(frame);
  const size_t bytes = row * frame.height;
  if (row == 0) return Error(Code::invalid_argument, "frame " + std::to_string(index) + " has an unknown pixel type");
  if (!ring_ || ring_->slot_size < bytes) {
    // Slots sized from the first frame (every frame of a camera has one size).
    const uint64_t slot = (bytes + 4095) / 4096 * 4096;
    auto ring = wire::make_ring(std::max<uint32_t>(1, options_.frame_slots), slot);
    if (!ring) return ring.status();
    wire::Writer w;
    w.u32(ring->slots);
    w.u64(ring->slot_size);
    auto m = call(wire::Msg::set_ring, "add_frame", w.bytes(), ring->worker_fd.get(), options_.call_timeout);
    if (!m) return m.status();
    ring->worker_fd = wire::UniqueFd();  // the worker has its copy
    ring_ = std::move(*ring);
    next_slot_ = 0;
  }
  const uint32_t slot = next_slot_++ % ring_->slots;
  // The one copy: camera buffer -> shared slot.
  uint8_t* dst = ring_->map.mutable_data() + slot * ring_->slot_size;
  const auto* src = static_cast<const uint8_t*>(frame.data);
  if (frame.stride_bytes == row) {
    std::memcpy(dst, src, bytes);
  } else {
    for (uint32_t y = 0; y < frame.height; ++y) std::memcpy(dst + y * row, src + y * frame.stride_bytes, row);
  }
  wire::Writer w;
  w.u32(index);
  w.u32(slot);
  w.u32(frame.width);
  w.u32(frame.height);
  w.u32(frame.channels);
  w.u32(frame.pixel_type);
  w.u32(frame.bit_depth);
  auto m = call(wire::Msg::add_frame, "add_frame", w.bytes(), -1, options_.call_timeout);
  return m ? Status::Ok() : m.status();
}

Status WorkerProxy::end_round(size_t frames, bool then_next_plan) {
  // Version 6: ask the worker to go on with next_plan (and get_outputs
  // after the last round) on its own; the payload names the outputs' mode.
  const std::string payload = wire::encode_end_round(then_next_plan ? static_cast<uint8_t>(1 + outputs_mode()) : 0);
  auto m = call(wire::Msg::end_round, "end_round", payload, -1, round_deadline(frames));
  if (!m) return m.status();
  if (then_next_plan) {
    ahead_ = Ahead::plan;
    ahead_mode_ = outputs_mode();
  }
  return {};
}

uint8_t WorkerProxy::outputs_mode() const {
  // A worker that can serve another session keeps its output arena, which
  // this side copies from; one that cannot (reuse off) sends a sealed blob,
  // mapped without a copy (WORKER_PROTOCOL.md "Output arena"). Maps already
  // in the worker's shared heap are named, not copied, only when this side
  // will read them frozen (README.md "Speed"): a worker that keeps running
  // would send them through the arena anyway.
  const bool arena = options_.max_idle_workers > 0;
  const bool heap = arena && outputs_copy_.has_heap() && may_freeze();
  return heap ? 2 : arena ? 1 : 0;
}

Status WorkerProxy::stop() {
  // After outputs() (the worker is frozen) the worker's Session::stop would
  // only mark a finished scan finished: nothing to ask a stopped worker.
  if (frozen_) return {};
  auto m = call(wire::Msg::stop, "stop", {}, -1, options_.call_timeout);
  return m ? Status::Ok() : m.status();
}

// The largest arena part of an outputs reply decoded while the worker
// stops (outputs()): copying it costs less than the stop it overlaps
// (~20 us for 256 KiB against ~0.1 ms). The ensemble's is ~4.5 KB.
constexpr uint64_t kDecodeWhileStoppingBytes = 256 * 1024;

Result<std::vector<Output>> WorkerProxy::outputs() {
  // Views of the first call stay valid until the session ends: never take a
  // second copy under them.
  if (outputs_) return *outputs_;
  // The mode end_round asked for if the reply is on its way, else now's
  // (the same: nothing it depends on changes within a session).
  const uint8_t mode = ahead_ == Ahead::outputs ? ahead_mode_ : outputs_mode();
  const bool arena = mode != 0, heap = mode == 2;
  auto m = call(wire::Msg::get_outputs, "get_outputs", std::string(1, static_cast<char>(mode)), -1,
                round_deadline(last_round_frames_));
  if (!m) return m.status();
  wire::Reader r(reinterpret_cast<const uint8_t*>(m->payload.data()), m->payload.size());
  const bool has = r.u8("outputs flag") != 0;
  const uint64_t used = r.u64("output bytes");
  if (!r.ok() || !has || !r.at_end() || (!arena && !m->fd))
    return fail("get_outputs", Code::plugin_error, "sent a malformed outputs reply (worker killed)");
  std::vector<procam_output> abi;
  Status decoded;
  if (!arena) {
    auto blob = wire::map_sealed_blob(m->fd.get());
    if (!blob) return fail("get_outputs", Code::plugin_error, "sent bad outputs: " + blob.status().message());
    outputs_blob_ = std::move(*blob);
    decoded = wire::decode_outputs(outputs_blob_, abi);
  } else {
    if (m->fd) {
      if (Status s = outputs_copy_.adopt(m->fd.get()); !s)
        return fail("get_outputs", Code::plugin_error, "sent bad outputs: " + s.message());
    }
    // Decoding while the worker stops (README.md "Speed"): where the
    // arena's part is small (names, JSON, sizes and heap offsets: the maps
    // lie in the heap) and the worker cannot remove heap pages, the stop is
    // started first, and the arena is copied and decoded and the heap
    // ranges checked while the worker's threads stop. Nothing decoded reads
    // the heap's bytes, only its page table, and a checked page stays; the
    // views into the heap are handed out only once the stop is complete.
    if (heap && used <= kDecodeWhileStoppingBytes && outputs_copy_.pages_stay() && stop_begin()) {
      if (Status s = outputs_copy_.take(used); !s)
        return fail("get_outputs", Code::plugin_error, "sent bad outputs: " + s.message());
      decoded = wire::decode_outputs(outputs_copy_.data(), outputs_copy_.size(), abi, outputs_copy_.heap_in_place());
      if (!decoded) return fail("get_outputs", Code::plugin_error, "sent bad outputs: " + decoded.message());
      // The checks read names, units and JSON: all in the private copy.
      auto outs = outputs_from_abi(abi.data(), static_cast<uint32_t>(abi.size()), "plugin '" + plugin_ + "'");
      if (stop_wait()) {
        if (outs) outputs_ = *outs;
        return outs;
      }
      abi.clear();  // still running: copy the heap ranges after all
      decoded = wire::decode_outputs(outputs_copy_.data(), outputs_copy_.size(), abi, outputs_copy_.heap_copied());
    } else {
      // A frozen worker cannot write its arena or its heap until the session
      // ends: read them in place. Otherwise only private copies are read: the
      // worker may still write both (output_arena.hpp).
      const bool frozen = freeze();
      const Status s = frozen ? outputs_copy_.view(used) : outputs_copy_.take(used);
      if (!s) return fail("get_outputs", Code::plugin_error, "sent bad outputs: " + s.message());
      wire::HeapResolver refs;
      if (heap) refs = frozen ? outputs_copy_.heap_in_place() : outputs_copy_.heap_copied();
      decoded = wire::decode_outputs(outputs_copy_.data(), outputs_copy_.size(), abi, refs);
    }
  }
  if (!decoded) return fail("get_outputs", Code::plugin_error, "sent bad outputs: " + decoded.message());
  auto outs = outputs_from_abi(abi.data(), static_cast<uint32_t>(abi.size()), "plugin '" + plugin_ + "'");
  if (outs) outputs_ = *outs;
  return outs;
}

}  // namespace procam::host::detail

namespace procam::host::detail {

bool WorkerProxy::may_freeze() const {
  constexpr uint32_t needed = wire::kSandboxSeccomp | wire::kSandboxFreezeSafe | wire::kSandboxLandlockScope;
  return options_.freeze_outputs && options_.sandbox && pid_ > 0 && !broken_ && (sandbox_flags_ & needed) == needed;
}

namespace {
// The state letter of a /proc stat line ("tid (comm) S ..."; comm may hold
// ')' itself, so the last one counts), or 0 if the line is malformed.
char stat_state(const char* line) {
  const char* paren = std::strrchr(line, ')');
  return paren != nullptr && paren[1] == ' ' ? paren[2] : '\0';
}

// The thread's stat line read again from an open file (pread at 0: procfs
// makes it anew); <= 0 when the thread is gone (ESRCH) or on an error.
ssize_t read_stat(int fd, char (&buf)[512]) {
  const ssize_t got = ::pread(fd, buf, sizeof buf - 1, 0);
  if (got > 0) buf[got] = '\0';
  return got;
}
}  // namespace

void ThreadStates::clear() {
  pid_ = -1;
  task_dir_ = wire::UniqueFd();
  stat_.clear();
}

bool ThreadStates::settled(pid_t pid) {
  // Raw system calls, not std::filesystem and stdio: this runs on every
  // frozen outputs reply, after the last frame.
  if (pid != pid_ || !task_dir_) {
    clear();
    char path[64];
    std::snprintf(path, sizeof path, "/proc/%d/task", static_cast<int>(pid));
    task_dir_ = wire::UniqueFd(::open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC));
    if (!task_dir_) return false;
    pid_ = pid;
  } else if (::lseek(task_dir_.get(), 0, SEEK_SET) != 0) {
    clear();
    return false;
  }
  std::vector<std::pair<pid_t, wire::UniqueFd>> kept;  // this call's threads, in listing order
  kept.reserve(stat_.size());
  alignas(8) char entries[4096];
  bool settled = true;
  for (;;) {
    const long n = ::syscall(SYS_getdents64, task_dir_.get(), entries, sizeof entries);
    if (n < 0) settled = false;
    if (n <= 0) break;
    for (long at = 0; at < n && settled;) {
      const auto* e = reinterpret_cast<const struct dirent64*>(entries + at);
      at += e->d_reclen;
      if (e->d_name[0] < '0' || e->d_name[0] > '9') continue;  // "." and ".."
      const auto tid = static_cast<pid_t>(std::strtol(e->d_name, nullptr, 10));
      char buf[512];
      ssize_t got = 0;
      const auto old = std::find_if(stat_.begin(), stat_.end(), [&](const auto& t) { return t.first == tid && t.second; });
      wire::UniqueFd fd;
      if (old != stat_.end()) {
        fd = std::move(old->second);
        got = read_stat(fd.get(), buf);
      }
      if (got <= 0) {  // not kept, or its thread is gone and the tid listed is another one
        char stat_path[48];
        std::snprintf(stat_path, sizeof stat_path, "%.20s/stat", e->d_name);
        fd = wire::UniqueFd(::openat(task_dir_.get(), stat_path, O_RDONLY | O_CLOEXEC));
        if (!fd) continue;  // released meanwhile
        got = read_stat(fd.get(), buf);
        if (got <= 0) continue;  // released between the open and the read
      }
      const char state = stat_state(buf);
      if (state != 'T' && state != 'Z' && state != 'X') settled = false;
      if (kept.size() < kMaxOpen) kept.emplace_back(tid, std::move(fd));
    }
    if (!settled) break;
  }
  stat_ = std::move(kept);
  return settled;
}

bool WorkerProxy::freeze() { return stop_begin() && stop_wait(); }

bool WorkerProxy::stop_begin() {
  if (frozen_) return true;
  if (!may_freeze()) return false;
  if (::kill(pid_, SIGSTOP) != 0) return false;
  frozen_ = true;  // from here on thaw() must run, whatever happens
  return true;
}

bool WorkerProxy::stop_wait() {
  if (!frozen_) return false;
  // The stop is complete when every thread of the worker has stopped (a
  // thread inside a system call stops when it returns from it, after its
  // last write); the kernel then reports it to the parent. A plugin thread
  // that sends itself SIGCONT before it stops cancels the stop: the
  // deadline catches that, and the caller copies instead.
  const auto start = Clock::now();
  const auto give_up = start + std::chrono::seconds(1);
  for (;;) {
    siginfo_t info{};
    if (::waitid(P_PID, static_cast<id_t>(pid_), &info, WSTOPPED | WEXITED | WNOWAIT | WNOHANG) != 0) {
      if (errno == EINTR) continue;
      break;  // ECHILD: SIGCHLD ignored, the kernel reaped it: no report to trust
    }
    if (info.si_pid == pid_) {
      if (info.si_code == CLD_EXITED || info.si_code == CLD_KILLED || info.si_code == CLD_DUMPED) return true;
      // CLD_TRAPPED (a debugger attached) and anything else: not ours to trust.
      if (info.si_code != CLD_STOPPED) break;
      if (thread_states_.settled(pid_)) return true;
    }
    if (Clock::now() > give_up) {
      PROCAM_LOG(plugins, warn) << "plugin '" << plugin_ << "': its worker did not stop within 1 s after its "
                                << "outputs reply; the outputs are copied instead";
      break;
    }
    // The stop needs each worker thread to run once (0.05-0.2 ms on the
    // project's VM, more when its virtual CPU halted): wait for it awake for
    // 2 ms (a yield lets those threads have this CPU), then in 100 us sleeps,
    // which would add up to a timer slack's worth to a stop that is late.
    if (Clock::now() - start < std::chrono::milliseconds(2)) std::this_thread::yield();
    else std::this_thread::sleep_for(std::chrono::microseconds(100));
  }
  thaw();
  return false;
}

void WorkerProxy::thaw() {
  if (!frozen_) return;
  frozen_ = false;
  if (pid_ > 0) ::kill(pid_, SIGCONT);
}

}  // namespace procam::host::detail
