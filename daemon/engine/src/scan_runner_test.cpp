// SPDX-License-Identifier: MIT
// Scan runner settings mapping: every procam_frame_settings field reaches the
// rig's devices or fails the scan (here: projector_polarizer_deg), checked
// through whole scans of a fixture plugin against the sim rig and, under a
// private Xvfb, the glfw projector.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "procam/engine/scan_runner.hpp"
#include "procam/hw/rig.hpp"
#include "procam/hw/sim/sim_rig.hpp"
#include "x_server.hpp"

namespace procam {
namespace {

// A small sim rig: 64x48 projector, 64x48 camera, the shipped plane scene.
nlohmann::json small_sim_rig() {
  return nlohmann::json::parse(R"({
    "name": "small", "scene": "plane", "threads": 1,
    "projector": {"backend": "sim", "intrinsics": {"width": 64, "height": 48, "fx": 80, "fy": 80, "cx": 31.5, "cy": 23.5}},
    "cameras": [{"backend": "sim",
                 "intrinsics": {"width": 64, "height": 48, "fx": 90, "fy": 90, "cx": 31.5, "cy": 23.5},
                 "cam_from_proj": {"euler_deg": [0, -12.34, 0], "translation_mm": [175, 0, 0]}}]})");
}

hw::RigContext ctx() { return {PROCAM_SOURCE_DIR "/configs/rigs", {PROCAM_SOURCE_DIR "/configs/scenes"}}; }

// Runs the fixture's one-frame scan on `rig` with the given polariser angle
// (omitted from the params when NaN).
Result<engine::ScanOutcome> scan_with_polarizer(hw::Rig& rig, double deg) {
  host::PluginHost host;
  if (Status st = host.load_file(PROCAM_ENGINE_FIXTURE); !st) return st;
  const auto& pi = rig.projector().info();
  nlohmann::json params = {{"width", pi.width}, {"height", pi.height}};
  if (!std::isnan(deg)) params["projector_polarizer_deg"] = deg;
  auto session = host.create_session("polarised", "polarised", params.dump(), "{}");
  if (!session) return session.status();
  std::atomic<bool> cancel{false};
  return engine::run_scan(rig, *session, {}, nullptr, cancel);
}

TEST(ScanRunnerSettings, ProjectorPolarizerReachesTheSimProjector) {
  auto rig = hw::create_rig(small_sim_rig(), ctx());
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  auto* proj = dynamic_cast<sim::SimProjector*>(&(*rig)->projector());
  ASSERT_NE(proj, nullptr);
  ASSERT_TRUE(std::isnan(proj->polarizer_deg())) << "a fresh sim projector has no polariser angle";

  auto out = scan_with_polarizer(**rig, 37.5);
  ASSERT_TRUE(out.ok()) << out.status().to_string();
  EXPECT_EQ(out->patterns, 1u);
  EXPECT_DOUBLE_EQ(proj->polarizer_deg(), 37.5);

  // A plan without the angle (NaN) clears it: the setting is per frame.
  out = scan_with_polarizer(**rig, std::nan(""));
  ASSERT_TRUE(out.ok()) << out.status().to_string();
  EXPECT_TRUE(std::isnan(proj->polarizer_deg()));
}

TEST(ScanRunnerSettings, SimProjectorRejectsInfiniteAngle) {
  auto rig = hw::create_rig(small_sim_rig(), ctx());
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  Status st = (*rig)->projector().set_polarizer_deg(INFINITY);
  EXPECT_EQ(st.code(), Code::invalid_argument) << st.to_string();
}

TEST(ScanRunnerSettings, GlfwProjectorRefusesPolarizerAndTheScanFails) {
  const auto backends = hw::available_backends();
  for (const char* b : {"glfw", "screencam"})
    if (std::find(backends.begin(), backends.end(), b) == backends.end())
      GTEST_SKIP() << "backend '" << b << "' is not compiled into this build";
  testing::XServer x = testing::XServer::xvfb("320x240");
  ASSERT_TRUE(x.ok()) << "could not start Xvfb (run scripts/install-deps.sh)";
  auto rig_json = nlohmann::json::parse(R"({
    "name": "glfw-screencam-small",
    "sync": {"mode": "software", "display_latency_ms": 0, "camera_latency_ms": 0},
    "projector": {"backend": "glfw", "monitor": 0,
                  "intrinsics": {"width": 320, "height": 240, "fx": 400, "fy": 400, "cx": 159.5, "cy": 119.5}},
    "cameras": [{"backend": "screencam",
                 "intrinsics": {"width": 320, "height": 240, "fx": 400, "fy": 400, "cx": 159.5, "cy": 119.5},
                 "cam_from_proj": {"euler_deg": [0, 0, 0], "translation_mm": [100, 0, 0]}}]})");
  auto rig = hw::create_rig(rig_json, ctx());
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();

  // The device itself: NaN (no polariser) is fine, an angle is refused.
  hw::Projector& proj = (*rig)->projector();
  EXPECT_EQ(proj.info().backend, "glfw");
  EXPECT_TRUE(proj.set_polarizer_deg(std::nan("")).ok());
  Status st = proj.set_polarizer_deg(45);
  EXPECT_EQ(st.code(), Code::failed_precondition);
  EXPECT_NE(st.to_string().find("remove projector_polarizer_deg from the plan"), std::string::npos) << st.to_string();

  // A whole scan whose plan asks for an angle fails with that error, naming the frame.
  auto out = scan_with_polarizer(**rig, 45);
  ASSERT_FALSE(out.ok());
  EXPECT_EQ(out.status().code(), Code::failed_precondition) << out.status().to_string();
  const std::string msg = out.status().to_string();
  EXPECT_NE(msg.find("polariser"), std::string::npos) << msg;
  EXPECT_NE(msg.find("round 1, frame 0"), std::string::npos) << msg;

  // The same plan without the angle scans (the refusal is about the angle only).
  auto ok = scan_with_polarizer(**rig, std::nan(""));
  EXPECT_TRUE(ok.ok()) << ok.status().to_string();
}

}  // namespace
}  // namespace procam
