// SPDX-License-Identifier: MIT
// Test/benchmark helper: start a program as a child process (fork + execv),
// stop it with a signal and reap it. Header-only, POSIX.
//
// Contract: call from the parent's thread that owns the child; the pid is
// reaped exactly once (by stop_child, wait_child or reap_if_exited returning
// a value). The child runs only async-signal-safe-ish code before execv (it
// is used from single-threaded test mains and fixtures; a child of a
// multi-threaded process only opens its log file and calls dup2/execv).
// Exit codes: 127 from the child means execv failed; -1 means killed by a signal.
#pragma once

#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

namespace procam::testing {

// The exit status in a waitpid() status: WEXITSTATUS, or -1 if a signal ended it.
inline int exit_code(int wstatus) { return WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1; }

namespace child_detail {
// In the child: exec argv (argv[0] is a path) or _exit(127).
[[noreturn]] inline void exec_or_die(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  execv(args[0], args.data());
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

}  // namespace procam::testing
