// SPDX-License-Identifier: MIT
// Test support: a helper process (an emulator, an X server) started, watched and stopped by a test.
//
// The child runs argv (PATH lookup) with stdout/stderr on /dev/null and dies
// with the test process (PR_SET_PDEATHSIG SIGKILL), so a crashed test never
// leaves emulators behind. Owned by one thread; move-only; the destructor
// stops the child (SIGTERM, then reaps it). Errors: a failed fork gives a
// ChildProcess that is not running; a failed exec makes the child exit 127.
// Used by tests/hardware/x_server.hpp and hw/aravis/testing/gv_fake.hpp.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>
#include <utility>
#include <vector>

namespace procam::testing {

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
      std::vector<char*> a;
      for (auto& s : argv) a.push_back(s.data());
      a.push_back(nullptr);
      execvp(a[0], a.data());
      _exit(127);
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
    kill(pid_, sig);
    int st = 0;
    waitpid(pid_, &st, 0);
    pid_ = -1;
  }

private:
  pid_t pid_ = -1;
};

}  // namespace procam::testing
