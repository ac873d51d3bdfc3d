// SPDX-License-Identifier: MIT
// Least privilege of isolated sessions (README.md "Least privilege"): the
// "faults" fixture's try_* methods attempt each forbidden thing from inside
// the plugin and log what happened; each rule is checked in a worker, and
// against a control (sandbox off) to show the attempt itself works. Rules
// the running kernel cannot enforce (Landlock ABI, probed here, not taken
// from the code under test) are skipped, not passed.
#include <gtest/gtest.h>
#include <linux/landlock.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "procam/core/image.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::host {
namespace {
namespace fs = std::filesystem;

long landlock_abi() { return ::syscall(SYS_landlock_create_ruleset, nullptr, 0, LANDLOCK_CREATE_RULESET_VERSION); }

class SandboxTest : public ::testing::Test {
protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "procam-sandbox-test-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    tmp_ = tmpl;
    ASSERT_TRUE(host_.load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok());
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(tmp_, ec);
  }

  // Runs `method` (sandbox on or off); returns the plugin's log lines and,
  // while the worker lives, its /proc status.
  std::vector<std::string> run(const std::string& method, bool sandbox, std::string* proc_status = nullptr,
                               std::vector<std::string> readable = {}) {
    IsolationOptions iso;
    iso.sandbox = sandbox;
    iso.readable = std::move(readable);
    iso.scratch_parent = tmp_.string();
    host_.set_isolation(iso);
    std::vector<std::string> lines;
    auto s = host_.create_session("faults", method, "{}", "{}");
    EXPECT_TRUE(s.ok()) << s.status().to_string();
    if (!s) return lines;
    if (proc_status != nullptr) {
      std::ifstream in("/proc/" + std::to_string(s->worker_pid()) + "/status");
      *proc_status = std::string(std::istreambuf_iterator<char>(in), {});
    }
    s->set_log_handler([&](log::Level, const std::string& m) { lines.push_back(m); });
    Image frame(4, 3, PixelType::u8);
    EXPECT_TRUE(s->next_plan().ok());
    for (uint32_t i = 0; i < 3; ++i) EXPECT_TRUE(s->add_frame(i, frame.view()).ok());
    Status st = s->end_round();
    EXPECT_TRUE(st.ok()) << st.to_string();
    return lines;
  }

  static bool has(const std::vector<std::string>& lines, const std::string& prefix) {
    for (const auto& l : lines)
      if (l.rfind(prefix, 0) == 0) return true;
    return false;
  }

  fs::path tmp_;
  PluginHost host_;
};

TEST_F(SandboxTest, NoNetworkSockets) {
  const auto control = run("try_network", /*sandbox=*/false);
  ASSERT_TRUE(has(control, "udp: allowed")) << "the attempt itself does not work here";
  const auto lines = run("try_network", true);
  EXPECT_TRUE(has(lines, "udp: blocked (Permission denied)")) << ::testing::PrintToString(lines);
  EXPECT_TRUE(has(lines, "tcp: blocked (Permission denied)")) << ::testing::PrintToString(lines);
}

// A named Unix socket this test listens on: the control connects, the
// sandboxed worker cannot even create a socket (seccomp).
TEST_F(SandboxTest, NoConnectionsToNamedUnixSockets) {
  const fs::path path = tmp_ / "listening.sock";
  const int srv = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(srv, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
  ASSERT_EQ(::bind(srv, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(srv, 4), 0);
  ::setenv("PROCAM_TEST_UNIX", path.c_str(), 1);
  const auto control = run("try_unix", false);
  const auto lines = run("try_unix", true);
  ::unsetenv("PROCAM_TEST_UNIX");
  ::close(srv);
  ASSERT_TRUE(has(control, "unix: allowed")) << ::testing::PrintToString(control);
  EXPECT_TRUE(has(lines, "unix: blocked (Permission denied)")) << ::testing::PrintToString(lines);
}

// A file the daemon's user can read, outside the plugin's folder, the
// system folders and the scratch folder: readable in the control, not in
// the worker (Landlock, applied after the plugin is loaded); a system file
// stays readable.
TEST_F(SandboxTest, NoReadsOutsideThePluginSystemAndScratchFolders) {
  if (landlock_abi() < 1) GTEST_SKIP() << "kernel without Landlock: the read rule is not enforced here";
  const fs::path secret = tmp_ / "secret.txt";
  std::ofstream(secret) << "the daemon's secret\n";
  ::setenv("PROCAM_TEST_SECRET", secret.c_str(), 1);
  const auto control = run("try_read", false);
  const auto lines = run("try_read", true);
  ::unsetenv("PROCAM_TEST_SECRET");
  ASSERT_TRUE(has(control, "read_outside: allowed")) << ::testing::PrintToString(control);
  EXPECT_TRUE(has(lines, "read_outside: blocked (Permission denied)")) << ::testing::PrintToString(lines);
  EXPECT_TRUE(has(lines, "read_system: allowed")) << ::testing::PrintToString(lines);
  // A folder listed in IsolationOptions::readable (procamd.json plugins.readable).
  const fs::path data = tmp_ / "data";
  fs::create_directory(data);
  std::ofstream(data / "lut.txt") << "1 2 3\n";
  ::setenv("PROCAM_TEST_SECRET", (data / "lut.txt").c_str(), 1);
  const auto listed = run("try_read", true, nullptr, {data.string()});
  ::unsetenv("PROCAM_TEST_SECRET");
  EXPECT_TRUE(has(listed, "read_outside: allowed")) << ::testing::PrintToString(listed);
}

TEST_F(SandboxTest, NoNewFilesOutsideTheScratchFolder) {
  if (landlock_abi() < 1) GTEST_SKIP() << "kernel without Landlock: the file rule is not enforced here";
  const fs::path outside = tmp_ / "outside-file";
  ::setenv("PROCAM_TEST_OUTSIDE", outside.c_str(), 1);
  const auto control = run("try_write_outside", false);
  ASSERT_TRUE(has(control, "write_outside: allowed"));
  ASSERT_TRUE(fs::exists(outside));
  fs::remove(outside);
  const auto lines = run("try_write_outside", true);
  ::unsetenv("PROCAM_TEST_OUTSIDE");
  EXPECT_TRUE(has(lines, "write_outside: blocked (Permission denied)")) << ::testing::PrintToString(lines);
  EXPECT_FALSE(fs::exists(outside));
}

TEST_F(SandboxTest, ScratchFolderIsWritableAndRemovedAfterTheSession) {
  const auto lines = run("try_write_scratch", true);
  EXPECT_TRUE(has(lines, "write_scratch: allowed")) << ::testing::PrintToString(lines);
  for (const auto& e : fs::directory_iterator(tmp_))
    ADD_FAILURE() << "left behind: " << e.path();  // the worker's scratch folder is gone
}

TEST_F(SandboxTest, NoSignalsToProcessesOutsideTheWorker) {
  if (landlock_abi() < 6) GTEST_SKIP() << "Landlock ABI < 6: signal scoping is not enforced here";
  const auto control = run("try_signal", false);  // SIGCONT to this test process: harmless
  ASSERT_TRUE(has(control, "signal: allowed"));
  const auto lines = run("try_signal", true);
  EXPECT_TRUE(has(lines, "signal: blocked (Operation not permitted)")) << ::testing::PrintToString(lines);
}

// What freezing the worker after its outputs reply relies on (README.md
// "Speed"): no new processes (they would share the arena and not stop with
// the worker), nothing that makes the kernel send SIGCONT later, no process
// group change, no native AIO, no PTRACE_TRACEME, no removing written pages
// from shared memory; threads stay allowed.
TEST_F(SandboxTest, NothingThatCouldWriteOrResumeAFrozenWorker) {
  const auto control = run("try_freeze_escape", false);
  for (const char* rule : {"fork", "thread", "timer", "setsig", "pdeathsig", "setpgid", "aio", "punch_hole", "madv_remove"})
    ASSERT_TRUE(has(control, std::string(rule) + ": allowed")) << rule << ": " << ::testing::PrintToString(control);
  ::setenv("PROCAM_TEST_TRACEME", "1", 1);  // inherited by the worker; harmless there with the sandbox on
  const auto lines = run("try_freeze_escape", true);
  ::unsetenv("PROCAM_TEST_TRACEME");
  EXPECT_TRUE(has(lines, "thread: allowed")) << ::testing::PrintToString(lines);
  // Pages of shared memory stay once written (the daemon checks each page
  // of the shared heap once per worker: README.md "Speed").
  for (const char* rule : {"fork", "timer", "setsig", "pdeathsig", "setpgid", "traceme", "punch_hole", "madv_remove"})
    EXPECT_TRUE(has(lines, std::string(rule) + ": blocked (Operation not permitted)"))
        << rule << ": " << ::testing::PrintToString(lines);
  EXPECT_TRUE(has(lines, "aio: blocked (Function not implemented)")) << ::testing::PrintToString(lines);
}

TEST_F(SandboxTest, CapabilitiesDroppedNoNewPrivsSeccompOn) {
  std::string status;
  const auto lines = run("try_caps", true, &status);
  EXPECT_TRUE(has(lines, "caps: 0000000000000000")) << ::testing::PrintToString(lines);
  EXPECT_NE(status.find("NoNewPrivs:\t1"), std::string::npos) << status;
  EXPECT_NE(status.find("Seccomp:\t2"), std::string::npos) << status;  // filter mode
  EXPECT_NE(status.find("CapBnd:\t0000000000000000"), std::string::npos) << status;
}

}  // namespace
}  // namespace procam::host
