// SPDX-License-Identifier: MIT
// Test helper: run a real procamd (or procam CLI) as a child process.
#pragma once

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../../hw/core/testing/child_process.hpp"  // fork/exec/stop/reap
#include "procam/client/client.hpp"

namespace procam::testing {
namespace fs = std::filesystem;

inline std::string bin(const std::string& name) { return std::string(PROCAM_BINARY_DIR) + "/bin/" + name; }
inline std::string source(const std::string& rel) { return std::string(PROCAM_SOURCE_DIR) + "/" + rel; }

// A fresh temporary folder removed at destruction.
struct TempDir {
  fs::path path;
  TempDir() {
    static std::atomic<int> n{0};
    path = fs::temp_directory_path() / ("procam-it-" + std::to_string(::getpid()) + "-" + std::to_string(n++));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

// Runs a command, captures stdout+stderr, returns the exit status (-1 on signal).
inline int run_command(const std::vector<std::string>& argv, std::string* output = nullptr) {
  int pipefd[2];
  if (pipe(pipefd) != 0) return -2;
  const pid_t pid = spawn_piped(argv, pipefd[1], pipefd[0]);
  close(pipefd[1]);
  std::string out;
  char buf[4096];
  ssize_t n;
  while ((n = read(pipefd[0], buf, sizeof buf)) > 0) out.append(buf, static_cast<size_t>(n));
  close(pipefd[0]);
  const int status = wait_child(pid);
  if (output) *output = out;
  return status;
}

class Daemon {
public:
  // Starts procamd with configs/procamd.json on a private ipc endpoint and
  // results folder; `extra` are more command-line arguments.
  explicit Daemon(const std::vector<std::string>& extra = {}) {
    static std::atomic<int> n{0};
    endpoint = "ipc://" + (dir.path / "procamd.sock").string();
    results = (dir.path / "results").string();
    log_path = (dir.path / "procamd.log").string();
    std::vector<std::string> argv = {bin("procamd"), "--config", source("configs/procamd.json"),
                                     "--endpoint", endpoint, "--results", results,
                                     "--plugins", PROCAM_PLUGIN_DIR};
    argv.insert(argv.end(), extra.begin(), extra.end());
    (void)n;
    start(argv);
  }
  ~Daemon() { stop(); }

  // True once the daemon answers `status`.
  bool wait_ready(std::chrono::seconds limit = std::chrono::seconds(30)) {
    auto until = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < until) {
      if (!alive()) return false;
      client::Client c(endpoint, std::chrono::milliseconds(500));
      if (c.call(proto::StatusQuery{}).ok()) return true;
    }
    return false;
  }
  bool alive() {
    if (pid <= 0) return false;
    if (auto ended = reap_if_exited(pid)) {
      exit_status = *ended;
      pid = -1;
      return false;
    }
    return true;
  }
  // SIGTERM and wait; returns the exit status (0 = clean).
  int stop() {
    if (pid > 0) {
      exit_status = stop_child(pid);
      pid = -1;
    }
    return exit_status;
  }
  std::string log() const {
    std::ifstream in(log_path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

  TempDir dir;
  std::string endpoint, results, log_path;
  pid_t pid = -1;
  int exit_status = -100;

private:
  void start(const std::vector<std::string>& argv) { pid = spawn_logged(argv, log_path); }
};

}  // namespace procam::testing
