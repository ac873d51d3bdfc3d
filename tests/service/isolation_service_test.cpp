// SPDX-License-Identifier: MIT
// Plugins in worker processes, seen from a client of a real procamd
// (daemon/plugin_host/README.md "Process model"): a scan whose plugin
// crashes, aborts, writes into its read-only frame or sends garbage fails
// with an error naming the plugin, the call and the cause; the scans queued
// behind it (structured-light) finish; the frames it saved survive.
#include <gtest/gtest.h>

#include <filesystem>

#include "service_fixture.hpp"

namespace procam::testing {
namespace {

using json = nlohmann::json;
using namespace std::chrono_literals;

struct Fault {
  const char* method;
  const char* call;   // where the fixture faults
  const char* cause;  // what the error must say
  int saved_frames;   // frames written before the fault (save_frames)
};

TEST(ServiceIsolation, FaultingPluginFailsItsScanAndQueuedScansStillFinish) {
  ConfigOptions o;
  o.plugin_paths = {std::string(PROCAM_BINARY_DIR) + "/test-plugins-faults"};
  ServiceDaemon sd(o);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  for (const Fault& f : {Fault{"segv", "in add_frame", "killed by signal 11 (SIGSEGV)", 2},
                         Fault{"abort", "in end_round", "killed by signal 6 (SIGABRT)", 3},
                         Fault{"write_frame", "in add_frame", "SIGSEGV", 1},
                         Fault{"garbage", "in end_round", "garbage on the control channel", 3}}) {
    SCOPED_TRACE(f.method);
    proto::Scan bad = tiny_scan();
    bad.plugin = "faults";
    bad.method = f.method;
    bad.save_frames = true;
    auto submitted = c.call(bad);
    ASSERT_TRUE(submitted.ok()) << submitted.status().to_string();
    const std::string bad_id = (*submitted)["scan_id"];
    std::vector<std::string> queued;  // structured-light scans waiting behind the faulting one
    for (int i = 0; i < 2; ++i) {
      auto g = c.call(tiny_scan(i ? "tilted-box" : "plane"));
      ASSERT_TRUE(g.ok()) << g.status().to_string();
      queued.push_back((*g)["scan_id"]);
    }
    const json fin = wait_final(c, bad_id);
    ASSERT_FALSE(fin.is_null()) << sd.d->log();
    EXPECT_EQ(fin["state"], "failed");
    const std::string msg = fin["error"].value("message", "");
    EXPECT_NE(msg.find("plugin 'faults'"), std::string::npos) << msg;
    EXPECT_NE(msg.find(f.call), std::string::npos) << msg;
    EXPECT_NE(msg.find(f.cause), std::string::npos) << msg;
    for (const std::string& id : queued) {
      const json g = wait_final(c, id);
      ASSERT_FALSE(g.is_null());
      EXPECT_EQ(g["state"], "done") << g.dump();
    }
    // Frames are saved before the plugin sees them: decodable again offline.
    const std::filesystem::path dir = std::filesystem::path(sd.results) / bad_id;
    for (int i = 0; i < f.saved_frames; ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "frame-r1-%03d.png", i);
      EXPECT_TRUE(std::filesystem::is_regular_file(dir / name)) << (dir / name);
    }
  }
  auto st = c.call(proto::StatusQuery{});
  ASSERT_TRUE(st.ok()) << st.status().to_string();
}

}  // namespace
}  // namespace procam::testing
