// SPDX-License-Identifier: MIT
// Sync engine (daemon/engine/sync.*): fault injection on the sim rig (drops,
// late frames, timeouts, dropped presentations), packet loss on the fake GigE
// camera, hardware-trigger order matching, latency calibration, and the
// per-frame overhead / frame rate with the in-process Fake camera.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <fstream>

#include "../../hw/aravis/testing/gv_fake.hpp"
#include "rig_helpers.hpp"
#include "procam/core/image.hpp"
#include "procam/engine/sync.hpp"
#include "procam/hw/aravis/aravis_camera.hpp"
#include "procam/hw/rig.hpp"

namespace procam::testing {
namespace {

// Pattern k: vertical stripes of period 2^(k%6+4), so consecutive patterns differ.
Image pattern(uint32_t w, uint32_t h, uint32_t k) {
  Image im(w, h, PixelType::u8);
  const uint32_t period = 1u << (k % 6 + 4);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) im.at<uint8_t>(x, y) = (x / period) % 2 ? 255 : 0;
  return im;
}

// Pixels differing by more than 40 levels: noise reaches that only at a few
// stripe edges (< 1 %); another pattern differs in ~25-50 % of the pixels.
size_t big_differences(const Image& a, const Image& b) {
  size_t n = 0;
  for (size_t i = 0; i < a.size_bytes() && i < b.size_bytes(); ++i) n += std::abs(int{a.data()[i]} - int{b.data()[i]}) > 40;
  return n;
}

// Captures `n` patterns through the engine on `faulty` and checks every frame
// against a fault-free reference rig: no frame may show another pattern.
void expect_every_frame_matches(hw::Rig& faulty, engine::SyncEngine& sync, int n) {
  auto ref = make_rig("sim.json");
  ASSERT_TRUE(ref);
  const auto& pi = faulty.projector().info();
  for (int k = 0; k < n; ++k) {
    Image p = pattern(pi.width, pi.height, static_cast<uint32_t>(k));
    auto f = sync.capture(p.view(), static_cast<uint64_t>(k + 1), 0, "p" + std::to_string(k));
    ASSERT_TRUE(f.ok()) << "pattern " << k << ": " << f.status().to_string();
    ASSERT_TRUE(ref->projector().show(p.view(), static_cast<uint64_t>(k + 1)).ok());
    ASSERT_TRUE(ref->projector().wait_presented(static_cast<uint64_t>(k + 1), std::chrono::milliseconds(100)).ok());
    auto g = ref->camera(0).capture(std::chrono::milliseconds(1000));
    ASSERT_TRUE(g.ok());
    EXPECT_LT(big_differences(f->image, g->image), f->image.size_bytes() / 50)
        << "pattern " << k << " was delivered with another pattern's frame";
  }
}

engine::SyncSettings settings_for(hw::Rig& rig) {
  auto s = engine::parse_sync_settings(rig.sync_settings(), rig.camera(0).trigger_mode());
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  return s.ok() ? *s : engine::SyncSettings{};
}

TEST(SyncEngine, SimFaultsAreDetectedAndOnlyAffectedPatternsRecaptured) {
  // Every 5th capture times out, every 7th frame is lost (id gap), every 4th
  // frame is stamped 400 ms late, every 6th presentation is dropped.
  auto rig = make_rig("sim.json", {{"projector", {{"faults", {{"drop_every", 6}}}}},
                                   {"cameras", {{{"backend", "sim"},
                                                 {"id", "sim0"},
                                                 {"intrinsics", read_rig("sim.json")["cameras"][0]["intrinsics"]},
                                                 {"cam_from_proj", read_rig("sim.json")["cameras"][0]["cam_from_proj"]},
                                                 {"faults", {{"timeout_every", 5}, {"drop_every", 7}, {"late_every", 4}, {"late_ms", 400}}}}}}});
  ASSERT_TRUE(rig);
  auto s = settings_for(*rig);
  s.retries = 4;
  s.late_ms = 200;
  engine::SyncEngine sync(*rig, s);
  const int n = 24;
  expect_every_frame_matches(*rig, sync, n);
  const auto& r = sync.report();
  std::printf("sync report: %s\n", r.to_json().dump().c_str());
  EXPECT_EQ(r.frames, static_cast<size_t>(n));
  EXPECT_GT(r.retried, 0u);
  EXPECT_GT(r.late, 0u);
  EXPECT_GT(r.dropped, 0u);
  EXPECT_LT(r.retried, static_cast<size_t>(n));  // only the affected patterns
  EXPECT_EQ(r.mode, "software");
}

TEST(SyncEngine, PersistentFaultsFailWithAClearError) {
  auto cam = read_rig("sim.json")["cameras"][0];
  cam["faults"] = {{"timeout_every", 1}};
  auto rig = make_rig("sim.json", {{"cameras", {cam}}});
  ASSERT_TRUE(rig);
  auto s = settings_for(*rig);
  s.retries = 2;
  engine::SyncEngine sync(*rig, s);
  Image p = pattern(rig->projector().info().width, rig->projector().info().height, 1);
  auto f = sync.capture(p.view(), 1, 0, "col bit 3");
  ASSERT_FALSE(f.ok());
  const std::string msg = f.status().to_string();
  EXPECT_NE(msg.find("col bit 3"), std::string::npos) << msg;
  EXPECT_NE(msg.find("3 capture attempts"), std::string::npos) << msg;
  EXPECT_NE(msg.find("dropped"), std::string::npos) << msg;
  EXPECT_EQ(sync.report().retried, 2u);
}

TEST(SyncEngine, HardwareModeMatchesByOrderAndCatchesLostFrames) {
  auto cam = read_rig("sim.json")["cameras"][0];
  cam["faults"] = {{"drop_every", 5}};
  auto rig = make_rig("sim.json", {{"cameras", {cam}}, {"projector", {{"refresh_hz", 1000}}}});
  ASSERT_TRUE(rig);
  auto s = settings_for(*rig);
  s.mode = hw::TriggerMode::hardware;
  s.retries = 3;
  engine::SyncEngine sync(*rig, s);
  expect_every_frame_matches(*rig, sync, 16);
  EXPECT_GT(sync.report().mismatched, 0u) << sync.report().to_json().dump(2);
  EXPECT_EQ(sync.report().mode, "hardware");
}

// The sim projector + a real GigE camera (fake, 2 % packet loss): corrupt
// frames are detected and re-captured.
TEST(SyncEngine, GigEPacketLossIsDetectedAndRecaptured) {
  ASSERT_TRUE(have_fake_binary()) << "arv-fake-gv-camera-0.8 missing: run scripts/install-deps.sh";
  GvFake fake(20);
  aravis::AravisCameraConfig c;
  c.device = "127.0.0.1";
  c.roi_width = 128;
  c.roi_height = 128;
  auto cam = aravis::AravisCamera::open(c);
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  auto sim = make_rig("sim.json");
  ASSERT_TRUE(sim);
  SimProjectorGvCameraRig rig(std::move(sim), std::move(*cam));
  engine::SyncSettings s;
  s.retries = 8;
  s.late_ms = 500;
  engine::SyncEngine sync(rig, s);
  const auto& pi = rig.projector().info();
  Image p = pattern(pi.width, pi.height, 0);
  int k = 0;
  for (; k < 60 && (k < 20 || sync.report().corrupt == 0); ++k) {
    auto f = sync.capture(p.view(), static_cast<uint64_t>(k + 1), 0, "p" + std::to_string(k));
    ASSERT_TRUE(f.ok()) << f.status().to_string();
  }
  std::printf("GigE fake -r 20: %d patterns, report %s\n", k, sync.report().to_json().dump().c_str());
  EXPECT_GT(sync.report().corrupt + sync.report().dropped, 0u);
  EXPECT_EQ(sync.report().frames, static_cast<size_t>(k));
  EXPECT_GT(rig.camera(0).stats()["missing_packets"].get<uint64_t>(), 0u);
}

TEST(SyncEngine, FreeRunDiscardsFramesFromThePatternChange) {
  auto rig = make_rig("aravis-fake.json", {{"cameras", {{{"backend", "aravis"},
                                                          {"device", "Fake"},
                                                          {"trigger", "free_run"},
                                                          {"frame_rate", 200},
                                                          {"intrinsics", read_rig("sim.json")["cameras"][0]["intrinsics"]},
                                                          {"cam_from_proj", read_rig("sim.json")["cameras"][0]["cam_from_proj"]},
                                                          {"feed", {{"backend", "sim"}}}}}},
                                           {"sync", {{"mode", "free_run"}, {"late_ms", 500}}}});
  ASSERT_TRUE(rig);
  engine::SyncEngine sync(*rig, settings_for(*rig));
  expect_every_frame_matches(*rig, sync, 6);
  EXPECT_EQ(sync.report().mode, "free_run");
}

TEST(SyncEngine, LatencyCalibrationStoresLatenciesInTheRigState) {
  auto rig = make_rig("aravis-fake.json");
  ASSERT_TRUE(rig);
  auto cal = engine::calibrate_latency(*rig, 3);
  ASSERT_TRUE(cal.ok()) << cal.status().to_string();
  std::printf("latency calibration: %s\n", cal->dump().c_str());
  EXPECT_GE((*cal)["display_latency_ms"].get<double>(), 0.0);
  EXPECT_GE((*cal)["camera_latency_ms"].get<double>(), 0.0);
  auto st = rig->sync_settings();
  EXPECT_EQ(st["latency_source"], "calibrated") << st.dump();
  EXPECT_EQ(rig->describe()["state"]["sync"]["latency_source"], "calibrated");
  auto s = engine::parse_sync_settings(st, hw::TriggerMode::software);
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  EXPECT_EQ(s->latency_source, "calibrated");
}

}  // namespace
}  // namespace procam::testing
