// SPDX-License-Identifier: MIT
// Test helper (hw/aravis tests and tests/hardware): one arv-fake-gv-camera-0.8
// process on loopback, started and stopped by the test (killed with the test
// process if it crashes).
#pragma once

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "../../core/testing/child_process.hpp"

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
    std::vector<std::string> argv = {"arv-fake-gv-camera-0.8", "-i", "127.0.0.1", "-s", serial_};
    if (lost_per_thousand > 0) argv.insert(argv.end(), {"-r", std::to_string(lost_per_thousand)});
    child_ = ChildProcess::spawn(std::move(argv));
    std::this_thread::sleep_for(300ms);  // socket bind
  }
  void stop() { child_.stop(); }
  bool running() { return child_.running(); }

private:
  std::string serial_;
  int lock_fd_ = -1;
  ChildProcess child_;
};

inline bool have_fake_binary() { return std::system("command -v arv-fake-gv-camera-0.8 >/dev/null 2>&1") == 0; }

}  // namespace procam::testing
