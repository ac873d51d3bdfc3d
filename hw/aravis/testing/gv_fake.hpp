// SPDX-License-Identifier: MIT
// Test helper (hw/aravis tests and tests/hardware): one arv-fake-gv-camera-0.8
// process on loopback, started and stopped by the test (killed with the test
// process if it crashes).
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>

namespace procam::testing {

using namespace std::chrono_literals;

// One arv-fake-gv-camera-0.8 on 127.0.0.1 (the fake only binds addresses that
// an interface has, and two fakes on one address collide), so tests from any
// process serialise on a lock file.
class GvFake {
public:
  explicit GvFake(int lost_per_thousand = 0, const std::string& serial = "PROCAM-T1") : serial_(serial) {
    lock_fd_ = ::open("/tmp/procam-arv-fake-gv.lock", O_CREAT | O_RDWR, 0666);
    if (lock_fd_ >= 0) flock(lock_fd_, LOCK_EX);
    start(lost_per_thousand);
  }
  ~GvFake() {
    stop();
    if (lock_fd_ >= 0) {
      flock(lock_fd_, LOCK_UN);
      ::close(lock_fd_);
    }
  }
  void start(int lost_per_thousand) {
    pid_ = fork();
    if (pid_ == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);  // never outlive a crashed test
      int devnull = ::open("/dev/null", O_WRONLY);
      if (devnull >= 0) {
        dup2(devnull, 1);
        dup2(devnull, 2);
      }
      std::string r = std::to_string(lost_per_thousand);
      if (lost_per_thousand > 0)
        execlp("arv-fake-gv-camera-0.8", "arv-fake-gv-camera-0.8", "-i", "127.0.0.1", "-s", serial_.c_str(), "-r",
               r.c_str(), static_cast<char*>(nullptr));
      else
        execlp("arv-fake-gv-camera-0.8", "arv-fake-gv-camera-0.8", "-i", "127.0.0.1", "-s", serial_.c_str(),
               static_cast<char*>(nullptr));
      _exit(127);
    }
    std::this_thread::sleep_for(300ms);  // socket bind
  }
  void stop() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      int st = 0;
      waitpid(pid_, &st, 0);
      pid_ = -1;
    }
  }
  bool running() {
    if (pid_ <= 0) return false;
    int st = 0;
    return waitpid(pid_, &st, WNOHANG) == 0;
  }

private:
  std::string serial_;
  int lock_fd_ = -1;
  pid_t pid_ = -1;
};

inline bool have_fake_binary() { return std::system("command -v arv-fake-gv-camera-0.8 >/dev/null 2>&1") == 0; }

}  // namespace procam::testing
