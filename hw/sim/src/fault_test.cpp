// SPDX-License-Identifier: MIT
// Fault injection of the sim rig: dropped projector frames (wait_presented
// times out, the screen keeps the old pattern), late presentation and late
// exposures (timestamps shifted by late_ms), lost camera frames (frame-id
// gaps), camera timeouts, counters in describe()["state"]["faults"], and
// config errors naming the field.
#include <gtest/gtest.h>
#include <time.h>

#include "procam/hw/sim/sim_rig.hpp"
#include "test_util.hpp"

namespace procam::sim {
namespace {

using namespace std::chrono_literals;

std::unique_ptr<SimRig> make_rig(const nlohmann::json& j) {
  auto cfg = parse_sim_rig_config(j);
  EXPECT_TRUE(cfg.ok()) << cfg.status().to_string();
  if (!cfg.ok()) return nullptr;
  auto rig = SimRig::create(*cfg, {test::configs_dir() + "/rigs", {test::configs_dir() + "/scenes"}});
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  return rig.ok() ? std::move(rig).value() : nullptr;
}
int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1000000000LL + ts.tv_nsec;
}
Image constant(uint8_t v) {
  Image im(1280, 800, PixelType::u8);
  std::fill(im.data(), im.data() + im.size_bytes(), v);
  return im;
}
double mean(const Image& im) {
  double s = 0;
  for (size_t i = 0; i < im.size_bytes(); ++i) s += im.data()[i];
  return s / static_cast<double>(im.size_bytes());
}

TEST(Faults, ProjectorDropsAndLatePresentations) {
  auto j = test::read_json(test::configs_dir() + "/rigs/sim.json");
  j["projector"]["faults"] = {{"drop_every", 3}, {"late_every", 2}, {"late_ms", 40}};
  auto rig = make_rig(j);
  ASSERT_TRUE(rig);
  hw::Projector& proj = rig->projector();
  hw::Camera& cam = rig->camera(0);
  const Image white = constant(255), black = constant(0);
  // show #1 (white): fine; #2 (black): late; #3 (white): dropped.
  ASSERT_TRUE(proj.show(white.view(), 1).ok());
  int64_t t0 = now_ns();
  auto p1 = proj.wait_presented(1, 100ms);
  ASSERT_TRUE(p1.ok());
  EXPECT_LE(p1->shown_ns, now_ns());
  ASSERT_TRUE(proj.show(black.view(), 2).ok());
  t0 = now_ns();
  auto p2 = proj.wait_presented(2, 100ms);
  ASSERT_TRUE(p2.ok());
  EXPECT_GE(p2->shown_ns, t0 + 40'000'000);  // reported 40 ms late
  ASSERT_TRUE(proj.show(white.view(), 3).ok());
  auto p3 = proj.wait_presented(3, 100ms);
  ASSERT_FALSE(p3.ok());
  EXPECT_EQ(p3.status().code(), Code::timeout);
  // The screen still shows pattern 2 (black): the capture is dark.
  auto f = cam.capture(100ms);
  ASSERT_TRUE(f.ok());
  EXPECT_LT(mean(f->image), 30.0);
  const auto st = rig->describe()["state"]["faults"]["projector"];
  EXPECT_EQ(st["shows"], 3);
  EXPECT_EQ(st["dropped"], 1);
  EXPECT_EQ(st["late"], 1);
}

TEST(Faults, CameraTimeoutsLostFramesAndLateExposures) {
  auto j = test::read_json(test::configs_dir() + "/rigs/sim.json");
  j["cameras"][0]["faults"] = {{"timeout_every", 4}, {"drop_every", 3}, {"late_every", 5}, {"late_ms", 25}};
  auto rig = make_rig(j);
  ASSERT_TRUE(rig);
  const Image white = constant(255);
  ASSERT_TRUE(rig->projector().show(white.view(), 1).ok());
  hw::Camera& cam = rig->camera(0);
  std::vector<uint64_t> ids;
  size_t timeouts = 0;
  for (int k = 1; k <= 10; ++k) {
    const int64_t t0 = now_ns();
    auto f = cam.capture(50ms);
    if (k % 4 == 0) {
      ASSERT_FALSE(f.ok()) << k;
      EXPECT_EQ(f.status().code(), Code::timeout);
      ++timeouts;
      continue;
    }
    ASSERT_TRUE(f.ok()) << k;
    ids.push_back(f->frame_id);
    if (k % 5 == 0) EXPECT_GE(f->timestamp_ns, t0 + 25'000'000) << k;
    else EXPECT_LE(f->timestamp_ns, now_ns()) << k;
  }
  // Captures 1..10 minus the timeouts at 4 and 8; the frames lost at 3, 6
  // and 9 leave gaps in the ids (3, 6, 9 never delivered).
  EXPECT_EQ(ids, (std::vector<uint64_t>{1, 2, 4, 5, 7, 8, 10, 11}));
  const auto st = rig->describe()["state"]["faults"]["cameras"][0];
  EXPECT_EQ(st["captures"], 10);
  EXPECT_EQ(st["timeouts"], 2);
  EXPECT_EQ(st["dropped"], 3);
  EXPECT_EQ(st["late"], 2);
}

TEST(Faults, NoFaultsNoCountersAndBadConfigNamesTheField) {
  auto j = test::read_json(test::configs_dir() + "/rigs/sim.json");
  auto rig = make_rig(j);
  ASSERT_TRUE(rig);
  EXPECT_FALSE(rig->describe()["state"].contains("faults"));
  j["cameras"][0]["faults"] = {{"late_every", 2}};
  auto bad = parse_sim_rig_config(j, "rig.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("rig.json: cameras[0].faults.late_ms"), std::string::npos)
      << bad.status().message();
  j["cameras"][0]["faults"] = {{"drop_evry", 2}};
  bad = parse_sim_rig_config(j, "rig.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("cameras[0].faults.drop_evry"), std::string::npos);
  j["cameras"][0].erase("faults");
  j["projector"]["faults"] = {{"timeout_every", 2}};  // cameras only
  bad = parse_sim_rig_config(j, "rig.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("projector.faults.timeout_every"), std::string::npos);
}

}  // namespace
}  // namespace procam::sim
