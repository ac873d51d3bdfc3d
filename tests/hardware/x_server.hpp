// SPDX-License-Identifier: MIT
// Test helper: a private Xvfb (one screen) or Xorg-dummy (two monitors) X
// server on a free display number, started and stopped by the test, killed
// with the test process if it crashes. Sets DISPLAY while it runs.
#pragma once

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "../../hw/core/testing/child_process.hpp"

namespace procam::testing {

class XServer {
public:
  // Xvfb with one screen of `size` ("1280x800").
  static XServer xvfb(const std::string& size = "1280x800") {
    XServer x;
    x.start([&](const std::string& disp) {
      return std::vector<std::string>{"Xvfb", disp, "-screen", "0", size + "x24", "-nolisten", "tcp"};
    });
    return x;
  }
  // Xorg with the dummy driver and two monitors side by side: DUMMY0
  // 1280x800 at +0+0 and DUMMY1 1024x768 at +1280+0 (set up with xrandr).
  // Needs root (Xorg) and xserver-xorg-video-dummy; !ok() otherwise.
  static XServer xorg_dummy_two_monitors(const std::string& workdir) {
    const std::string conf = workdir + "/xorg-dummy.conf";
    {
      FILE* f = std::fopen(conf.c_str(), "w");
      if (!f) return XServer();
      std::fputs("Section \"Device\"\n  Identifier \"dummy\"\n  Driver \"dummy\"\n  VideoRam 256000\nEndSection\n"
                 "Section \"Monitor\"\n  Identifier \"mon\"\n  HorizSync 5.0-1000.0\n  VertRefresh 5.0-200.0\nEndSection\n"
                 "Section \"Screen\"\n  Identifier \"screen\"\n  Device \"dummy\"\n  Monitor \"mon\"\n  DefaultDepth 24\n"
                 "  SubSection \"Display\"\n    Depth 24\n    Virtual 2560 1024\n  EndSubSection\nEndSection\n", f);
      std::fclose(f);
    }
    XServer x;
    const std::string log = workdir + "/xorg.log";
    x.start([&](const std::string& disp) {
      return std::vector<std::string>{"Xorg", disp, "-config", conf, "-noreset", "-nolisten", "tcp", "-logfile", log};
    });
    if (!x.ok()) return x;
    const std::string d = "DISPLAY=" + x.display() + " ";
    const bool ok =
        std::system((d + "xrandr --newmode procam1024 63.50 1024 1072 1176 1328 768 771 775 798 -hsync +vsync").c_str()) == 0 &&
        std::system((d + "xrandr --addmode DUMMY1 procam1024").c_str()) == 0 &&
        std::system((d + "xrandr --output DUMMY0 --mode 1280x800 --pos 0x0 --output DUMMY1 --mode procam1024 --pos 1280x0").c_str()) == 0 &&
        std::system((d + "xrandr --query >/dev/null").c_str()) == 0;  // full probe: refreshes the cached connection state
    if (!ok) x.stop();
    return x;
  }
  XServer() = default;
  XServer(XServer&& o) noexcept
      : child_(std::move(o.child_)), display_(std::move(o.display_)), old_display_(std::move(o.old_display_)) {}
  XServer& operator=(XServer&&) = delete;
  ~XServer() { stop(); }

  bool ok() const { return child_.pid() > 0; }
  const std::string& display() const { return display_; }
  void stop() {
    if (child_.pid() > 0) {
      child_.stop();
      if (old_display_.empty()) unsetenv("DISPLAY");
      else setenv("DISPLAY", old_display_.c_str(), 1);
    }
  }

  template <typename ArgsFn>
  void start(ArgsFn args_for) {
    if (const char* d = std::getenv("DISPLAY")) old_display_ = d;
    // A display number unlikely to collide with parallel test processes.
    for (int attempt = 0; attempt < 20 && child_.pid() <= 0; ++attempt) {
      const int n = 300 + static_cast<int>((getpid() * 7 + attempt * 13) % 600);
      const std::string lock = "/tmp/.X" + std::to_string(n) + "-lock";
      struct stat sb{};
      if (stat(lock.c_str(), &sb) == 0) continue;
      const std::string disp = ":" + std::to_string(n);
      ChildProcess child = ChildProcess::spawn(args_for(disp));
      // Ready when the server has written its lock file and still runs.
      const std::string sock = "/tmp/.X11-unix/X" + std::to_string(n);
      bool up = false;
      for (int i = 0; i < 100 && !up; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        if (!child.running()) break;  // exited: display taken or failed
        up = stat(lock.c_str(), &sb) == 0;
      }
      if (up) {
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
        child_ = std::move(child);
        display_ = disp;
        setenv("DISPLAY", disp.c_str(), 1);
      } else {
        child.stop(SIGKILL);
      }
    }
  }

private:
  ChildProcess child_;
  std::string display_, old_display_;
};

}  // namespace procam::testing
