// SPDX-License-Identifier: MIT
// End to end through a real Aravis acquisition path: procamd on the
// configs/rigs/aravis-fake.json rig (sim projector + Aravis in-process Fake
// camera fed by the sim renderer) decodes a Gray scan with the same accuracy
// as the pure sim rig, and the manifest reports how frames were synchronised.
#include <gtest/gtest.h>

#include <fstream>

#include "../integration/daemon_process.hpp"
#include "procam/core/image_io.hpp"
#include "x_server.hpp"

namespace procam::testing {
namespace {

// A daemon config in a temp folder that points at `rig` (path under configs/rigs).
std::string write_daemon_config(const TempDir& dir, const std::string& rig, const nlohmann::json& rig_override = {}) {
  nlohmann::json cfg = {{"rig", source("configs/rigs/" + rig)},
                        {"scene_dirs", {source("configs/scenes")}},
                        {"plugin_paths", nlohmann::json::array()},
                        {"endpoint", "tcp://127.0.0.1:5560"},
                        {"results_dir", (dir.path / "results").string()},
                        {"log", "info"},
                        {"threads", 2},
                        {"max_queue", 4}};
  if (!rig_override.is_null()) {
    std::ifstream in(source("configs/rigs/" + rig));
    nlohmann::json r = nlohmann::json::parse(in);
    r.merge_patch(rig_override);
    cfg["rig"] = r;
  }
  const std::string path = (dir.path / "procamd.json").string();
  std::ofstream(path) << cfg.dump(2);
  return path;
}

nlohmann::json gray_scan(Daemon& d, const std::string& scene) {
  client::Client c(d.endpoint, std::chrono::milliseconds(60000));
  proto::Scan s;
  s.plugin = "structured-light";
  s.method = "gray";
  s.rig_options = {{"scene", scene}};
  auto fin = c.scan(s, [](const proto::Event&) {});
  EXPECT_TRUE(fin.ok()) << fin.status().to_string();
  if (!fin.ok()) return {};
  EXPECT_EQ((*fin)["state"], "done") << fin->dump(2);
  auto r = c.call(proto::ResultQuery{(*fin)["scan_id"]});
  EXPECT_TRUE(r.ok()) << r.status().to_string();
  return r.ok() ? (*r)["manifest"] : nlohmann::json{};
}

TEST(AravisFakeScan, GrayScanThroughAravisMatchesThePureSimRig) {
  TempDir dir;
  const std::string sim_cfg = write_daemon_config(dir, "sim.json");
  nlohmann::json sim_manifest;
  {
    Daemon sim({"--config", sim_cfg});
    ASSERT_TRUE(sim.wait_ready()) << sim.log();
    sim_manifest = gray_scan(sim, "tilted-box");
    EXPECT_EQ(sim.stop(), 0) << sim.log();
  }
  TempDir dir2;
  const std::string arv_cfg = write_daemon_config(dir2, "aravis-fake.json");
  Daemon arv({"--config", arv_cfg});
  ASSERT_TRUE(arv.wait_ready()) << arv.log();
  {
    client::Client c(arv.endpoint, std::chrono::milliseconds(10000));
    auto rig = c.call(proto::DescribeRig{});
    ASSERT_TRUE(rig.ok()) << rig.status().to_string();
    EXPECT_EQ((*rig)["rig"]["backends"]["cameras"][0], "aravis") << rig->dump(2);
    EXPECT_EQ((*rig)["rig"]["cameras"][0]["fed_by"], "sim") << rig->dump(2);
  }
  auto m = gray_scan(arv, "tilted-box");
  ASSERT_TRUE(m.contains("evaluation")) << m.dump(2);
  ASSERT_TRUE(sim_manifest.contains("evaluation")) << sim_manifest.dump(2);
  const double a = m["evaluation"]["within_1col_fraction"].get<double>();
  const double s = sim_manifest["evaluation"]["within_1col_fraction"].get<double>();
  std::printf("within 1 column: aravis-fake %.5f, pure sim %.5f; depth RMS %.3f vs %.3f mm\n", a, s,
              m["evaluation"]["depth_rms_mm"].get<double>(), sim_manifest["evaluation"]["depth_rms_mm"].get<double>());
  EXPECT_GE(a, 0.99) << m["evaluation"].dump(2);
  EXPECT_NEAR(a, s, 0.002) << "aravis " << m["evaluation"].dump(2) << "\nsim " << sim_manifest["evaluation"].dump(2);
  EXPECT_NEAR(m["evaluation"]["depth_rms_mm"].get<double>(), sim_manifest["evaluation"]["depth_rms_mm"].get<double>(), 0.1);
  RecordProperty("aravis_fake_within_1col", std::to_string(a));
  if (m.contains("sync")) {
    EXPECT_EQ(m["sync"]["mode"], "software") << m["sync"].dump(2);
  }
  EXPECT_EQ(arv.stop(), 0);
  if (HasFailure()) std::printf("%s\n", arv.log().substr(0, 4000).c_str());
}

// Sim fault injection through procamd: the scan completes with ground-truth
// accuracy and the manifest says what the sync engine did.
TEST(SyncThroughDaemon, SimFaultsAreRecapturedAndReported) {
  TempDir dir;
  std::ifstream in(source("configs/rigs/sim.json"));
  nlohmann::json cam = nlohmann::json::parse(in)["cameras"][0];
  cam["faults"] = {{"timeout_every", 13}, {"drop_every", 9}, {"late_every", 8}, {"late_ms", 400}};
  const std::string cfg = write_daemon_config(dir, "sim.json", {{"cameras", {cam}}, {"projector", {{"faults", {{"drop_every", 17}}}}}});
  Daemon d({"--config", cfg});
  ASSERT_TRUE(d.wait_ready()) << d.log();
  auto m = gray_scan(d, "tilted-box");
  ASSERT_TRUE(m.contains("evaluation")) << m.dump(2);
  EXPECT_GE(m["evaluation"]["within_1col_fraction"].get<double>(), 0.99) << m["evaluation"].dump(2);
  ASSERT_TRUE(m.contains("sync")) << m.dump(2);
  const auto& s = m["sync"];
  std::printf("manifest sync: frames %d, retried %d, dropped %d, late %d, mode %s\n", s["frames"].get<int>(),
              s["frames_retried"].get<int>(), s["dropped"].get<int>(), s["late"].get<int>(),
              s["mode"].get<std::string>().c_str());
  EXPECT_EQ(s["mode"], "software");
  EXPECT_GT(s["frames_retried"].get<int>(), 0);
  EXPECT_GT(s["late"].get<int>(), 0);
  EXPECT_EQ(m["frames_retried"], s["frames_retried"]);
  EXPECT_EQ(d.stop(), 0);
}

// Faults that hit one pattern more often than the retry limit allows: the scan
// fails with an error naming the pattern and every problem seen.
TEST(SyncThroughDaemon, TooManyFaultsFailTheScanClearly) {
  TempDir dir;
  std::ifstream in(source("configs/rigs/sim.json"));
  nlohmann::json cam = nlohmann::json::parse(in)["cameras"][0];
  cam["faults"] = {{"timeout_every", 7}, {"late_every", 5}, {"late_ms", 400}};
  const std::string cfg = write_daemon_config(dir, "sim.json", {{"cameras", {cam}}, {"projector", {{"faults", {{"drop_every", 11}}}}}});
  Daemon d({"--config", cfg});
  ASSERT_TRUE(d.wait_ready()) << d.log();
  client::Client c(d.endpoint, std::chrono::milliseconds(60000));
  proto::Scan s;
  s.plugin = "structured-light";
  s.method = "gray";
  s.rig_options = {{"scene", "tilted-box"}};
  auto fin = c.scan(s, [](const proto::Event&) {});
  ASSERT_TRUE(fin.ok()) << fin.status().to_string();
  EXPECT_EQ((*fin)["state"], "failed") << fin->dump(2);
  auto r = c.call(proto::ResultQuery{(*fin)["scan_id"]});
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  const std::string msg = (*r)["manifest"]["error"].dump();
  EXPECT_NE(msg.find("failed 3 capture attempts"), std::string::npos) << msg;
  EXPECT_NE(msg.find("late"), std::string::npos) << msg;
  EXPECT_NE(msg.find("dropped"), std::string::npos) << msg;
  EXPECT_EQ(d.stop(), 0);
}

// GLFW projector + loopback screen camera + sync engine + gray decoder under
// a private Xvfb, through procamd: every camera pixel decodes to exactly its
// own projector column.
TEST(GlfwScreencamScan, GrayDecodesExactProjectorColumns) {
  XServer x = XServer::xvfb("1280x800");
  ASSERT_TRUE(x.ok()) << "could not start Xvfb (run scripts/install-deps.sh)";
  TempDir dir;
  const std::string cfg = write_daemon_config(dir, "glfw-screencam.json");
  Daemon d({"--config", cfg});  // inherits DISPLAY
  ASSERT_TRUE(d.wait_ready()) << d.log();
  client::Client c(d.endpoint, std::chrono::milliseconds(60000));
  proto::Scan s;
  s.plugin = "structured-light";
  s.method = "gray";
  auto fin = c.scan(s, [](const proto::Event&) {});
  ASSERT_TRUE(fin.ok()) << fin.status().to_string();
  ASSERT_EQ((*fin)["state"], "done") << fin->dump(2) << d.log();
  const std::string id = (*fin)["scan_id"];
  std::string files;
  for (const auto& e : fs::recursive_directory_iterator(dir.path)) files += e.path().string() + " ";
  auto col = read_image((fs::path(d.results) / id / "proj_col_px.exr").string());
  ASSERT_TRUE(col.ok()) << col.status().to_string() << "\nfiles: " << files;
  ASSERT_EQ(col->width(), 1280u);
  size_t exact = 0, total = 0;
  double worst = 0;
  for (uint32_t yy = 0; yy < col->height(); ++yy)
    for (uint32_t xx = 0; xx < col->width(); ++xx) {
      const float v = col->at<float>(xx, yy);
      ++total;
      const double err = std::isnan(v) ? 1e9 : std::abs(static_cast<double>(v) - xx);
      worst = std::max(worst, err);
      exact += err < 0.5;
    }
  std::printf("glfw + screencam: %zu of %zu pixels decode to their exact column (worst error %.3g)\n", exact, total, worst);
  EXPECT_EQ(exact, total);
  auto r = c.call(proto::ResultQuery{id});
  ASSERT_TRUE(r.ok());
  EXPECT_EQ((*r)["manifest"]["sync"]["mode"], "software");
  EXPECT_EQ((*r)["manifest"]["sync"]["frames"], 24);
  EXPECT_EQ(d.stop(), 0);
}

// `procam calibrate-latency --write` stores the latencies in the rig config;
// procamd then uses them (manifest sync.latency_source) and `procam rig` shows them.
TEST(LatencyCalibration, CliMeasuresStoresAndDaemonShowsThem) {
  TempDir dir;
  fs::create_directories(dir.path / "rigs");
  fs::create_directory_symlink(source("configs/scenes"), dir.path / "scenes");
  const std::string rig = (dir.path / "rigs" / "aravis-fake.json").string();
  fs::copy_file(source("configs/rigs/aravis-fake.json"), rig);
  std::string out;
  ASSERT_EQ(run_command({bin("procam"), "calibrate-latency", "--rig", rig, "--cycles", "3", "--write", "1"}, &out), 0) << out;
  EXPECT_NE(out.find("display latency"), std::string::npos) << out;
  std::ifstream in(rig);
  const auto written = nlohmann::json::parse(in);
  EXPECT_EQ(written["sync"]["latency_source"], "calibrated") << written["sync"].dump();
  EXPECT_TRUE(written["sync"].contains("calibrated_utc"));
  nlohmann::json cfg = {{"rig", rig}, {"scene_dirs", {source("configs/scenes")}}, {"results_dir", (dir.path / "results").string()}};
  const std::string cfg_path = (dir.path / "procamd.json").string();
  std::ofstream(cfg_path) << cfg.dump(2);
  Daemon d({"--config", cfg_path});
  ASSERT_TRUE(d.wait_ready()) << d.log();
  ASSERT_EQ(run_command({bin("procam"), "rig", "--endpoint", d.endpoint}, &out), 0) << out;
  EXPECT_NE(out.find("aravis"), std::string::npos) << out;
  EXPECT_NE(out.find("\"latency_source\":\"calibrated\""), std::string::npos) << out;
  EXPECT_NE(out.find("display_latency_ms"), std::string::npos) << out;
  auto m = gray_scan(d, "plane");
  ASSERT_TRUE(m.contains("sync")) << m.dump(2);
  EXPECT_EQ(m["sync"]["latency_source"], "calibrated");
  EXPECT_GE(m["evaluation"]["within_1col_fraction"].get<double>(), 0.99);
  EXPECT_EQ(d.stop(), 0);
}

}  // namespace
}  // namespace procam::testing
