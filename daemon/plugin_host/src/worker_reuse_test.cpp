// SPDX-License-Identifier: MIT
// Worker reuse (README.md "Worker reuse", IsolationOptions::max_idle_workers):
// a worker whose session ended cleanly serves the next session of the same
// plugin (same pid); one that faulted, got an error from the plugin or was
// left mid-scan never does; the idle limits (count, timeout, sessions per
// worker) hold; the scratch folder is emptied between scans and removed with
// the worker. Ground truth is the kernel's: pids, whether a pid still exists,
// the scratch folder's entries.
#include <gtest/gtest.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <filesystem>
#include <thread>
#include <vector>

#include "procam/core/image.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::host {
namespace {
namespace fs = std::filesystem;
using namespace std::chrono_literals;

// True while `pid` is a process (a reaped worker is not; a zombie would be,
// but the proxy reaps before it returns).
bool alive(int pid) { return pid > 0 && (::kill(pid, 0) == 0 || errno == EPERM); }

class WorkerReuseTest : public ::testing::Test {
protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "procam-reuse-test-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    tmp_ = tmpl;
    ASSERT_TRUE(host_.load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok());
    ASSERT_TRUE(host_.load_file(std::string(PROCAM_HOST_FIXTURE_DIR) + "/good.so").ok());
    iso_.call_timeout = 2000ms;
    iso_.per_frame_timeout = 200ms;
    iso_.memory_limit_mb = 512;
    iso_.scratch_parent = tmp_.string();
    iso_.max_idle_workers = 1;
    iso_.idle_timeout = 60s;
    iso_.max_sessions_per_worker = 100;
    host_.set_isolation(iso_);
  }
  void TearDown() override {
    host_.set_isolation(IsolationOptions{});  // idle workers go (and their scratch folders)
    std::error_code ec;
    fs::remove_all(tmp_, ec);
  }

  // One scan of `method` (3 frames); finish=false leaves it after the first
  // frame. Returns the worker's pid, or -1 when any call failed.
  int scan(const std::string& plugin, const std::string& method, bool finish = true) {
    auto s = host_.create_session(plugin, method, "{}", "{}");
    if (!s) return -1;
    const int pid = s->worker_pid();
    Image frame(4, 3, PixelType::u8);
    for (;;) {
      auto plan = s->next_plan();
      if (!plan) return -1;
      if (!plan->has_value()) break;
      for (uint32_t i = 0; i < (*plan)->frames.size(); ++i) {
        if (!s->add_frame(i, frame.view())) return -1;
        if (!finish) return pid;
      }
      if (!s->end_round()) return -1;
    }
    return s->outputs().ok() ? pid : -1;
  }

  std::vector<fs::path> scratch_folders() const {
    std::vector<fs::path> out;
    for (const auto& e : fs::directory_iterator(tmp_)) out.push_back(e.path());
    return out;
  }

  fs::path tmp_;
  IsolationOptions iso_;
  PluginHost host_;
};

TEST_F(WorkerReuseTest, CleanSessionsOfOnePluginShareAWorker) {
  const int a = scan("faults", "ok");
  ASSERT_GT(a, 0);
  EXPECT_TRUE(alive(a)) << "the worker waits, idle, for the next session";
  EXPECT_EQ(scan("faults", "ok"), a);
  EXPECT_EQ(scan("faults", "ok"), a);
  // Another plugin gets its own worker; the faults worker stays idle.
  const int b = scan("null", "null");
  ASSERT_GT(b, 0);
  EXPECT_NE(b, a);
  EXPECT_TRUE(alive(a));
  EXPECT_EQ(scan("null", "null"), b);
}

// Replies ahead (WORKER_PROTOCOL.md) on a reused worker: the sequence
// numbers stay in step across sessions, and a session that ends without
// asking for the outputs the worker already sent (its caller dropped the
// scan) leaves a worker that serves the next one. That first outputs reply
// also carried the worker's new output arena: the next session's outputs
// are read from it, so they are right only if the dropped reply's arena was
// kept.
TEST_F(WorkerReuseTest, RepliesAheadKeepAReusedWorkerInStep) {
  const auto run = [&](bool fetch_outputs, double* sum) {
    auto s = host_.create_session("faults", "ok", "{}", "{}");
    if (!s) return -1;
    Image frame(4, 3, PixelType::u8);
    for (size_t i = 0; i < 12; ++i) frame.ptr<uint8_t>()[i] = 3;
    auto plan = s->next_plan();
    if (!plan || !plan->has_value()) return -1;
    for (uint32_t i = 0; i < 3; ++i)
      if (!s->add_frame(i, frame.view())) return -1;
    if (!s->end_round(Session::AfterRound::next_plan)) return -1;
    auto none = s->next_plan();
    if (!none || none->has_value()) return -1;
    if (fetch_outputs) {
      auto outs = s->outputs();
      if (!outs || outs->empty()) return -1;
      *sum = outs->front().scalar;
    }
    return s->worker_pid();
  };
  double sum = 0;
  const int a = run(/*fetch_outputs=*/false, &sum);
  ASSERT_GT(a, 0);
  EXPECT_TRUE(alive(a));
  EXPECT_EQ(run(true, &sum), a);
  EXPECT_DOUBLE_EQ(sum, 3 * 12 * 3.0);
  sum = 0;
  EXPECT_EQ(run(true, &sum), a);
  EXPECT_DOUBLE_EQ(sum, 3 * 12 * 3.0);
  EXPECT_EQ(scan("faults", "ok"), a);  // and the plain exchange after them
}

TEST_F(WorkerReuseTest, ReuseOffGivesAFreshWorkerPerSession) {
  iso_.max_idle_workers = 0;
  host_.set_isolation(iso_);
  const int a = scan("faults", "ok");
  ASSERT_GT(a, 0);
  EXPECT_FALSE(alive(a));
  const int b = scan("faults", "ok");
  EXPECT_GT(b, 0);
  EXPECT_NE(b, a);
}

TEST_F(WorkerReuseTest, AFaultedOrRefusingWorkerIsNeverReused) {
  // A crash mid-round, a hang, garbage, an error from the plugin (its
  // PROCAM_ERR_NO_MEMORY), a scan abandoned mid-round: each time the worker
  // that served it (the idle one, taken for the scan) is gone afterwards,
  // and the next clean scan gets a new one.
  for (const char* method : {"segv", "abort", "garbage", "oom", "write_frame", "abandon"}) {
    SCOPED_TRACE(method);
    const int warm = scan("faults", "ok");
    ASSERT_GT(warm, 0);
    ASSERT_TRUE(alive(warm));
    const bool abandon = std::string(method) == "abandon";
    EXPECT_EQ(scan("faults", abandon ? "ok" : method, /*finish=*/!abandon), abandon ? warm : -1);
    EXPECT_FALSE(alive(warm)) << "the worker of the failed scan was killed and reaped";
    const int next = scan("faults", "ok");
    EXPECT_GT(next, 0);
    EXPECT_NE(next, warm);
  }
}

TEST_F(WorkerReuseTest, AtMostMaxIdleWorkersPerPlugin) {
  // Two sessions of one plugin at once: two workers; when both end, one stays.
  auto s1 = host_.create_session("faults", "ok", "{}", "{}");
  auto s2 = host_.create_session("faults", "ok", "{}", "{}");
  ASSERT_TRUE(s1.ok() && s2.ok());
  const int p1 = s1->worker_pid(), p2 = s2->worker_pid();
  ASSERT_NE(p1, p2);
  Image frame(4, 3, PixelType::u8);
  for (auto* s : {&*s1, &*s2}) {
    ASSERT_TRUE(s->next_plan().ok());
    for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(s->add_frame(i, frame.view()).ok());
    ASSERT_TRUE(s->end_round().ok());
    auto none = s->next_plan();
    ASSERT_TRUE(none.ok() && !none->has_value());
  }
  *s1 = std::move(*s2);  // s1's session ends (its worker goes idle), then s2's moves in
  EXPECT_TRUE(alive(p1));
  { auto gone = std::move(*s1); }  // the second worker ends: the pool is full
  EXPECT_TRUE(alive(p1));
  EXPECT_FALSE(alive(p2));
  EXPECT_EQ(scan("faults", "ok"), p1);
}

TEST_F(WorkerReuseTest, IdleTimeoutEndsTheWorker) {
  iso_.idle_timeout = 100ms;
  host_.set_isolation(iso_);
  const int a = scan("faults", "ok");
  ASSERT_GT(a, 0);
  EXPECT_TRUE(alive(a));
  // The reaper ends it with no further session: an idle daemon keeps none.
  for (int i = 0; i < 100 && alive(a); ++i) std::this_thread::sleep_for(20ms);
  EXPECT_FALSE(alive(a)) << "still there 2 s after its 100 ms idle timeout";
  EXPECT_TRUE(scratch_folders().empty()) << "its scratch folder goes with it";
  const int b = scan("faults", "ok");
  EXPECT_GT(b, 0);
  EXPECT_NE(b, a);
}

TEST_F(WorkerReuseTest, AtMostMaxSessionsPerWorker) {
  iso_.max_sessions_per_worker = 2;
  host_.set_isolation(iso_);
  const int a = scan("faults", "ok");
  ASSERT_GT(a, 0);
  EXPECT_EQ(scan("faults", "ok"), a);
  EXPECT_FALSE(alive(a)) << "two sessions served: not kept";
  const int c = scan("faults", "ok");
  EXPECT_GT(c, 0);
  EXPECT_NE(c, a);
}

TEST_F(WorkerReuseTest, ScratchFolderIsEmptiedBetweenScansAndRemovedWithTheWorker) {
  const int a = scan("faults", "try_write_scratch");  // creates $TMPDIR/plugin-file
  ASSERT_GT(a, 0);
  auto folders = scratch_folders();
  ASSERT_EQ(folders.size(), 1u);
  EXPECT_TRUE(fs::is_empty(folders[0])) << "plugin-file leaked into the next scan's scratch folder";
  EXPECT_EQ(scan("faults", "try_write_scratch"), a);
  EXPECT_EQ(scratch_folders(), folders) << "the same folder, emptied again";
  EXPECT_TRUE(fs::is_empty(folders[0]));
  host_.set_isolation(iso_);  // the idle worker goes, with its folder
  EXPECT_FALSE(alive(a));
  EXPECT_TRUE(scratch_folders().empty());
}

TEST_F(WorkerReuseTest, AWorkerThatDiedWhileIdleIsReplaced) {
  const int a = scan("faults", "ok");
  ASSERT_GT(a, 0);
  ASSERT_EQ(::kill(a, SIGKILL), 0);
  const int b = scan("faults", "ok");
  EXPECT_GT(b, 0);
  EXPECT_NE(b, a);
}

}  // namespace
}  // namespace procam::host
