// SPDX-License-Identifier: MIT
// Tests for the plugin log/progress host services (host_services.hpp) and for
// ABI 1 compatibility: a plugin with the first (shorter) ABI 1 function table
// still loads and runs; a plugin that logs and reports progress has its
// messages arrive sanitised, rate-limited and only from the calling thread.
#include "host_services.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "procam/core/image.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::host {
namespace {

std::string fixture(const std::string& name) {
  return std::string(PROCAM_HOST_FIXTURE_DIR) + "/" + name + ".so";
}

// One round of a good.c-derived plugin: a 4x3 frame of `value`; returns
// the "frame_mean" output (the plugin's mean of the frame) or NaN.
double run_one_round(Session& s, uint8_t value, std::chrono::nanoseconds* end_round_time = nullptr) {
  auto plan = s.next_plan();
  EXPECT_TRUE(plan.ok() && plan->has_value()) << plan.status().to_string();
  if (!plan.ok() || !plan->has_value()) return NAN;
  Image frame(4, 3, PixelType::u8);
  std::memset(frame.data(), value, frame.size_bytes());
  EXPECT_TRUE(s.add_frame(0, frame.view()).ok());
  const auto t0 = std::chrono::steady_clock::now();
  Status st = s.end_round();
  if (end_round_time) *end_round_time = std::chrono::steady_clock::now() - t0;
  EXPECT_TRUE(st.ok()) << st.to_string();
  auto done = s.next_plan();
  EXPECT_TRUE(done.ok() && !done->has_value());
  auto outs = s.outputs();
  EXPECT_TRUE(outs.ok()) << outs.status().to_string();
  if (!outs.ok()) return NAN;
  for (const auto& o : *outs)
    if (o.name == "frame_mean") return o.scalar;
  return NAN;
}

TEST(HostServicesAbi, V1TableIsTheFirstAbi1Layout) {
  // The first ABI 1 table: two uint32 then seven function pointers.
  EXPECT_EQ(PROCAM_PLUGIN_VTABLE_V1_SIZE, 2 * sizeof(uint32_t) + 7 * sizeof(void (*)(void)));
  EXPECT_GT(sizeof(procam_plugin_vtable), PROCAM_PLUGIN_VTABLE_V1_SIZE);
}

int fake_set_host(procam_session*, const procam_host_services*, procam_error*) { return 0; }

TEST(HostServicesAbi, SetHostIsReadOnlyWhenStructSizeCoversIt) {
  procam_plugin_vtable vt{};
  vt.session_set_host = &fake_set_host;
  vt.struct_size = static_cast<uint32_t>(PROCAM_PLUGIN_VTABLE_V1_SIZE);
  EXPECT_EQ(detail::set_host_of(vt), nullptr);
  vt.struct_size = sizeof(procam_plugin_vtable);
  EXPECT_EQ(detail::set_host_of(vt), &fake_set_host);
  vt.session_set_host = nullptr;
  EXPECT_EQ(detail::set_host_of(vt), nullptr);
}

TEST(HostServicesAbi, PluginWithTheV1TableLoadsAndRuns) {
  for (bool probe : {true, false}) {
    PluginHost host(LoadOptions{.probe_in_child = probe, .probe_timeout = std::chrono::seconds(5)});
    Status st = host.load_file(fixture("v1_table"));
    ASSERT_TRUE(st.ok()) << st.to_string();
    auto s = host.create_session("v1_table", "null", "{}", "{}");
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    // The host must not look past the v1 table (the fixture puts a trap there).
    EXPECT_FALSE(s->has_host_services());
    s->set_log_handler([](log::Level, const std::string&) { ADD_FAILURE() << "no log expected"; });
    EXPECT_DOUBLE_EQ(run_one_round(*s, 9), 9.0);
  }
}

TEST(HostServices, LogAndProgressArriveSanitisedAndRateLimited) {
  PluginHost host;
  ASSERT_TRUE(host.load_file(fixture("host_services")).ok());
  auto s = host.create_session("host_services", "null", "{}", "{}");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  ASSERT_TRUE(s->has_host_services());
  std::vector<std::pair<log::Level, std::string>> logs;
  std::vector<std::pair<double, std::string>> progress;
  s->set_log_handler([&](log::Level l, const std::string& m) { logs.emplace_back(l, m); });
  s->set_progress_handler([&](double f, const std::string& st) { progress.emplace_back(f, st); });
  std::chrono::nanoseconds took{};
  EXPECT_DOUBLE_EQ(run_one_round(*s, 5, &took), 5.0);

  // Logs: the worker thread's and session_set_host's are dropped.
  ASSERT_EQ(logs.size(), 4u);
  EXPECT_EQ(logs[0], std::make_pair(log::Level::info, std::string("decoding 1 frame")));
  EXPECT_EQ(logs[1], std::make_pair(log::Level::warn, std::string("line1\\x0aline2\\x01end")));
  EXPECT_EQ(logs[2].first, log::Level::debug);
  EXPECT_EQ(logs[2].second, std::string(1024, 'x') + "...");  // 3000 bytes cut at 1 KiB
  EXPECT_EQ(logs[3], std::make_pair(log::Level::info, std::string("unknown level")));

  // Progress: 1001 "unwrap" reports 0..1 then (2.0, "clamp"); NaN dropped.
  ASSERT_GE(progress.size(), 3u);
  EXPECT_EQ(progress.front(), std::make_pair(0.0, std::string("unwrap")));
  EXPECT_EQ(progress[progress.size() - 2], std::make_pair(1.0, std::string("unwrap")));
  EXPECT_EQ(progress.back(), std::make_pair(1.0, std::string("clamp")));
  for (size_t i = 1; i + 1 < progress.size(); ++i) {
    EXPECT_EQ(progress[i].second, "unwrap");
    EXPECT_GE(progress[i].first, progress[i - 1].first);
  }
  // At most one report per 50 ms besides the first, fraction 1 and the new stage.
  const auto intervals = static_cast<size_t>(took / detail::kProgressInterval);
  EXPECT_LE(progress.size(), 3 + intervals) << "end_round took " << took.count() << " ns";
}

TEST(HostServices, PluginRunsWithoutHandlers) {
  PluginHost host(LoadOptions{.probe_in_child = false});
  ASSERT_TRUE(host.load_file(fixture("host_services")).ok());
  auto s = host.create_session("host_services", "null", "{}", "{}");
  ASSERT_TRUE(s.ok());
  Session moved = std::move(*s);  // the table's ctx must survive a move
  std::vector<std::string> logs;
  moved.set_log_handler([&](log::Level, const std::string& m) { logs.push_back(m); });
  EXPECT_DOUBLE_EQ(run_one_round(moved, 200), 200.0);
  EXPECT_EQ(logs.size(), 4u);
}

TEST(HostServices, SdkPluginMarshalsWorkerThreadMessages) {
  PluginHost host;
  Status loaded = host.load_file(fixture("sdk_host_services"));
  ASSERT_TRUE(loaded.ok()) << loaded.to_string();
  auto s = host.create_session("sdk_host_services", "null", "{}", "{}");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  ASSERT_TRUE(s->has_host_services());
  std::vector<std::pair<log::Level, std::string>> logs;
  std::vector<std::pair<double, std::string>> progress;
  std::vector<std::thread::id> threads;  // where each callback ran
  s->set_log_handler([&](log::Level l, const std::string& m) {
    logs.emplace_back(l, m);
    threads.push_back(std::this_thread::get_id());
  });
  s->set_progress_handler([&](double f, const std::string& st) {
    progress.emplace_back(f, st);
    threads.push_back(std::this_thread::get_id());
  });
  auto plan = s->next_plan();
  ASSERT_TRUE(plan.ok() && plan->has_value());
  Image frame(4, 3, PixelType::u8);
  std::memset(frame.data(), 0, frame.size_bytes());
  ASSERT_TRUE(s->add_frame(0, frame.view()).ok());
  ASSERT_TRUE(s->end_round().ok());
  // Everything arrived, in the order the SDK delivers it: the worker's lines
  // are queued and flushed on the calling thread before the next direct call.
  const std::vector<std::pair<log::Level, std::string>> want_logs = {
      {log::Level::info, "frame added"},
      {log::Level::warn, "from the worker"},
      {log::Level::info, "round decoded"}};
  EXPECT_EQ(logs, want_logs);
  const std::vector<std::pair<double, std::string>> want_progress = {{0.25, "calling thread"},
                                                                     {0.75, "worker"}};
  EXPECT_EQ(progress, want_progress);
  for (const auto& t : threads) EXPECT_EQ(t, std::this_thread::get_id());
}

TEST(HostServices, SanitizeLogMessage) {
  EXPECT_EQ(detail::sanitize_log_message(nullptr), "");
  EXPECT_EQ(detail::sanitize_log_message("plain text"), "plain text");
  EXPECT_EQ(detail::sanitize_log_message("a\tb\\c\x7f"), "a\\x09b\\x5cc\\x7f");
  EXPECT_EQ(detail::sanitize_log_message("gr\xc3\xbc\xc3\x9f"), "gr\xc3\xbc\xc3\x9f");  // UTF-8 kept
  const std::string exact(1024, 'a');
  EXPECT_EQ(detail::sanitize_log_message(exact.c_str()), exact);  // at the limit: not cut
  // 1023 'a' then a 2-byte character straddling the limit: cut before it.
  const std::string straddle = std::string(1023, 'a') + "\xc3\xa9";
  EXPECT_EQ(detail::sanitize_log_message(straddle.c_str()), std::string(1023, 'a') + "...");
}

TEST(HostServices, LogLevels) {
  EXPECT_EQ(detail::log_level_of(PROCAM_LOG_DEBUG), log::Level::debug);
  EXPECT_EQ(detail::log_level_of(PROCAM_LOG_INFO), log::Level::info);
  EXPECT_EQ(detail::log_level_of(PROCAM_LOG_WARN), log::Level::warn);
  EXPECT_EQ(detail::log_level_of(PROCAM_LOG_ERROR), log::Level::error);
  EXPECT_EQ(detail::log_level_of(-7), log::Level::info);
}

}  // namespace
}  // namespace procam::host
