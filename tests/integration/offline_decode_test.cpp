// SPDX-License-Identifier: MIT
// Offline decoding (`procam decode`) of frames captured from the simulated rig
// and saved as files: same accuracy as a live scan, clear errors on bad input.
#include <gtest/gtest.h>

#include <cstdio>

#include "daemon_process.hpp"
#include "procam/core/image_io.hpp"
#include "procam/engine/evaluate.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

namespace procam::testing {
namespace {

// Captures the first round of `method`'s plan (default gray) on the sim rig
// (scene `scene`) into `dir` as 000.png, 001.png, ... and returns the
// ground truth.
hw::GroundTruth capture_to_files(const std::string& scene, const fs::path& dir, const std::string& method = "gray") {
  auto cfg = engine::read_json_file(source("configs/rigs/sim.json"));
  EXPECT_TRUE(cfg.ok());
  auto rig = hw::create_rig(*cfg, {source("configs/rigs"), {source("configs/scenes")}});
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  EXPECT_TRUE((*rig)->apply_scan_options({{"scene", scene}}).ok());
  host::PluginHost plugins(host::LoadOptions{.probe_in_child = false});
  plugins.load_directories({PROCAM_PLUGIN_DIR});
  auto rig_json = engine::plugin_rig_json(**rig, 1);
  auto session = plugins.create_session("structured-light", method, "{}", rig_json.dump());
  EXPECT_TRUE(session.ok()) << session.status().to_string();
  auto plan = session->next_plan();
  EXPECT_TRUE(plan.ok() && plan->has_value());
  const auto& frames = (**plan).frames;
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_TRUE((*rig)->projector().show(frames[i].pattern, i + 1).ok());
    auto f = (*rig)->camera(0).capture(std::chrono::milliseconds(1000));
    EXPECT_TRUE(f.ok());
    char name[32];
    std::snprintf(name, sizeof name, "%03zu.png", i);
    EXPECT_TRUE(write_image((dir / name).string(), f->image).ok());
  }
  auto gt = (*rig)->ground_truth(0);
  EXPECT_TRUE(gt.ok());
  return std::move(*gt);
}

std::vector<std::string> decode_cmd(const fs::path& frames, const fs::path& out) {
  return {bin("procam"), "decode", "--plugin", "structured-light", "--method", "gray", "--frames", frames.string(),
          "--out", out.string(), "--rig", source("configs/rigs/sim.json"), "--plugins", PROCAM_PLUGIN_DIR};
}

TEST(OfflineDecode, SavedSimFramesDecodeAsAccuratelyAsALiveScan) {
  TempDir frames, out;
  auto gt = capture_to_files("tilted-box", frames.path);
  std::string text;
  ASSERT_EQ(run_command(decode_cmd(frames.path, out.path), &text), 0) << text;
  for (const char* f : {"proj_col_px.exr", "depth_mm.exr", "depth_mm.preview.png", "valid.png", "points.ply",
                        "manifest.json"})
    EXPECT_TRUE(fs::exists(out.path / f)) << f << "\n" << text;
  auto col = read_image((out.path / "proj_col_px.exr").string());
  auto depth = read_image((out.path / "depth_mm.exr").string());
  ASSERT_TRUE(col.ok() && depth.ok());
  auto e = engine::evaluate_correspondence(*col, &*depth, gt);
  EXPECT_GE(e["within_1col_fraction"].get<double>(), 0.99) << e.dump(2);
  EXPECT_LE(e["depth_rms_mm"].get<double>(), 2.0) << e.dump(2);
  auto m = engine::read_json_file((out.path / "manifest.json").string());
  ASSERT_TRUE(m.ok());
  EXPECT_EQ((*m)["plan"]["patterns"], 24);
}

// A multi-round method on a one-round capture decodes that round (the
// session is stopped there, host::Session::stop, also in the isolated
// worker the CLI uses), says which round it skipped and why. `auto` on the deep scene plans a second
// round (more codes where its first disputes, docs/report/issue18), so the
// capture of its first round alone lacks round2/.
TEST(OfflineDecode, MultiRoundMethodOnOneRoundCaptureRunsTheRoundsThatExist) {
  TempDir frames, out;
  auto gt = capture_to_files("deep-scene", frames.path, "auto");
  std::vector<std::string> cmd = decode_cmd(frames.path, out.path);
  cmd[5] = "auto";  // --method
  std::string text;
  ASSERT_EQ(run_command(cmd, &text), 0) << text;
  EXPECT_NE(text.find("round 2"), std::string::npos) << text;
  auto m = engine::read_json_file((out.path / "manifest.json").string());
  ASSERT_TRUE(m.ok());
  ASSERT_TRUE((*m)["plan"]["rounds_skipped"].is_string()) << m->dump(2);
  EXPECT_NE((*m)["plan"]["rounds_skipped"].get<std::string>().find("round2"), std::string::npos) << m->dump(2);
  EXPECT_EQ((*m)["plan"]["rounds"].size(), 1u);
  auto col = read_image((out.path / "proj_col_px.exr").string());
  ASSERT_TRUE(col.ok());
  auto e = engine::evaluate_correspondence(*col, nullptr, gt);
  // Round 1 alone leaves the disputed pixels invalid (the second round is
  // what resolves them), but what it decodes is right: the correspondence
  // suite's bar of <= 0.5 % gross errors, and more than half of the lit
  // pixels decoded.
  EXPECT_LE(e["gross_error_fraction"].get<double>(), 0.005) << e.dump(2);
  EXPECT_GT(e["decoded_fraction"].get<double>(), 0.5) << e.dump(2);
}

TEST(OfflineDecode, WrongFrameCountAndCorruptFramesAreExplained) {
  TempDir frames, out;
  (void)capture_to_files("plane", frames.path);
  fs::remove(frames.path / "023.png");
  std::string text;
  EXPECT_EQ(run_command(decode_cmd(frames.path, out.path), &text), 1);
  EXPECT_NE(text.find("needs 24 frames"), std::string::npos) << text;
  EXPECT_NE(text.find("found 23"), std::string::npos) << text;
  EXPECT_NE(text.find("col bit 0 inverse"), std::string::npos) << text;  // the hint lists the plan order

  std::ofstream(frames.path / "023.png") << "this is not an image";
  EXPECT_EQ(run_command(decode_cmd(frames.path, out.path), &text), 1);
  EXPECT_NE(text.find("023.png"), std::string::npos) << text;
  EXPECT_FALSE(fs::exists(out.path / "manifest.json"));  // nothing half-written

  EXPECT_EQ(run_command(decode_cmd(frames.path / "nope", out.path), &text), 1);
  EXPECT_NE(text.find("does not exist"), std::string::npos) << text;
}

// A plugin folder with broken files: each is reported, the daemon keeps serving.
TEST(BrokenPlugins, AreReportedAndSkippedWhileTheDaemonServes) {
  TempDir bad;
  const fs::path fixtures = fs::path(PROCAM_BINARY_DIR) / "daemon/plugin_host/test-plugins";
  fs::copy_file(fixtures / "wrong_abi.so", bad.path / "wrong_abi.so");
  fs::copy_file(fixtures / "crash_on_load.so", bad.path / "crash_on_load.so");
  fs::copy_file(fixtures / "missing_create.so", bad.path / "missing_create.so");
  std::ofstream(bad.path / "corrupt.so") << "not an ELF file";
  Daemon d({"--plugins", bad.path.string()});
  ASSERT_TRUE(d.wait_ready()) << d.log();
  client::Client c(d.endpoint, std::chrono::milliseconds(20000));
  auto p = c.call(proto::ListPlugins{});
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  std::map<std::string, std::string> rejected;
  for (const auto& r : (*p)["rejected"])
    rejected[fs::path(r["file"].get<std::string>()).filename().string()] =
        r["error"]["code"].get<std::string>() + ": " + r["error"]["message"].get<std::string>();
  ASSERT_EQ(rejected.size(), 4u) << p->dump(2);
  EXPECT_NE(rejected["wrong_abi.so"].find("ABI 999"), std::string::npos) << rejected["wrong_abi.so"];
  EXPECT_NE(rejected["crash_on_load.so"].find("crashed"), std::string::npos) << rejected["crash_on_load.so"];
  EXPECT_NE(rejected["missing_create.so"].find("procam_plugin_create"), std::string::npos) << rejected["missing_create.so"];
  EXPECT_NE(rejected["corrupt.so"].find("corrupt_data"), std::string::npos) << rejected["corrupt.so"];
  bool good = false;
  for (const auto& pl : (*p)["plugins"]) good |= pl["name"] == "structured-light";
  EXPECT_TRUE(good);
  proto::Scan s;
  s.plugin = "structured-light";
  s.method = "gray";
  auto fin = c.scan(s, nullptr);
  ASSERT_TRUE(fin.ok()) << fin.status().to_string();
  EXPECT_EQ((*fin)["state"], "done");
  EXPECT_NE(d.log().find("skipped plugin"), std::string::npos);
}

}  // namespace
}  // namespace procam::testing
