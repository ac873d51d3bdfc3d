// SPDX-License-Identifier: MIT
// Isolated sessions (README.md "Process model"): the "faults" fixture
// crashes, aborts, hangs, runs out of memory, writes garbage to the control
// socket and writes into its read-only frame, each in a worker process. Each
// fault fails that session with a Status naming the plugin, the call and the
// cause; this (test) process lives, leaves no child behind, and the next
// session, of a good plugin and of the same plugin, works.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "procam/core/image.hpp"
#include "procam/host/plugin_host.hpp"
#include "worker_wire.hpp"

namespace procam::host {
namespace {
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

bool contains(const std::string& hay, const std::string& needle) { return hay.find(needle) != std::string::npos; }

bool no_children() {
  int st = 0;
  return ::waitpid(-1, &st, WNOHANG) == -1 && errno == ECHILD;
}

class IsolationTest : public ::testing::Test {
protected:
  void SetUp() override {
    ASSERT_TRUE(host_.load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok());
    ASSERT_TRUE(host_.load_file(std::string(PROCAM_HOST_FIXTURE_DIR) + "/good.so").ok());
    IsolationOptions iso;  // mode process is the default
    iso.call_timeout = 1000ms;
    iso.per_frame_timeout = 200ms;
    iso.memory_limit_mb = 512;
    host_.set_isolation(iso);
  }

  // Runs one whole scan of 3 frames whose pixels are all `value`; returns
  // the first failure, or the outputs' frame_sum.
  // `after`: how each round ends (AfterRound::next_plan: the worker sends
  // the next plan and the outputs ahead, WORKER_PROTOCOL.md "Replies ahead").
  Result<double> scan(const std::string& plugin, const std::string& method, uint8_t value = 7,
                      Session::AfterRound after = Session::AfterRound::next_plan_or_stop) {
    auto s = host_.create_session(plugin, method, "{}", "{}");
    if (!s) return s.status();
    EXPECT_TRUE(s->isolated());
    Image frame(4, 3, PixelType::u8);
    for (size_t i = 0; i < 12; ++i) frame.ptr<uint8_t>()[i] = value;
    for (;;) {
      auto plan = s->next_plan();
      if (!plan) return plan.status();
      if (!plan->has_value()) break;
      for (uint32_t i = 0; i < (*plan)->frames.size(); ++i) PROCAM_TRY(s->add_frame(i, frame.view()));
      PROCAM_TRY(s->end_round(after));
    }
    auto outs = s->outputs();
    if (!outs) return outs.status();
    for (const Output& o : *outs)
      if (o.name == "frame_sum" || o.name == "frame_mean") return o.scalar;
    return Error(Code::internal, "no frame_sum output");
  }

  void expect_recovers() {
    auto good = scan("null", "null", 6);
    ASSERT_TRUE(good.ok()) << good.status().to_string();
    EXPECT_DOUBLE_EQ(*good, 6.0);  // null outputs the frame's mean
    auto same = scan("faults", "ok", 2);
    ASSERT_TRUE(same.ok()) << same.status().to_string();
    EXPECT_DOUBLE_EQ(*same, 3 * 12 * 2.0);
    EXPECT_TRUE(no_children());
  }

  PluginHost host_;
};

TEST_F(IsolationTest, WholeSessionMatchesTheInProcessResult) {
  auto iso = scan("faults", "ok", 5);
  ASSERT_TRUE(iso.ok()) << iso.status().to_string();
  EXPECT_DOUBLE_EQ(*iso, 3 * 12 * 5.0);  // 3 frames of 12 pixels of 5
  IsolationOptions in;
  in.mode = Isolation::in_process;
  host_.set_isolation(in);
  auto s = host_.create_session("faults", "ok", "{}", "{}");
  ASSERT_TRUE(s.ok());
  EXPECT_FALSE(s->isolated());
  EXPECT_TRUE(no_children());
}

TEST_F(IsolationTest, OutputsOfEveryKindCrossTheProcessBoundary) {
  auto s = host_.create_session("faults", "ok", "{}", "{}");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  ASSERT_TRUE(s->has_host_services());
  std::vector<std::string> lines;
  std::vector<double> progress;
  s->set_log_handler([&](log::Level, const std::string& m) { lines.push_back(m); });
  s->set_progress_handler([&](double f, const std::string&) { progress.push_back(f); });
  auto plan = s->next_plan();
  ASSERT_TRUE(plan.ok() && plan->has_value());
  const Plan& p = **plan;
  ASSERT_EQ(p.frames.size(), 3u);
  EXPECT_EQ(p.frames[1].label, "b");
  EXPECT_EQ(p.note, "three black frames");
  EXPECT_EQ(p.frames[0].pattern.width, 4u);
  EXPECT_EQ(static_cast<const uint8_t*>(p.frames[2].pattern.data)[11], 0);
  EXPECT_TRUE(std::isnan(p.frames[0].settings.polarizer_deg));
  Image frame(4, 3, PixelType::u8);
  for (size_t i = 0; i < 12; ++i) frame.ptr<uint8_t>()[i] = static_cast<uint8_t>(i);
  for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(s->add_frame(i, frame.view()).ok());
  ASSERT_TRUE(s->end_round().ok());
  EXPECT_EQ(lines, std::vector<std::string>{"decoded 3 frames"});
  EXPECT_EQ(progress, std::vector<double>{1.0});
  ASSERT_FALSE(s->next_plan()->has_value());
  auto outs = s->outputs();
  ASSERT_TRUE(outs.ok()) << outs.status().to_string();
  ASSERT_EQ(outs->size(), 4u);
  EXPECT_DOUBLE_EQ((*outs)[0].scalar, 3 * 66.0);  // 3 x (0 + 1 + ... + 11)
  const procam_image& img = (*outs)[1].image;
  ASSERT_EQ(img.width, 2u);
  const auto* px = static_cast<const float*>(img.data);
  EXPECT_EQ(px[0], 1.0f);
  EXPECT_EQ(px[2], 3.0f);
  EXPECT_TRUE(std::isnan(px[3]));
  EXPECT_EQ((*outs)[1].unit, "mm");
  ASSERT_EQ((*outs)[2].point_count, 2u);
  EXPECT_EQ((*outs)[2].points[7], 7.0f);
  EXPECT_EQ((*outs)[2].point_fields, "x,y,z,i");
  EXPECT_EQ((*outs)[3].json, "{\"frames\": 3}");
}

TEST_F(IsolationTest, PluginErrorsKeepTheirCodeAndMessage) {
  auto s = host_.create_session("faults", "no_such", "{}", "{}");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), Code::not_found);  // checked in the daemon
  auto bad_frame = host_.create_session("faults", "ok", "{}", "{}");
  ASSERT_TRUE(bad_frame.ok());
  ASSERT_TRUE(bad_frame->next_plan().ok());
  Image f32(4, 3, PixelType::f32);
  Status st = bad_frame->add_frame(0, f32.view());
  EXPECT_EQ(st.code(), Code::corrupt_data) << st.to_string();  // PROCAM_ERR_BAD_FRAME, as in-process
  EXPECT_TRUE(contains(st.message(), "expected 1-channel U8 or U16 frames")) << st.message();
  EXPECT_TRUE(bad_frame->add_frame(7, f32.view()).code() == Code::invalid_argument);
}

struct Fault {
  const char* method;
  const char* call;
  Code code;
  const char* cause;
  bool ahead = false;  // rounds end with AfterRound::next_plan
};

class FaultTest : public IsolationTest, public ::testing::WithParamInterface<Fault> {};

TEST_P(FaultTest, FailsTheScanNamingPluginCallAndCauseThenRecovers) {
  const Fault& f = GetParam();
  const auto t0 = Clock::now();
  auto r = scan("faults", f.method, 7,
                f.ahead ? Session::AfterRound::next_plan : Session::AfterRound::next_plan_or_stop);
  const auto took = Clock::now() - t0;
  ASSERT_FALSE(r.ok()) << f.method << " did not fail";
  const Status& st = r.status();
  EXPECT_EQ(st.code(), f.code) << st.to_string();
  EXPECT_TRUE(contains(st.message(), "plugin 'faults'")) << st.message();
  EXPECT_TRUE(contains(st.message(), f.call)) << st.message();
  EXPECT_TRUE(contains(st.message(), f.cause)) << st.message();
  EXPECT_LT(took, 10s);
  expect_recovers();
}

INSTANTIATE_TEST_SUITE_P(
    Faults, FaultTest,
    ::testing::Values(Fault{"segv", "in add_frame", Code::plugin_error, "killed by signal 11 (SIGSEGV)"},
                      Fault{"abort", "in end_round", Code::plugin_error, "killed by signal 6 (SIGABRT)"},
                      Fault{"hang", "in end_round", Code::timeout, "did not answer within 1600 ms"},
                      Fault{"oom", "end_round", Code::plugin_error, "address-space limit is 512 MiB"},
                      Fault{"garbage", "in end_round", Code::plugin_error, "garbage on the control channel"},
                      Fault{"write_frame", "in add_frame", Code::plugin_error, "SIGSEGV"},
                      Fault{"segv_outputs", "in get_outputs", Code::plugin_error, "killed by signal 11 (SIGSEGV)"},
                      // The worker went on unasked after end_round: each
                      // fault is still reported by the call it happened in.
                      Fault{"abort", "in end_round", Code::plugin_error, "killed by signal 6 (SIGABRT)", true},
                      Fault{"segv_outputs", "in get_outputs", Code::plugin_error, "killed by signal 11 (SIGSEGV)",
                            true}),
    [](const ::testing::TestParamInfo<Fault>& i) {
      return std::string(i.param.method) + (i.param.ahead ? "_ahead" : "");
    });

// Replies ahead (WORKER_PROTOCOL.md): with AfterRound::next_plan the worker
// sends the next plan, and after the last round the outputs, unasked. The
// results are those of the plain exchange, over one round and over two
// (where the plan sent ahead is a real round), and the plugin sees the same
// calls: its outputs count every frame of every round once.
TEST_F(IsolationTest, RepliesAheadGiveTheResultsOfThePlainExchange) {
  for (const auto after : {Session::AfterRound::next_plan_or_stop, Session::AfterRound::next_plan}) {
    SCOPED_TRACE(after == Session::AfterRound::next_plan ? "ahead" : "plain");
    auto one = scan("faults", "ok", 5, after);
    ASSERT_TRUE(one.ok()) << one.status().to_string();
    EXPECT_DOUBLE_EQ(*one, 3 * 12 * 5.0);
    auto two = scan("faults", "two_rounds", 5, after);
    ASSERT_TRUE(two.ok()) << two.status().to_string();
    EXPECT_DOUBLE_EQ(*two, 2 * 3 * 12 * 5.0);
    auto good = scan("null", "null", 6, after);
    ASSERT_TRUE(good.ok()) << good.status().to_string();
    EXPECT_DOUBLE_EQ(*good, 6.0);
  }
  EXPECT_TRUE(no_children());
}

// The promise is checked where the plugin runs in-process too, so a caller
// that breaks it finds out without isolation.
TEST_F(IsolationTest, StopAfterPromisingNextPlanIsRefused) {
  for (const auto mode : {Isolation::process, Isolation::in_process}) {
    IsolationOptions iso;
    iso.mode = mode;
    host_.set_isolation(iso);
    auto s = host_.create_session("faults", "two_rounds", "{}", "{}");
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    Image frame(4, 3, PixelType::u8);
    ASSERT_TRUE(s->next_plan().ok());
    for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(s->add_frame(i, frame.view()).ok());
    ASSERT_TRUE(s->end_round(Session::AfterRound::next_plan).ok());
    const Status st = s->stop();
    EXPECT_EQ(st.code(), Code::failed_precondition) << st.to_string();
    EXPECT_TRUE(contains(st.message(), "promised next_plan")) << st.message();
    // Keeping the promise still works: the second round, then the outputs.
    auto plan = s->next_plan();
    ASSERT_TRUE(plan.ok() && plan->has_value()) << plan.status().to_string();
    for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(s->add_frame(i, frame.view()).ok());
    ASSERT_TRUE(s->end_round().ok());
    ASSERT_TRUE(s->stop().ok());  // no promise this time: the host may stop
    auto outs = s->outputs();
    ASSERT_TRUE(outs.ok()) << outs.status().to_string();
  }
}

TEST_F(IsolationTest, HangDeadlineScalesWithTheRoundsFrames) {
  // end_round of 3 frames: 1000 ms + 3 x 200 ms; killed soon after, not before.
  const auto t0 = Clock::now();
  auto r = scan("faults", "hang");
  const auto took = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - t0);
  ASSERT_EQ(r.status().code(), Code::timeout);
  EXPECT_GE(took, 1600ms);
  EXPECT_LT(took, 5000ms);
}

TEST_F(IsolationTest, OutOfMemoryIsTheWorkersNotOurs) {
  auto r = scan("faults", "oom");
  ASSERT_FALSE(r.ok());
  // The plugin's own report survives (it saw malloc fail at the limit).
  EXPECT_TRUE(contains(r.status().message(), "PROCAM_ERR_NO_MEMORY")) << r.status().message();
  EXPECT_TRUE(contains(r.status().message(), "out of memory after")) << r.status().message();
}

TEST_F(IsolationTest, CallsAfterAFaultFailWithoutTouchingTheWorker) {
  auto s = host_.create_session("faults", "abort", "{}", "{}");
  ASSERT_TRUE(s.ok());
  Image frame(4, 3, PixelType::u8);
  ASSERT_TRUE(s->next_plan().ok());
  for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(s->add_frame(i, frame.view()).ok());
  ASSERT_FALSE(s->end_round().ok());
  auto again = s->next_plan();
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.status().code(), Code::failed_precondition);
  EXPECT_TRUE(contains(again.status().message(), "worker is gone")) << again.status().message();
  EXPECT_TRUE(no_children());
}

TEST_F(IsolationTest, MissingWorkerIsReportedWithAHint) {
  IsolationOptions iso;
  iso.worker_path = "/nonexistent/procam-plugin-worker";
  host_.set_isolation(iso);
  auto s = host_.create_session("null", "null", "{}", "{}");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), Code::not_found);
  EXPECT_TRUE(contains(s.status().hint(), "in_process")) << s.status().hint();
}

// A worker from another build (here a script saying hello with protocol
// version 99) is refused with an error that says so, not "garbage".
TEST_F(IsolationTest, WorkerOfAnotherProtocolVersionIsRefusedClearly) {
  char dir[] = "/tmp/procam-isolation-XXXXXX";
  ASSERT_NE(::mkdtemp(dir), nullptr);
  const std::string script = std::string(dir) + "/procam-plugin-worker";
  {
    std::FILE* f = std::fopen(script.c_str(), "w");
    ASSERT_NE(f, nullptr);
    // One 16-byte packet on fd 3: magic "PCWK", version 99, type 64 (hello), seq 0, length 0.
    std::fputs("#!/bin/sh\nprintf '\\120\\103\\127\\113\\143\\000\\100\\000\\000\\000\\000\\000"
               "\\000\\000\\000\\000' >&3\nsleep 5\n", f);
    std::fclose(f);
  }
  ASSERT_EQ(::chmod(script.c_str(), 0700), 0);
  IsolationOptions iso;
  iso.worker_path = script;
  iso.start_timeout = 3000ms;
  host_.set_isolation(iso);
  auto s = host_.create_session("null", "null", "{}", "{}");
  std::remove(script.c_str());
  ::rmdir(dir);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), Code::plugin_error) << s.status().to_string();
  EXPECT_TRUE(contains(s.status().message(), "protocol version 99, expected " + std::to_string(wire::kVersion)))
      << s.status().message();
  EXPECT_TRUE(contains(s.status().message(), "from another build")) << s.status().message();
  EXPECT_TRUE(no_children());
}

TEST_F(IsolationTest, TrustedPluginsRunInProcess) {
  IsolationOptions iso;
  iso.trusted = {"null"};
  host_.set_isolation(iso);
  EXPECT_FALSE(host_.runs_isolated("null"));
  EXPECT_TRUE(host_.runs_isolated("faults"));
  auto s = host_.create_session("null", "null", "{}", "{}");
  ASSERT_TRUE(s.ok());
  EXPECT_FALSE(s->isolated());
  EXPECT_EQ(s->worker_pid(), -1);
}

TEST_F(IsolationTest, DestroyingASessionEndsItsWorker) {
  int pid = -1;
  {
    auto s = host_.create_session("faults", "ok", "{}", "{}");
    ASSERT_TRUE(s.ok());
    pid = s->worker_pid();
    ASSERT_GT(pid, 0);
    EXPECT_EQ(::kill(pid, 0), 0);
  }
  EXPECT_TRUE(no_children());
  EXPECT_NE(::kill(pid, 0), 0);
}

}  // namespace
}  // namespace procam::host

namespace procam::host {
namespace {

TEST(IsolationPrestart, SessionsUseTheSpareWorkerAndNothingLeaksWhenItGoes) {
  {
    PluginHost host;
    ASSERT_TRUE(host.load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok());
    IsolationOptions iso;
    iso.prestart = true;
    host.set_isolation(iso);  // starts the first spare
    std::vector<int> pids;
    for (int i = 0; i < 3; ++i) {
      auto s = host.create_session("faults", "ok", "{}", "{}");
      ASSERT_TRUE(s.ok()) << s.status().to_string();
      pids.push_back(s->worker_pid());
      Image frame(4, 3, PixelType::u8);
      ASSERT_TRUE(s->next_plan().ok());
      for (uint32_t f = 0; f < 3; ++f) ASSERT_TRUE(s->add_frame(f, frame.view()).ok());
      ASSERT_TRUE(s->end_round().ok());
    }
    EXPECT_NE(pids[0], pids[1]);  // a fresh process per session, spare or not
    EXPECT_NE(pids[1], pids[2]);
    EXPECT_FALSE(no_children());  // the next spare waits
  }
  EXPECT_TRUE(no_children());  // ...and goes with its PluginHost
}

}  // namespace
}  // namespace procam::host
