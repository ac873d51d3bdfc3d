// SPDX-License-Identifier: MIT
// Aravis backend against real emulators: arv-fake-gv-camera-0.8 on loopback
// (started and stopped here; GigE over UDP) and the in-process Fake device
// with injected images.
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <arv.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>

#include "../testing/gv_fake.hpp"
#include "procam/hw/aravis/aravis_camera.hpp"

namespace procam::aravis {
namespace {

using namespace std::chrono_literals;

using procam::testing::GvFake;
using procam::testing::have_fake_binary;

AravisCameraConfig gv_config() {
  AravisCameraConfig c;
  c.device = "127.0.0.1";
  c.trigger = hw::TriggerMode::software;
  return c;
}

TEST(AravisGvFake, ConfigurationRoundTrips) {
  ASSERT_TRUE(have_fake_binary()) << "arv-fake-gv-camera-0.8 missing: run scripts/install-deps.sh";
  GvFake fake;
  auto c = gv_config();
  c.roi_x = 64;
  c.roi_y = 32;
  c.roi_width = 320;
  c.roi_height = 240;
  c.pixel_format = "Mono16";
  c.exposure_us = 5000;
  c.gain_db = 2;
  auto cam = AravisCamera::open(c);
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  auto rb = (*cam)->readback();
  ASSERT_TRUE(rb.ok()) << rb.status().to_string();
  EXPECT_EQ(rb->x, 64);
  EXPECT_EQ(rb->y, 32);
  EXPECT_EQ(rb->width, 320);
  EXPECT_EQ(rb->height, 240);
  EXPECT_EQ(rb->pixel_format, "Mono16");
  EXPECT_NEAR(rb->exposure_us, 5000, 1);
  EXPECT_NEAR(rb->gain_db, 2, 0.5);
  EXPECT_EQ(rb->trigger_mode, "On");
  EXPECT_EQ(rb->trigger_source, "Software");
  EXPECT_EQ((*cam)->info().width, 320u);
  EXPECT_EQ((*cam)->info().bit_depth, 16u);
  // Per-frame settings round-trip too.
  hw::CameraSettings s;
  s.exposure_us = 2500;
  ASSERT_TRUE((*cam)->configure(s).ok());
  rb = (*cam)->readback();
  ASSERT_TRUE(rb.ok());
  EXPECT_NEAR(rb->exposure_us, 2500, 1);
  // A frame arrives in the configured format.
  auto f = (*cam)->capture(2000ms);
  ASSERT_TRUE(f.ok()) << f.status().to_string();
  EXPECT_EQ(f->image.type(), PixelType::u16);
  EXPECT_EQ(f->image.width(), 320u);
  EXPECT_EQ(f->image.height(), 240u);
  // Free-run mode: trigger off after a frame-rate change.
  ASSERT_TRUE((*cam)->set_trigger_mode(hw::TriggerMode::free_run).ok());
  rb = (*cam)->readback();
  ASSERT_TRUE(rb.ok());
  EXPECT_EQ(rb->trigger_mode, "Off");
  auto g = (*cam)->capture(2000ms);
  ASSERT_TRUE(g.ok()) << g.status().to_string();
  EXPECT_GE(g->timestamp_ns, f->timestamp_ns);
}

TEST(AravisGvFake, OpenBySerialAndBadDeviceIsNamed) {
  ASSERT_TRUE(have_fake_binary());
  GvFake fake(0, "PROCAM-SER9");
  auto c = gv_config();
  c.device = "PROCAM-SER9";
  auto cam = AravisCamera::open(c);
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  EXPECT_EQ((*cam)->info().id, "PROCAM-SER9");
  cam = Result<std::unique_ptr<AravisCamera>>(Error(Code::internal, "reset"));
  c.device = "No-Such-Camera-42";
  auto bad = AravisCamera::open(c);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), Code::not_found);
  EXPECT_NE(bad.status().to_string().find("No-Such-Camera-42"), std::string::npos) << bad.status().to_string();
}

TEST(AravisGvFake, SoftwareTriggeredCaptureGivesIncreasingIds) {
  ASSERT_TRUE(have_fake_binary());
  GvFake fake;
  auto cam = AravisCamera::open(gv_config());
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  uint64_t last_id = 0;
  int64_t last_ts = 0;
  const int n = 8;
  for (int i = 0; i < n; ++i) {
    auto f = (*cam)->capture(2000ms);
    ASSERT_TRUE(f.ok()) << "frame " << i << ": " << f.status().to_string();
    if (i > 0) {
      EXPECT_GT(f->frame_id, last_id) << "frame " << i;
      EXPECT_GT(f->timestamp_ns, last_ts) << "frame " << i;
    }
    last_id = f->frame_id;
    last_ts = f->timestamp_ns;
    EXPECT_EQ(f->image.width(), 512u);
  }
  auto st = (*cam)->stats();
  EXPECT_EQ(st["frames"].get<uint64_t>(), static_cast<uint64_t>(n)) << st.dump();
  EXPECT_EQ(st["missing_packets"].get<uint64_t>(), 0u) << st.dump();
}

TEST(AravisGvFake, PacketLossIsDetectedAsCorruptFrames) {
  ASSERT_TRUE(have_fake_binary());
  GvFake fake(50);  // 5 % of packets lost: every 512x512 frame misses some
  auto cam = AravisCamera::open(gv_config());
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  int corrupt = 0;
  for (int i = 0; i < 3; ++i) {
    auto f = (*cam)->capture(2000ms);
    ASSERT_FALSE(f.ok()) << "a frame with lost packets was delivered as good";
    EXPECT_TRUE(f.status().code() == Code::corrupt_data || f.status().code() == Code::timeout)
        << f.status().to_string();
    corrupt += f.status().code() == Code::corrupt_data;
  }
  EXPECT_GE(corrupt, 1);
  auto st = (*cam)->stats();
  EXPECT_GT(st["missing_packets"].get<uint64_t>(), 0u) << st.dump();
}

TEST(AravisGvFake, PacketLossIsRecoveredByRecapture) {
  ASSERT_TRUE(have_fake_binary());
  GvFake fake(20);  // 2 %: a 128x128 frame (~12 packets) is lost ~20 % of the time
  auto c = gv_config();
  c.roi_width = 128;
  c.roi_height = 128;
  auto cam = AravisCamera::open(c);
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  int good = 0, bad = 0;
  for (int attempt = 0; attempt < 300 && (good < 20 || bad == 0); ++attempt) {
    auto f = (*cam)->capture(1000ms);
    if (f.ok()) {
      ++good;
      EXPECT_EQ(f->image.width(), 128u);
    } else {
      ASSERT_TRUE(f.status().code() == Code::corrupt_data || f.status().code() == Code::timeout)
          << f.status().to_string();
      ++bad;
    }
  }
  EXPECT_GE(good, 20);
  EXPECT_GE(bad, 1);
  RecordProperty("corrupt_frames_recaptured", bad);
}

TEST(AravisGvFake, ReconnectsAfterTheCameraDisappears) {
  ASSERT_TRUE(have_fake_binary());
  GvFake fake;
  auto cam = AravisCamera::open(gv_config());
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  ASSERT_TRUE((*cam)->capture(2000ms).ok());
  fake.stop();
  auto lost = (*cam)->capture(500ms);
  ASSERT_FALSE(lost.ok());
  EXPECT_TRUE(lost.status().code() == Code::unavailable || lost.status().code() == Code::timeout)
      << lost.status().to_string();
  // Gone for good: capture reports it clearly.
  (*cam)->drop_connection_for_test();
  auto gone = (*cam)->capture(500ms);
  ASSERT_FALSE(gone.ok());
  EXPECT_NE(gone.status().to_string().find("disappeared"), std::string::npos) << gone.status().to_string();
  // Back again: the next capture reconnects.
  fake.start(0);
  Result<hw::Frame> back = Error(Code::timeout, "not tried");
  for (int i = 0; i < 5 && !back.ok(); ++i) back = (*cam)->capture(2000ms);
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_GE((*cam)->stats()["reconnects"].get<uint64_t>(), 1u);
}

// ---- in-process Fake device

TEST(AravisInProcessFake, InjectedImagesArriveExactly) {
  AravisCameraConfig c;
  c.device = "Fake";
  c.roi_width = 320;
  c.roi_height = 200;
  std::atomic<int> calls{0};
  auto cam = AravisCamera::open(c, [&](uint32_t w, uint32_t h, uint32_t bpp, uint8_t* dst) {
    const int k = calls++;
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) dst[(size_t{y} * w + x) * bpp] = static_cast<uint8_t>((x + y + static_cast<uint32_t>(k)) & 0xff);
    return Status::Ok();
  });
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  uint64_t last = 0;
  for (int i = 0; i < 10; ++i) {
    auto f = (*cam)->capture(2000ms);
    ASSERT_TRUE(f.ok()) << f.status().to_string();
    ASSERT_EQ(f->image.width(), 320u);
    ASSERT_EQ(f->image.height(), 200u);
    // The frame is one injected image, unchanged: x + y + k for a single k.
    const int k = f->image.at<uint8_t>(0, 0);
    int mismatches = 0;
    for (uint32_t y = 0; y < 200; ++y)
      for (uint32_t x = 0; x < 320; ++x)
        mismatches += f->image.at<uint8_t>(x, y) != static_cast<uint8_t>((x + y + static_cast<uint32_t>(k)) & 0xff);
    EXPECT_EQ(mismatches, 0);
    if (i > 0) {
      EXPECT_GT(f->frame_id, last);
    }
    last = f->frame_id;
  }
}

TEST(AravisInProcessFake, SoftwareTriggerAt1000Hz) {
  AravisCameraConfig c;
  c.device = "Fake";
  c.roi_width = 640;
  c.roi_height = 480;
  c.fake_trigger_hz = 1000;
  auto cam = AravisCamera::open(c, [](uint32_t w, uint32_t h, uint32_t bpp, uint8_t* dst) {
    std::memset(dst, 128, size_t{w} * h * bpp);
    return Status::Ok();
  });
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  const int n = 300;
  auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < n; ++i) {
    auto f = (*cam)->capture(2000ms);
    ASSERT_TRUE(f.ok()) << f.status().to_string();
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double fps = n / s;
  std::printf("in-process Fake, software trigger at 1000 Hz, 640x480 Mono8: %.0f frames/s\n", fps);
  RecordProperty("fake_software_trigger_fps", std::to_string(fps));
  EXPECT_GT(fps, 100);
}

TEST(AravisInProcessFake, BayerIsConvertedToGrey) {
  AravisCameraConfig c;
  c.device = "Fake";
  c.roi_width = 64;
  c.roi_height = 64;
  c.pixel_format = "BayerRG8";
  auto cam = AravisCamera::open(c, [](uint32_t w, uint32_t h, uint32_t, uint8_t* dst) {
    // RGGB mosaic of a uniform colour R=200, G=100, B=0 → grey (200 + 2*100 + 0)/4 = 100.
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x)
        dst[size_t{y} * w + x] = (y % 2 == 0) ? (x % 2 == 0 ? 200 : 100) : (x % 2 == 0 ? 100 : 0);
    return Status::Ok();
  });
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  auto f = (*cam)->capture(2000ms);
  ASSERT_TRUE(f.ok()) << f.status().to_string();
  EXPECT_EQ(f->image.at<uint8_t>(10, 10), 100);
  EXPECT_EQ(f->image.at<uint8_t>(63, 63), 100);
}

TEST(AravisConfig, StrictParseNamesTheField) {
  auto bad = parse_aravis_camera_config({{"backend", "aravis"}, {"pixel_fromat", "Mono8"}}, "cameras[0]");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().to_string().find("cameras[0].pixel_fromat"), std::string::npos);
  auto bad2 = parse_aravis_camera_config({{"trigger", "sometimes"}}, "cameras[1]");
  ASSERT_FALSE(bad2.ok());
  EXPECT_NE(bad2.status().to_string().find("cameras[1].trigger"), std::string::npos);
  auto ok = parse_aravis_camera_config({{"device", "Fake"}, {"trigger", "free_run"}, {"roi", {{"width", 10}, {"height", 8}}}},
                                       "cameras[0]");
  ASSERT_TRUE(ok.ok()) << ok.status().to_string();
  EXPECT_EQ(ok->trigger, hw::TriggerMode::free_run);
  EXPECT_EQ(ok->roi_width, 10);
}

}  // namespace
}  // namespace procam::aravis

namespace procam::aravis {
namespace {
TEST(AravisInProcessFake, FrameShowsWhatWasSetBeforeTheTrigger) {
  AravisCameraConfig c;
  c.device = "Fake";
  c.roi_width = 64;
  c.roi_height = 64;
  std::atomic<int> shown{0};
  auto cam = AravisCamera::open(c, [&](uint32_t w, uint32_t h, uint32_t bpp, uint8_t* dst) {
    std::memset(dst, shown.load(), size_t{w} * h * bpp);
    return Status::Ok();
  });
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  for (int i = 1; i < 40; ++i) {
    shown = i;
    auto f = (*cam)->capture(std::chrono::milliseconds(2000));
    ASSERT_TRUE(f.ok()) << f.status().to_string();
    EXPECT_EQ(f->image.at<uint8_t>(5, 5), i) << "frame " << i << " id " << f->frame_id;
  }
}
}  // namespace
}  // namespace procam::aravis
