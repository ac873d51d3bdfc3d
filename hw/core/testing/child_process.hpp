// SPDX-License-Identifier: MIT
// Test support: child processes (an emulator, an X server, procamd) started,
// watched, stopped and reaped by a test or a benchmark. Header-only, POSIX.
//
// Two forms over the same fork/exec code:
//   - free functions on a pid (spawn_logged, spawn_piped, wait_child,
//     stop_child, reap_if_exited) for callers that keep the pid themselves
//     (tests/integration/daemon_process.hpp, the service benchmark);
//   - ChildProcess, a move-only owner that stops its child on destruction and
//     makes it die with the test (PR_SET_PDEATHSIG), for emulators
//     (tests/hardware/x_server.hpp, hw/aravis/testing/gv_fake.hpp).
// Contract: call from the thread that owns the child; each pid is reaped
// exactly once. Between fork and exec the child only opens a file and calls
// dup2/prctl/exec. Exit codes: 127 from the child means exec failed; -1 means
// a signal ended it.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace procam::testing {

// The exit status in a waitpid() status: WEXITSTATUS, or -1 if a signal ended it.
inline int exit_code(int wstatus) { return WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1; }

namespace child_detail {
// In the child: exec argv or _exit(127). `search_path`: argv[0] is looked up
// on PATH (execvp), else it is a path (execv).
[[noreturn]] inline void exec_or_die(const std::vector<std::string>& argv, bool search_path = false) {
  std::vector<char*> args;
  for (auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  if (search_path) execvp(args[0], args.data());
  else execv(args[0], args.data());
  _exit(127);
}
}  // namespace child_detail

// Starts argv with stdout and stderr written to the file `log_path`
// (truncated; if it cannot be opened the child keeps ours). Returns the pid,
// or -1 if fork failed.
inline pid_t spawn_logged(const std::vector<std::string>& argv, const std::string& log_path) {
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* f = std::fopen(log_path.c_str(), "w");
    if (f) {
      dup2(fileno(f), 1);
      dup2(fileno(f), 2);
    }
    child_detail::exec_or_die(argv);
  }
  return pid;
}

// Starts argv with stdout and stderr going to the pipe end `write_fd`; the
// child closes both pipe ends after dup2 (`read_fd` is the parent's end).
// The parent must close write_fd itself. Returns the pid, or -1.
inline pid_t spawn_piped(const std::vector<std::string>& argv, int write_fd, int read_fd) {
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(write_fd, 1);
    dup2(write_fd, 2);
    close(read_fd);
    close(write_fd);
    child_detail::exec_or_die(argv);
  }
  return pid;
}

// Waits for the child to end; returns exit_code() of it (-2 if waitpid failed).
inline int wait_child(pid_t pid) {
  int st = 0;
  pid_t r;
  while ((r = waitpid(pid, &st, 0)) < 0 && errno == EINTR) {
  }
  return r == pid ? exit_code(st) : -2;
}

// Sends `sig` (SIGTERM: the daemon's clean shutdown) and waits; returns exit_code().
inline int stop_child(pid_t pid, int sig = SIGTERM) {
  kill(pid, sig);
  return wait_child(pid);
}

// The child's exit_code() if it has ended (it is reaped then), nullopt while it runs.
inline std::optional<int> reap_if_exited(pid_t pid) {
  int st = 0;
  if (waitpid(pid, &st, WNOHANG) == pid) return exit_code(st);
  return std::nullopt;
}

class ChildProcess {
public:
  ChildProcess() = default;
  // Starts `argv` (argv[0] looked up on PATH); not running if fork fails.
  static ChildProcess spawn(std::vector<std::string> argv) {
    ChildProcess c;
    c.pid_ = fork();
    if (c.pid_ == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);  // never outlive a crashed test
      int devnull = ::open("/dev/null", O_WRONLY);
      if (devnull >= 0) {
        dup2(devnull, 1);
        dup2(devnull, 2);
      }
      child_detail::exec_or_die(argv, /*search_path=*/true);
    }
    return c;
  }
  ChildProcess(ChildProcess&& o) noexcept : pid_(std::exchange(o.pid_, -1)) {}
  ChildProcess& operator=(ChildProcess&& o) noexcept {
    if (this != &o) {
      stop();
      pid_ = std::exchange(o.pid_, -1);
    }
    return *this;
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess() { stop(); }

  pid_t pid() const { return pid_; }
  // Whether the child still runs; an exited child is reaped and forgotten.
  bool running() {
    if (pid_ <= 0) return false;
    int st = 0;
    if (waitpid(pid_, &st, WNOHANG) == 0) return true;
    pid_ = -1;
    return false;
  }
  // Sends `sig` and waits for the child to end; no-op when none runs.
  void stop(int sig = SIGTERM) {
    if (pid_ <= 0) return;
    stop_child(pid_, sig);
    pid_ = -1;
  }

private:
  pid_t pid_ = -1;
};

}  // namespace procam::testing
