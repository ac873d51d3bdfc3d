// SPDX-License-Identifier: MIT
// GLFW projector under a private Xvfb: exact pixels (GL back buffer and an
// external X grab through the screen camera), LUT, monitor errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "procam/core/image.hpp"
#include "procam/hw/glfw/glfw_projector.hpp"
#include "procam/hw/screencam/screen_camera.hpp"
#include "x_server.hpp"

namespace procam::testing {
namespace {

using namespace std::chrono_literals;

Image gray_code_columns(uint32_t w, uint32_t h, int bit) {
  Image im(w, h, PixelType::u8);
  for (uint32_t x = 0; x < w; ++x) {
    const uint32_t g = x ^ (x >> 1);
    const uint8_t v = (g >> bit) & 1u ? 255 : 0;
    for (uint32_t y = 0; y < h; ++y) im.at<uint8_t>(x, y) = v;
  }
  return im;
}

Image noise(uint32_t w, uint32_t h, unsigned seed) {
  Image im(w, h, PixelType::u8);
  std::mt19937 rng(seed);
  for (size_t i = 0; i < im.size_bytes(); ++i) im.data()[i] = static_cast<uint8_t>(rng() & 0xff);
  return im;
}

size_t mismatches(const uint8_t* a, const uint8_t* b, size_t n) {
  size_t m = 0;
  for (size_t i = 0; i < n; ++i) m += a[i] != b[i];
  return m;
}

TEST(GlfwProjector, ShowsEachPatternExactly) {
  XServer x = XServer::xvfb("1280x800");
  ASSERT_TRUE(x.ok()) << "could not start Xvfb (run scripts/install-deps.sh)";
  glfw::GlfwProjectorConfig c;
  c.keep_backbuffer = true;
  auto p = glfw::GlfwProjector::open(c);
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  ASSERT_EQ((*p)->info().width, 1280u);
  ASSERT_EQ((*p)->info().height, 800u);
  screencam::ScreenCameraConfig sc;
  auto cam = screencam::ScreenCamera::open(sc);
  ASSERT_TRUE(cam.ok()) << cam.status().to_string();
  std::vector<Image> patterns;
  for (int b = 0; b < 11; ++b) patterns.push_back(gray_code_columns(1280, 800, b));
  patterns.push_back(noise(1280, 800, 7));
  int64_t last_ns = 0;
  for (size_t k = 0; k < patterns.size(); ++k) {
    ASSERT_TRUE((*p)->show(patterns[k].view(), k + 1).ok());
    auto pres = (*p)->wait_presented(k + 1, 2000ms);
    ASSERT_TRUE(pres.ok()) << pres.status().to_string();
    EXPECT_GT(pres->shown_ns, last_ns);
    last_ns = pres->shown_ns;
    auto back = (*p)->last_backbuffer();
    ASSERT_EQ(back.size(), patterns[k].size_bytes());
    EXPECT_EQ(mismatches(back.data(), patterns[k].data(), back.size()), 0u) << "GL_BACK differs, pattern " << k;
    auto f = (*cam)->capture(1000ms);
    ASSERT_TRUE(f.ok()) << f.status().to_string();
    EXPECT_EQ(mismatches(f->image.data(), patterns[k].data(), back.size()), 0u) << "X grab differs, pattern " << k;
    EXPECT_GE(f->timestamp_ns, pres->shown_ns);
  }
  std::printf("screen camera grab: %.2f ms mean for 1280x800\n", (*cam)->stats()["grab_ms_mean"].get<double>());
}

TEST(GlfwProjector, ResponseLutIsApplied) {
  XServer x = XServer::xvfb("640x480");
  ASSERT_TRUE(x.ok());
  auto c = glfw::parse_glfw_projector_config({{"backend", "glfw"}, {"gamma", 2.2}, {"keep_backbuffer", true}}, {});
  ASSERT_TRUE(c.ok()) << c.status().to_string();
  auto p = glfw::GlfwProjector::open(*c);
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  Image ramp(640, 480, PixelType::u8);
  for (uint32_t y = 0; y < 480; ++y)
    for (uint32_t xx = 0; xx < 640; ++xx) ramp.at<uint8_t>(xx, y) = static_cast<uint8_t>(xx % 256);
  ASSERT_TRUE((*p)->show(ramp.view(), 1).ok());
  ASSERT_TRUE((*p)->wait_presented(1, 2000ms).ok());
  auto back = (*p)->last_backbuffer();
  ASSERT_EQ(back.size(), ramp.size_bytes());
  size_t bad = 0;
  for (uint32_t xx = 0; xx < 640; ++xx) bad += back[200 * 640 + xx] != c->lut[xx % 256];
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(c->lut[0], 0);
  EXPECT_EQ(c->lut[255], 255);
  EXPECT_GT(c->lut[64], 64);  // 1/gamma brightens mid-tones
}

TEST(GlfwProjector, AbsentMonitorAndDisplayAreReportedClearly) {
  XServer x = XServer::xvfb("640x480");
  ASSERT_TRUE(x.ok());
  glfw::GlfwProjectorConfig c;
  c.monitor = "HDMI-7";
  auto p = glfw::GlfwProjector::open(c);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.status().code(), Code::not_found);
  const std::string msg = p.status().to_string();
  EXPECT_NE(msg.find("HDMI-7"), std::string::npos) << msg;
  EXPECT_NE(msg.find("0: '"), std::string::npos) << "lists the monitors: " << msg;
  c.monitor = "3";
  EXPECT_EQ(glfw::GlfwProjector::open(c).status().code(), Code::not_found);
  c.monitor = "0";
  c.width = 1920;
  c.height = 1080;
  auto wrong = glfw::GlfwProjector::open(c);
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.status().to_string().find("640x480"), std::string::npos) << wrong.status().to_string();
  x.stop();  // no display at all
  unsetenv("DISPLAY");
  auto none = glfw::GlfwProjector::open(glfw::GlfwProjectorConfig{});
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.status().code(), Code::unavailable);
  EXPECT_NE(none.status().to_string().find("DISPLAY"), std::string::npos) << none.status().to_string();
}

// Two monitors (Xorg dummy): the projector opens on the monitor named or
// indexed in the config, and shows exactly there.
TEST(GlfwProjector, PicksTheMonitorByNameOrIndexOnTwoMonitors) {
  if (geteuid() != 0) GTEST_SKIP() << "Xorg with the dummy driver needs root here (make test runs as root)";
  char tmpl[] = "/tmp/procam-xorg-XXXXXX";
  ASSERT_NE(mkdtemp(tmpl), nullptr);
  XServer x = XServer::xorg_dummy_two_monitors(tmpl);
  ASSERT_TRUE(x.ok()) << "could not start Xorg with the dummy driver (xserver-xorg-video-dummy, xrandr)";
  auto mons = glfw::list_glfw_monitors();
  ASSERT_TRUE(mons.ok()) << mons.status().to_string();
  ASSERT_GE(mons->size(), 1u) << mons->dump();
  EXPECT_EQ((*mons)[0]["name"], "DUMMY0") << mons->dump();
  if (mons->size() < 2u) {
    // GLFW 3.3.8 reads XRRGetScreenResourcesCurrent (cached connection
    // state); x_server.hpp runs a full `xrandr --query` probe so DUMMY1 shows
    // up. Should a server still hide it, say so instead of failing obscurely.
    x.stop();
    std::error_code ec;
    std::filesystem::remove_all(tmpl, ec);
    GTEST_SKIP() << "GLFW lists " << mons->size() << " monitor(s) on the Xorg dummy server although xrandr enabled two: "
                 << mons->dump();
  }
  for (const std::string sel : {"DUMMY1", "1"}) {
    glfw::GlfwProjectorConfig c;
    c.monitor = sel;
    c.keep_backbuffer = true;
    auto p = glfw::GlfwProjector::open(c);
    ASSERT_TRUE(p.ok()) << sel << ": " << p.status().to_string();
    EXPECT_EQ((*p)->info().name, "DUMMY1");
    EXPECT_EQ((*p)->info().width, 1024u);
    EXPECT_EQ((*p)->info().height, 768u);
    EXPECT_EQ((*p)->info().screen_x, 1280);
    Image pat = noise(1024, 768, 11);
    ASSERT_TRUE((*p)->show(pat.view(), 1).ok());
    ASSERT_TRUE((*p)->wait_presented(1, 2000ms).ok());
    screencam::ScreenCameraConfig sc;
    sc.x = 1280;
    sc.width = 1024;
    sc.height = 768;
    auto cam = screencam::ScreenCamera::open(sc);
    ASSERT_TRUE(cam.ok()) << cam.status().to_string();
    auto f = (*cam)->capture(1000ms);
    ASSERT_TRUE(f.ok());
    EXPECT_EQ(mismatches(f->image.data(), pat.data(), pat.size_bytes()), 0u) << "monitor " << sel;
  }
  glfw::GlfwProjectorConfig c;
  c.monitor = "DUMMY0";
  auto p0 = glfw::GlfwProjector::open(c);
  ASSERT_TRUE(p0.ok()) << p0.status().to_string();
  EXPECT_EQ((*p0)->info().width, 1280u);
  EXPECT_EQ((*p0)->info().screen_x, 0);
  p0 = Result<std::unique_ptr<glfw::GlfwProjector>>(Error(Code::internal, "closed"));
  x.stop();
  std::error_code ec;
  std::filesystem::remove_all(tmpl, ec);
}

}  // namespace
}  // namespace procam::testing
