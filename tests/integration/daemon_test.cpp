// SPDX-License-Identifier: MIT
// Integration: a real procamd on the simulated rig, driven through the client
// library, raw ZeroMQ and the procam CLI. Accuracy is checked against the
// simulated rig's ground truth.
#include <gtest/gtest.h>

#include <cmath>

#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "daemon_process.hpp"
#include "procam/core/image_io.hpp"
#include "procam/engine/rig_json.hpp"

namespace procam::testing {
namespace {

// Accuracy contract of the walking skeleton (issue 2): Gray code with
// inverses on the default sim rig decodes >= 99% of the lit pixels to within
// one projector column; depth RMS over those pixels <= 2 mm (one projector
// column is ~2.5 mm of depth at 800 mm on this rig, so quantization alone
// gives ~0.7 mm RMS).
constexpr double kMinWithin1Col = 0.99;
constexpr double kMaxDepthRmsMm = 2.0;

class DaemonTest : public ::testing::Test {
protected:
  static void SetUpTestSuite() {
    daemon_ = new Daemon();
    ASSERT_TRUE(daemon_->wait_ready()) << daemon_->log();
  }
  static void TearDownTestSuite() {
    EXPECT_EQ(daemon_->stop(), 0) << daemon_->log();
    delete daemon_;
  }
  static Daemon* daemon_;
  client::Client client_{daemon_->endpoint, std::chrono::milliseconds(20000)};

  nlohmann::json scan_ok(const std::string& scene, nlohmann::json params = nlohmann::json::object()) {
    proto::Scan s;
    s.plugin = "structured-light";
    s.method = "gray";
    s.params = params;
    s.rig_options = {{"scene", scene}};
    int progress_events = 0;
    bool saw_done = false;
    auto fin = client_.scan(s, [&](const proto::Event& e) {
      progress_events += e.event == "progress";
      if (e.event == "state" && e.body.value("state", "") == "done") saw_done = true;
    });
    EXPECT_TRUE(fin.ok()) << fin.status().to_string();
    if (!fin.ok()) return {};
    EXPECT_EQ((*fin)["state"], "done") << fin->dump(2);
    EXPECT_GT(progress_events, 0);
    EXPECT_TRUE(saw_done);
    auto r = client_.call(proto::ResultQuery{(*fin)["scan_id"]});
    EXPECT_TRUE(r.ok()) << r.status().to_string();
    return r.ok() ? (*r)["manifest"] : nlohmann::json{};
  }
};
Daemon* DaemonTest::daemon_ = nullptr;

TEST_F(DaemonTest, HelloPluginsAndRig) {
  auto h = client_.call(proto::Hello{{1}, "daemon_test"});
  ASSERT_TRUE(h.ok()) << h.status().to_string();
  EXPECT_EQ((*h)["version"], 1);
  auto bad = client_.call(proto::Hello{{7}, "from-the-future"});
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), Code::unsupported_version);

  auto p = client_.call(proto::ListPlugins{});
  ASSERT_TRUE(p.ok());
  bool found = false;
  for (const auto& pl : (*p)["plugins"]) {
    // PROTOCOL.md: `file` is a bare file name, never a path on the daemon's host.
    EXPECT_EQ(pl["file"].get<std::string>().find('/'), std::string::npos) << pl["file"];
    EXPECT_EQ(pl["file"].get<std::string>().rfind("procam-", 0), 0u) << pl["file"];
    if (pl["name"] == "structured-light")
      for (const auto& m : pl["methods"]) found |= m["name"] == "gray";
  }
  EXPECT_TRUE(found) << p->dump(2);

  auto r = client_.call(proto::DescribeRig{});
  ASSERT_TRUE(r.ok());
  const auto& rig = (*r)["rig"];
  EXPECT_GT(rig["projector"]["width"].get<int>(), 0);
  ASSERT_GE(rig["cameras"].size(), 1u);
  EXPECT_TRUE(rig["cameras"][0]["calibration"].contains("cam_from_proj"));
}

TEST_F(DaemonTest, GrayScanOfPlaneMatchesGroundTruth) {
  auto m = scan_ok("plane");
  ASSERT_TRUE(m.contains("evaluation")) << m.dump(2);
  const auto& e = m["evaluation"];
  EXPECT_GE(e["within_1col_fraction"].get<double>(), kMinWithin1Col) << e.dump(2);
  EXPECT_LE(e["depth_rms_mm"].get<double>(), kMaxDepthRmsMm) << e.dump(2);
  EXPECT_GT(m["plan"]["patterns"].get<int>(), 2);
  RecordProperty("plane_within_1col", std::to_string(e["within_1col_fraction"].get<double>()));
}

TEST_F(DaemonTest, GrayScanOfTiltedBoxMatchesGroundTruthAndResultsDownload) {
  auto m = scan_ok("tilted-box");
  ASSERT_TRUE(m.contains("evaluation")) << m.dump(2);
  const auto& e = m["evaluation"];
  EXPECT_GE(e["within_1col_fraction"].get<double>(), kMinWithin1Col) << e.dump(2);
  EXPECT_LE(e["depth_rms_mm"].get<double>(), kMaxDepthRmsMm) << e.dump(2);
  EXPECT_EQ(m["rig"]["state"]["scene"], "tilted-box");

  TempDir out;
  auto got = client_.fetch_all(m["scan_id"], out.path.string());
  ASSERT_TRUE(got.ok()) << got.status().to_string();
  for (const char* f : {"depth_mm.exr", "depth_mm.preview.png", "proj_col_px.exr", "proj_col_px.png",
                        "valid.png", "points.ply", "manifest.json"})
    EXPECT_TRUE(fs::exists(out.path / f)) << f;
  for (const auto& f : m["files"]) {
    EXPECT_EQ(fs::file_size(out.path / f["name"].get<std::string>()), f["size_bytes"].get<uintmax_t>()) << f.dump();
  }
  // The downloaded depth map is the daemon's: finite where valid, NaN elsewhere.
  auto depth = read_image((out.path / "depth_mm.exr").string());
  ASSERT_TRUE(depth.ok());
  auto valid = read_image((out.path / "valid.png").string());
  ASSERT_TRUE(valid.ok());
  size_t mismatched = 0;
  for (size_t i = 0; i < depth->pixel_count(); ++i)
    mismatched += std::isfinite(depth->ptr<float>()[i]) != (valid->ptr<uint8_t>()[i] != 0);
  EXPECT_LT(mismatched, depth->pixel_count() / 1000);  // triangulation may drop a few grazing pixels
}

// save_frames: the raw frames of every round stay in the scan folder, are
// listed and fetchable, and `procam decode` on the downloaded folder gives the
// live scan's correspondences exactly — including the later (correction)
// rounds of a multi-round method, whose patterns depend on round 1's result.
TEST_F(DaemonTest, SavedFramesOfAMultiRoundScanDecodeOfflineToTheSameResult) {
  proto::Scan s;
  s.plugin = "structured-light";
  s.method = "ensemble";
  s.rig_options = {{"scene", "metal-lamp"}};  // glossy errors: the ensemble adds correction rounds
  s.save_frames = true;
  auto fin = client_.scan(s, nullptr);
  ASSERT_TRUE(fin.ok()) << fin.status().to_string();
  ASSERT_EQ((*fin)["state"], "done") << fin->dump(2);
  auto r = client_.call(proto::ResultQuery{(*fin)["scan_id"]});
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const auto& m = (*r)["manifest"];
  const auto rounds = m["plan"]["rounds"].size();
  ASSERT_GE(rounds, 2u) << "the test needs a multi-round scan: " << m["plan"].dump();
  const size_t patterns = m["plan"]["patterns"].get<size_t>();
  EXPECT_EQ(m["saved_frames"], patterns);
  size_t listed = 0, later_rounds = 0;
  for (const auto& f : m["files"]) {
    const std::string name = f["name"];
    listed += name.rfind("frame-r", 0) == 0;
    later_rounds += name.rfind("frame-r2-", 0) == 0;
  }
  EXPECT_EQ(listed, patterns);
  EXPECT_GT(later_rounds, 0u);

  TempDir scan_dir, redecoded;
  auto got = client_.fetch_all(m["scan_id"], scan_dir.path.string());
  ASSERT_TRUE(got.ok()) << got.status().to_string();
  std::string text;
  ASSERT_EQ(run_command({bin("procam"), "decode", "--plugin", "structured-light", "--method", "ensemble", "--frames",
                         scan_dir.path.string(), "--out", redecoded.path.string(), "--rig",
                         source("configs/rigs/sim.json"), "--plugins", PROCAM_PLUGIN_DIR},
                        &text),
            0)
      << text;
  auto live = read_image((scan_dir.path / "proj_col_px.exr").string());
  auto offline = read_image((redecoded.path / "proj_col_px.exr").string());
  ASSERT_TRUE(live.ok() && offline.ok());
  ASSERT_EQ(live->pixel_count(), offline->pixel_count());
  size_t differ = 0;
  for (size_t i = 0; i < live->pixel_count(); ++i) {
    const float a = live->ptr<float>()[i], b = offline->ptr<float>()[i];
    differ += !((std::isnan(a) && std::isnan(b)) || a == b);
  }
  EXPECT_EQ(differ, 0u);
  auto om = engine::read_json_file((redecoded.path / "manifest.json").string());
  ASSERT_TRUE(om.ok());
  EXPECT_EQ((*om)["plan"]["rounds"].size(), rounds);
}

TEST_F(DaemonTest, BadScanRequestsGetClearErrorsAndDaemonKeepsServing) {
  proto::Scan s;
  s.plugin = "no-such-plugin";
  s.method = "gray";
  auto r = client_.call(s);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::not_found);
  EXPECT_NE(r.status().message().find("no-such-plugin"), std::string::npos) << r.status().to_string();

  s.plugin = "structured-light";
  s.method = "nope";
  r = client_.call(s);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::not_found);

  s.method = "gray";
  s.params = {{"binarize", "sideways"}};
  r = client_.call(s);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument) << r.status().to_string();
  EXPECT_NE(r.status().message().find("binarize"), std::string::npos) << r.status().to_string();

  s.params = {{"no_such_param", 1}};
  r = client_.call(s);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument);

  // A bad rig option is refused when the request arrives (issue 17: it used
  // to be queued and fail later with not_found), naming the option once and
  // listing the scenes that exist.
  s.params = nlohmann::json::object();
  s.rig_options = {{"scene", "no-such-scene"}};
  r = client_.call(s);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument) << r.status().to_string();
  EXPECT_NE(r.status().message().find("no-such-scene"), std::string::npos) << r.status().to_string();
  EXPECT_EQ(r.status().message().find("rig_options: rig_options"), std::string::npos) << r.status().to_string();
  EXPECT_NE(r.status().hint().find("tilted-box"), std::string::npos) << r.status().to_string();
  s.rig_options = {{"scene", "plane"}, {"bogus", 1}};
  r = client_.call(s);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument);
  EXPECT_NE(r.status().message().find("'bogus'"), std::string::npos) << r.status().to_string();
  // Host paths are never read: a remote client cannot learn whether a file
  // exists or what it starts with.
  for (const char* path : {"/etc/passwd", "../../etc/passwd", "/etc/hostname", "plane.json", "./plane",
                           "a//b", "..", "/"}) {
    s.rig_options = {{"scene", path}};
    r = client_.call(s);
    ASSERT_FALSE(r.ok()) << path;
    EXPECT_EQ(r.status().code(), Code::invalid_argument) << path << ": " << r.status().to_string();
    EXPECT_NE(r.status().message().find("not a scene name"), std::string::npos) << path << ": " << r.status().to_string();
    EXPECT_EQ(r.status().message().find("JSON"), std::string::npos) << path << ": " << r.status().to_string();
    EXPECT_EQ(r.status().message().find("last read"), std::string::npos) << path << ": " << r.status().to_string();
  }
  // A well-formed name is looked up inside the scene folders only.
  s.rig_options = {{"scene", "configs/scenes/plane"}};
  r = client_.call(s);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument);
  EXPECT_NE(r.status().message().find("not one of the rig's scenes"), std::string::npos) << r.status().to_string();
  s.rig_options = {{"scene", "plane"}};
  auto fin = client_.scan(s, nullptr);
  ASSERT_TRUE(fin.ok()) << fin.status().to_string();
  EXPECT_EQ((*fin)["state"], "done") << fin->dump(2);

  auto res = client_.call(proto::ResultQuery{"20000101-000000-000000"});
  ASSERT_FALSE(res.ok());
  EXPECT_EQ(res.status().code(), Code::not_found);
  auto st = client_.call(proto::StatusQuery{});
  ASSERT_TRUE(st.ok());
}

// Raw ZeroMQ: what a buggy or hostile client can send.
TEST_F(DaemonTest, MalformedMessagesGetErrorReplies) {
  zmq::context_t ctx;
  zmq::socket_t sock(ctx, zmq::socket_type::dealer);
  sock.set(zmq::sockopt::linger, 0);
  sock.set(zmq::sockopt::rcvtimeo, 5000);
  sock.connect(daemon_->endpoint);
  auto ask = [&](const std::vector<std::string>& frames) -> nlohmann::json {
    sock.send(zmq::message_t(), zmq::send_flags::sndmore);
    for (size_t i = 0; i < frames.size(); ++i)
      sock.send(zmq::buffer(frames[i]), i + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
    std::vector<zmq::message_t> msg;
    auto got = zmq::recv_multipart(sock, std::back_inserter(msg));
    if (!got || msg.size() < 2) return {};
    return nlohmann::json::parse(msg[1].to_string(), nullptr, false);
  };
  struct Case { std::vector<std::string> frames; const char* code; };
  const std::vector<Case> cases = {
      {{std::string("\x00\xff\xfe garbage", 12)}, "bad_message"},
      {{"[1,2,3]"}, "bad_message"},
      {{"{\"procam\":1,\"type\":\"status\""}, "bad_message"},           // truncated
      {{"{\"procam\":1,\"type\":\"status\"}"}, "bad_message"},          // no id
      {{"{\"procam\":2,\"id\":\"a\",\"type\":\"status\"}"}, "unsupported_version"},
      {{"{\"procam\":1,\"id\":\"a\",\"type\":\"launch\"}"}, "unknown_type"},
      {{"{\"procam\":1,\"id\":\"a\",\"type\":\"status\",\"scan_id\":5}"}, "bad_message"},
      {{"{\"procam\":1,\"id\":\"a\",\"type\":\"fetch\",\"scan_id\":\"x\",\"file\":\"../../etc/passwd\"}"}, "invalid_argument"},
      {{"{\"procam\":1,\"id\":\"a\",\"type\":\"status\"}", "second frame"}, "bad_message"},
      {{std::string(1100000, ' ')}, "too_large"},
  };
  for (const auto& c : cases) {
    auto rep = ask(c.frames);
    ASSERT_TRUE(rep.is_object()) << "no JSON reply for case " << c.frames[0].substr(0, 60);
    EXPECT_EQ(rep["ok"], false) << rep.dump();
    EXPECT_EQ(rep["type"], "error") << rep.dump();
    EXPECT_EQ(rep["error"]["code"], c.code) << c.frames[0].substr(0, 60) << " -> " << rep.dump();
    EXPECT_FALSE(rep["error"]["message"].get<std::string>().empty());
  }
  // Still serving.
  auto ok = ask({"{\"procam\":1,\"id\":\"after\",\"type\":\"status\"}"});
  EXPECT_EQ(ok["ok"], true) << ok.dump();
  EXPECT_EQ(ok["id"], "after");
}

TEST_F(DaemonTest, CliScanWritesResultsAndPrintsSummary) {
  TempDir out;
  std::string text;
  int rc = run_command({bin("procam"), "scan", "--endpoint", daemon_->endpoint, "--plugin", "structured-light",
                        "--method", "gray", "--rig-option", "scene=plane", "--out", out.path.string()},
                       &text);
  EXPECT_EQ(rc, 0) << text;
  EXPECT_NE(text.find("within 1 projector column"), std::string::npos) << text;
  EXPECT_NE(text.find("decode time"), std::string::npos) << text;
  for (const char* f : {"depth_mm.exr", "depth_mm.preview.png", "valid.png", "points.ply", "manifest.json"})
    EXPECT_TRUE(fs::exists(out.path / f)) << f << "\n" << text;

  rc = run_command({bin("procam"), "plugins", "--endpoint", daemon_->endpoint}, &text);
  EXPECT_EQ(rc, 0);
  EXPECT_NE(text.find("gray"), std::string::npos) << text;
  rc = run_command({bin("procam"), "rig", "--endpoint", daemon_->endpoint}, &text);
  EXPECT_EQ(rc, 0);
  EXPECT_NE(text.find("projector"), std::string::npos) << text;
  rc = run_command({bin("procam"), "scan", "--endpoint", daemon_->endpoint, "--plugin", "structured-light",
                    "--method", "gray", "--param", "bits=banana", "--out", out.path.string()},
                   &text);
  EXPECT_EQ(rc, 1);
  EXPECT_NE(text.find("bits"), std::string::npos) << text;
}

TEST(DaemonLifecycle, NoDaemonGivesAHintNotAHang) {
  TempDir d;
  std::string text;
  int rc = run_command({bin("procam"), "status", "--endpoint", "ipc://" + (d.path / "nobody.sock").string(),
                        "--timeout", "1"},
                       &text);
  EXPECT_EQ(rc, 1);
  EXPECT_NE(text.find("is procamd running"), std::string::npos) << text;
}

TEST(DaemonLifecycle, BadConfigIsRefusedWithTheKeyNamed) {
  TempDir d;
  std::ofstream(d.path / "bad.json") << R"({"rig": "rigs/sim.json", "endpiont": "tcp://*:1"})";
  std::string text;
  int rc = run_command({bin("procamd"), "--config", (d.path / "bad.json").string()}, &text);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(text.find("endpiont"), std::string::npos) << text;
  // A wrong value of a nested key names it and the allowed values.
  std::ofstream(d.path / "bad2.json") << R"({"rig": {"name": "x"}, "queued_scans": {"on_restart": "later"}})";
  rc = run_command({bin("procamd"), "--config", (d.path / "bad2.json").string()}, &text);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(text.find("queued_scans.on_restart"), std::string::npos) << text;
  EXPECT_NE(text.find("\"run\" or \"fail\""), std::string::npos) << text;
}

TEST(DaemonLifecycle, RestartServesEarlierScansAndStopsCleanly) {
  TempDir results;
  std::string scan_id;
  {
    Daemon d({"--results", results.path.string()});
    ASSERT_TRUE(d.wait_ready()) << d.log();
    client::Client c(d.endpoint, std::chrono::milliseconds(20000));
    proto::Scan s;
    s.plugin = "structured-light";
    s.method = "gray";
    auto fin = c.scan(s, nullptr);
    ASSERT_TRUE(fin.ok()) << fin.status().to_string();
    scan_id = (*fin)["scan_id"];
    EXPECT_EQ(d.stop(), 0) << d.log();
    EXPECT_NE(d.log().find("stopped cleanly"), std::string::npos) << d.log();
  }
  // An interrupted scan folder (no final manifest) is reported as failed.
  fs::create_directories(results.path / "20260101-000000-abcdef");
  Daemon d2({"--results", results.path.string()});
  ASSERT_TRUE(d2.wait_ready()) << d2.log();
  client::Client c(d2.endpoint, std::chrono::milliseconds(20000));
  auto r = c.call(proto::ResultQuery{scan_id});
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ((*r)["manifest"]["state"], "done");
  auto i = c.call(proto::StatusQuery{std::string("20260101-000000-abcdef")});
  ASSERT_TRUE(i.ok()) << i.status().to_string();
  EXPECT_EQ((*i)["scan"]["state"], "failed");
  EXPECT_NE((*i)["scan"]["error"]["message"].get<std::string>().find("interrupted"), std::string::npos);
}

}  // namespace
}  // namespace procam::testing

namespace procam::testing {
namespace {

// Acceptance of issue 2: a client written only from proto/PROTOCOL.md (no
// procam code) lists plugins and runs a scan against the real daemon.
TEST(SpecOnlyClient, PythonClientListsPluginsAndRunsAScan) {
  ASSERT_TRUE(fs::exists("/usr/bin/python3")) << "scripts/install-deps.sh installs python3 + python3-zmq";
  Daemon d;
  ASSERT_TRUE(d.wait_ready()) << d.log();
  const std::string client = source("proto/examples/spec_client.py");
  std::string text;
  int rc = run_command({"/usr/bin/python3", client, "--endpoint", d.endpoint, "list"}, &text);
  ASSERT_EQ(rc, 0) << text;
  EXPECT_NE(text.find("structured-light"), std::string::npos) << text;
  TempDir out;
  rc = run_command({"/usr/bin/python3", client, "--endpoint", d.endpoint, "scan", "--plugin", "structured-light",
                    "--method", "gray", "--rig-option", "scene=plane", "--out", out.path.string()},
                   &text);
  ASSERT_EQ(rc, 0) << text;
  EXPECT_TRUE(fs::exists(out.path / "manifest.json")) << text;
  EXPECT_TRUE(fs::exists(out.path / "depth_mm.exr")) << text;
  EXPECT_TRUE(fs::exists(out.path / "points.ply")) << text;
}

}  // namespace
}  // namespace procam::testing
