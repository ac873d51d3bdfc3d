// SPDX-License-Identifier: MIT
// Loading one plugin file, step 2: run the dlopen check in a fork()ed child
// and read its report, so a crash or hang there cannot take the daemon down.
// See plugin_loader.hpp.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <thread>

#include "plugin_loader.hpp"

namespace procam::host::detail {
namespace {

const char* signal_name(int sig) {
  switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGABRT: return "SIGABRT";
    case SIGILL: return "SIGILL";
    case SIGFPE: return "SIGFPE";
    case SIGTRAP: return "SIGTRAP";
    case SIGSYS: return "SIGSYS";
    case SIGKILL: return "SIGKILL";
    case SIGTERM: return "SIGTERM";
    case SIGINT: return "SIGINT";
    case SIGQUIT: return "SIGQUIT";
    case SIGPIPE: return "SIGPIPE";
    case SIGALRM: return "SIGALRM";
    case SIGXCPU: return "SIGXCPU";
    case SIGXFSZ: return "SIGXFSZ";
    default: return nullptr;
  }
}

// --- probe wire format (child -> parent over a pipe) -------------------------
// 'P' phase(u8)                                    before each step
// 'R' code(u32) msg_len(u32) hint_len(u32) msg hint  the final result
constexpr size_t kMaxReport = 64 * 1024;

void write_all(int fd, const void* data, size_t n) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return;  // parent gone: nothing useful to do
    p += w;
    n -= static_cast<size_t>(w);
  }
}

[[noreturn]] void child_main(int fd, const std::string& path, const FileInfo& file) {
  // No core files from plugins that crash on purpose or by bug while probed,
  // and the default action for fatal signals, whatever the daemon installed.
  struct rlimit no_core {
    0, 0
  };
  ::setrlimit(RLIMIT_CORE, &no_core);
  for (int sig : {SIGSEGV, SIGBUS, SIGABRT, SIGILL, SIGFPE, SIGTRAP, SIGSYS})
    ::signal(sig, SIG_DFL);
  ::signal(SIGPIPE, SIG_IGN);

  Status st;
  try {
    auto r = load_and_check(
        path, file,
        [fd](Phase p) {
          uint8_t rec[2] = {'P', static_cast<uint8_t>(p)};
          write_all(fd, rec, sizeof rec);
        },
        /*unload=*/false);
    st = r.status();
  } catch (...) {
    st = Error(Code::internal, quoted(path) + ": unexpected exception while probing");
  }
  std::string msg = st.message().substr(0, kMaxReport / 2);
  std::string hint = st.hint().substr(0, kMaxReport / 4);
  const auto code = static_cast<uint32_t>(st.code());
  const auto msg_len = static_cast<uint32_t>(msg.size());
  const auto hint_len = static_cast<uint32_t>(hint.size());
  std::string rec(1, 'R');
  rec.append(reinterpret_cast<const char*>(&code), 4);
  rec.append(reinterpret_cast<const char*>(&msg_len), 4);
  rec.append(reinterpret_cast<const char*>(&hint_len), 4);
  rec += msg;
  rec += hint;
  write_all(fd, rec.data(), rec.size());
  ::close(fd);
  ::_exit(0);  // no atexit handlers, no static destructors (ours or the plugin's)
}

struct Report {
  Phase phase = Phase::none;
  bool has_result = false;
  Status result;
};

Report parse_report(const std::string& buf) {
  Report r;
  size_t i = 0;
  while (i < buf.size()) {
    if (buf[i] == 'P' && i + 2 <= buf.size()) {
      r.phase = static_cast<Phase>(static_cast<uint8_t>(buf[i + 1]));
      i += 2;
    } else if (buf[i] == 'R' && i + 13 <= buf.size()) {
      uint32_t code = 0, msg_len = 0, hint_len = 0;
      std::memcpy(&code, buf.data() + i + 1, 4);
      std::memcpy(&msg_len, buf.data() + i + 5, 4);
      std::memcpy(&hint_len, buf.data() + i + 9, 4);
      i += 13;
      if (msg_len > buf.size() - i || hint_len > buf.size() - i - msg_len) break;
      if (code > static_cast<uint32_t>(Code::too_large)) break;
      r.has_result = true;
      if (code == 0) {
        r.result = Status::Ok();
      } else {
        r.result = Status(static_cast<Code>(code), buf.substr(i, msg_len),
                          buf.substr(i + msg_len, hint_len));
      }
      i += msg_len + hint_len;
    } else {
      break;  // truncated or garbled (the plugin wrote to our pipe?)
    }
  }
  return r;
}

}  // namespace

Status probe_in_child(const std::string& path, const FileInfo& file,
                      std::chrono::milliseconds timeout) {
  const std::string who = quoted(path);
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    return Error(Code::unavailable,
                 who + ": cannot create a pipe to probe it: " + std::strerror(errno));
  std::fflush(nullptr);  // or buffered output would be written twice
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int e = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    return Error(Code::unavailable, who + ": cannot fork to probe it: " + std::strerror(e) +
                                        ": free resources, or disable probing "
                                        "(LoadOptions::probe_in_child)");
  }
  if (pid == 0) {
    ::close(fds[0]);
    child_main(fds[1], path, file);
  }
  ::close(fds[1]);

  using clock = std::chrono::steady_clock;
  const auto deadline = clock::now() + timeout;
  auto ms_left = [&]() -> int {
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - clock::now());
    return left.count() <= 0 ? 0 : static_cast<int>(std::min<int64_t>(left.count(), 1 << 30));
  };
  std::string buf;
  bool timed_out = false;
  for (;;) {
    const int left = ms_left();
    if (left == 0) {
      timed_out = true;
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    const int pr = ::poll(&p, 1, left);
    if (pr < 0 && errno == EINTR) continue;
    if (pr < 0) break;
    if (pr == 0) {
      timed_out = true;
      break;
    }
    char tmp[4096];
    const ssize_t r = ::read(fds[0], tmp, sizeof tmp);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;  // EOF: the child exited (or closed our pipe)
    if (buf.size() < kMaxReport) buf.append(tmp, static_cast<size_t>(r));
  }
  ::close(fds[0]);

  // Reap the child; if it does not exit by the deadline, kill it.
  int wstatus = 0;
  bool reaped = false;
  for (;;) {
    const pid_t w = ::waitpid(pid, &wstatus, WNOHANG);
    if (w == pid) {
      reaped = true;
      break;
    }
    if (w < 0 && errno != EINTR) break;  // ECHILD: SIGCHLD ignored, auto-reaped
    if (timed_out || ms_left() == 0) {
      timed_out = true;
      ::kill(pid, SIGKILL);
      while (::waitpid(pid, &wstatus, 0) < 0 && errno == EINTR) {
      }
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }

  const Report rep = parse_report(buf);
  const std::string where = phase_text(rep.phase);
  if (timed_out)
    return Error(Code::timeout,
                 who + " did not finish loading within " + std::to_string(timeout.count()) +
                     " ms (stuck " + where +
                     "); the probe process was killed and the plugin "
                     "skipped: fix the hang, or raise the probe timeout if it is just slow");
  if (reaped && WIFSIGNALED(wstatus)) {
    const int sig = WTERMSIG(wstatus);
    const char* sname = signal_name(sig);
    return Error(Code::plugin_error,
                 who + " crashed while loading (signal " + std::to_string(sig) +
                     (sname ? std::string(", ") + sname : std::string()) + ") " + where +
                     "; it was skipped: run the plugin's tests or a debugger to find the crash");
  }
  if (rep.has_result) {
    if (reaped && WIFEXITED(wstatus) && WEXITSTATUS(wstatus) != 0 && rep.result.ok())
      return Error(Code::plugin_error, who + ": the probe process exited with status " +
                                           std::to_string(WEXITSTATUS(wstatus)));
    return rep.result;
  }
  if (reaped && WIFEXITED(wstatus))
    return Error(Code::plugin_error, who + " ended the process (exit status " +
                                         std::to_string(WEXITSTATUS(wstatus)) + ") " + where +
                                         " instead of returning; it was skipped");
  return Error(Code::internal, who + ": the probe process ended without a report " + where +
                                   " (is SIGCHLD ignored?)");
}

}  // namespace procam::host::detail
