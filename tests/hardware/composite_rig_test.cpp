// SPDX-License-Identifier: MIT
// Composite rig (hw/compose): the sim projector + Aravis Fake camera fed by
// the sim renders exactly what the pure sim rig renders, frame by frame.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include "procam/core/image.hpp"
#include "procam/hw/rig.hpp"

namespace procam {
namespace {

nlohmann::json read_rig(const std::string& name) {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/" + name);
  return nlohmann::json::parse(in);
}

hw::RigContext ctx() {
  hw::RigContext c;
  c.config_dir = std::string(PROCAM_SOURCE_DIR) + "/configs/rigs";
  c.scene_dirs = {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"};
  return c;
}

// A projector-sized pattern: vertical stripes of width `period`, phase `k`.
Image stripes(uint32_t w, uint32_t h, uint32_t period, uint32_t k) {
  Image im(w, h, PixelType::u8);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) im.at<uint8_t>(x, y) = ((x + k) / period) % 2 ? 255 : 0;
  return im;
}

TEST(CompositeRig, AravisFakeFedBySimDeliversTheSimFrames) {
  auto sim = hw::create_rig(read_rig("sim.json"), ctx());
  ASSERT_TRUE(sim.ok()) << sim.status().to_string();
  auto arv = hw::create_rig(read_rig("aravis-fake.json"), ctx());
  ASSERT_TRUE(arv.ok()) << arv.status().to_string();
  ASSERT_EQ((*arv)->camera(0).info().backend, "aravis");
  const auto& pi = (*sim)->projector().info();
  for (uint32_t k = 0; k < 6; ++k) {
    Image p = stripes(pi.width, pi.height, 64, k * 16);
    hw::Rig* rigs[2] = {sim->get(), arv->get()};
    Image got[2];
    for (int r = 0; r < 2; ++r) {
      ASSERT_TRUE(rigs[r]->projector().show(p.view(), k + 1).ok());
      ASSERT_TRUE(rigs[r]->projector().wait_presented(k + 1, std::chrono::milliseconds(1000)).ok());
      auto f = rigs[r]->camera(0).capture(std::chrono::milliseconds(3000));
      ASSERT_TRUE(f.ok()) << f.status().to_string();
      got[r] = std::move(f->image);
    }
    ASSERT_EQ(got[0].width(), got[1].width());
    ASSERT_EQ(got[0].height(), got[1].height());
    // Same pattern, same renderer: only sensor noise may differ (noise is
    // seeded per frame id, and the Fake device may render frames the rig
    // never returns). A wrong pattern shows up as large differences.
    size_t big = 0;
    for (size_t i = 0; i < got[0].size_bytes(); ++i)
      big += std::abs(int{got[0].data()[i]} - int{got[1].data()[i]}) > 40;
    EXPECT_LT(big, got[0].size_bytes() / 1000) << "pattern " << k << ": the Aravis frame differs from the sim frame in "
                                                << big << " pixels by > 40 levels";
  }
}

}  // namespace
}  // namespace procam

namespace procam {
namespace {

// The shipped real-hardware configs parse and fail with clear device errors
// here (no projector monitor 1 / no libcamera camera), never with a config error.
TEST(CompositeRig, ShippedHardwareConfigsGiveClearDeviceErrors) {
  unsetenv("DISPLAY");
  for (const char* name : {"glfw-aravis.json", "glfw-libcamera.json", "glfw-screencam.json"}) {
    auto r = hw::create_rig(read_rig(name), ctx());
    ASSERT_FALSE(r.ok()) << name;
    const std::string msg = r.status().to_string();
    EXPECT_EQ(r.status().code(), Code::unavailable) << name << ": " << msg;
    EXPECT_NE(msg.find("DISPLAY"), std::string::npos) << name << ": " << msg;
  }
  auto bad = read_rig("aravis-fake.json");
  bad["cameras"][0]["pixel_fromat"] = "Mono8";
  auto r = hw::create_rig(bad, ctx());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().to_string().find("cameras[0].pixel_fromat"), std::string::npos) << r.status().to_string();
}

}  // namespace
}  // namespace procam
