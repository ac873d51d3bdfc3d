// SPDX-License-Identifier: MIT
// Ground truth's direct / global maps (hw::GroundTruth) against the sim
// camera's own noise-free frame under a full-white pattern.
#include "procam/hw/sim/ground_truth.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "procam/hw/sim/sensor.hpp"
#include "procam/hw/sim/sim_rig.hpp"
#include "test_util.hpp"

namespace procam::sim {
namespace {

using namespace std::chrono_literals;

// The shipped sim rig with the sensor noise switched off, so a captured frame
// is the expected DN rounded and clamped.
std::unique_ptr<SimRig> noise_free_rig(const std::string& scene) {
  nlohmann::json j = test::read_json(test::configs_dir() + "/rigs/sim.json");
  j["cameras"][0]["read_noise_e"] = 0;
  j["cameras"][0]["shot_noise"] = false;
  j["scene"] = scene;
  auto cfg = parse_sim_rig_config(j);
  EXPECT_TRUE(cfg.ok()) << cfg.status().to_string();
  if (!cfg.ok()) return nullptr;
  auto rig = SimRig::create(*cfg, {test::configs_dir() + "/rigs", {test::configs_dir() + "/scenes"}});
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  return rig.ok() ? std::move(rig).value() : nullptr;
}

Image white_frame(SimRig& rig) {
  const Intrinsics& k = rig.projector_intrinsics();
  Image white(k.width, k.height, PixelType::u8);
  std::fill(white.data(), white.data() + white.size_bytes(), uint8_t{255});
  EXPECT_TRUE(rig.projector().show(white.view(), 1).ok());
  auto f = rig.camera(0).capture(1000ms);
  EXPECT_TRUE(f.ok()) << f.status().to_string();
  return f.ok() ? std::move(f->image) : Image();
}

// direct + global + ambient (converted to DN here from the view's ambient
// radiance) must be the white frame the camera delivers: same rendering, one
// pass over all components vs one pass per part. Tolerance: 0.5 DN of rounding
// plus 1e-4 relative float error; saturated pixels are skipped.
void expect_parts_sum_to_white_frame(const std::string& scene) {
  SCOPED_TRACE(scene);
  auto rig = noise_free_rig(scene);
  ASSERT_TRUE(rig);
  auto gt = rig->ground_truth(0);
  ASSERT_TRUE(gt.ok()) << gt.status().to_string();
  const Image frame = white_frame(*rig);
  ASSERT_EQ(frame.type(), PixelType::u8);
  ASSERT_EQ(gt->direct.width(), frame.width());
  ASSERT_EQ(gt->global.height(), frame.height());
  ASSERT_EQ(gt->direct.type(), PixelType::f32);
  const SensorModel& s = rig->config().cameras[0].sensor;
  const std::vector<float>& ambient = rig->renderer(0).view().ambient;
  size_t compared = 0;
  double worst = 0;
  for (size_t i = 0; i < frame.pixel_count(); ++i) {
    const double d = gt->direct.ptr<float>()[i], g = gt->global.ptr<float>()[i];
    ASSERT_TRUE(std::isfinite(d) && std::isfinite(g) && d >= 0 && g >= 0) << i;
    const double expected = d + g + expected_dn(s, ambient[i], s.exposure_us, s.gain_db);
    if (expected > s.max_dn() - 0.5) continue;  // clamped by the sensor
    const double err = std::abs(double(frame.ptr<uint8_t>()[i]) - expected);
    worst = std::max(worst, err - 1e-4 * expected);
    ++compared;
  }
  EXPECT_GT(compared, frame.pixel_count() / 2);
  EXPECT_LE(worst, 0.5 + 1e-6);
}

TEST(GroundTruthComponents, SumToTheNoiseFreeWhiteFrameOnPlane) { expect_parts_sum_to_white_frame("plane"); }

// The curtain sends most light by global paths (thesis Fig. 3.11): a scene
// where a wrong split would show.
TEST(GroundTruthComponents, SumToTheNoiseFreeWhiteFrameBehindCurtain) {
  expect_parts_sum_to_white_frame("shower-curtain");
}

TEST(GroundTruthComponents, PlaneHasNoGlobalLightAndCurtainHasMuch) {
  auto plane = noise_free_rig("plane");
  ASSERT_TRUE(plane);
  auto gp = plane->ground_truth(0);
  ASSERT_TRUE(gp.ok());
  double direct_sum = 0, global_max = 0;
  for (size_t i = 0; i < gp->direct.pixel_count(); ++i) {
    direct_sum += double(gp->direct.ptr<float>()[i]);
    global_max = std::max(global_max, double(gp->global.ptr<float>()[i]));
  }
  const double direct_mean = direct_sum / double(gp->direct.pixel_count());
  EXPECT_GT(direct_mean, 20.0) << "a white pattern on the plane should be well exposed";
  EXPECT_LE(global_max, 1e-3) << "a single convex plane has no global transport";

  auto curtain = noise_free_rig("shower-curtain");
  ASSERT_TRUE(curtain);
  auto gc = curtain->ground_truth(0);
  ASSERT_TRUE(gc.ok());
  double d = 0, g = 0;
  for (size_t i = 0; i < gc->direct.pixel_count(); ++i) {
    if (gc->lit.ptr<uint8_t>()[i] == 0) continue;
    d += double(gc->direct.ptr<float>()[i]);
    g += double(gc->global.ptr<float>()[i]);
  }
  EXPECT_GT(g, d) << "the scene's description: global light 2.7x the direct light";
}

TEST(GroundTruthComponents, NoDirectLightInShadowAndScaleWithExposure) {
  auto rig = noise_free_rig("tilted-box");
  ASSERT_TRUE(rig);
  auto a = rig->ground_truth(0);
  ASSERT_TRUE(a.ok());
  size_t shadow = 0;
  for (size_t i = 0; i < a->direct.pixel_count(); ++i) {
    if (a->lit.ptr<uint8_t>()[i] != 0) continue;
    ++shadow;
    ASSERT_EQ(a->direct.ptr<float>()[i], 0.0f) << "direct light in a shadow at pixel " << i;
  }
  EXPECT_GT(shadow, 1000u) << "tilted-box casts a shadow";
  const double exposure = rig->config().cameras[0].sensor.exposure_us;
  hw::CameraSettings s;
  s.exposure_us = 2 * exposure;
  ASSERT_TRUE(rig->camera(0).configure(s).ok());
  auto b = rig->ground_truth(0);
  ASSERT_TRUE(b.ok());
  for (size_t i = 0; i < a->direct.pixel_count(); i += 97) {
    const double da = a->direct.ptr<float>()[i], ga = a->global.ptr<float>()[i];
    EXPECT_NEAR(b->direct.ptr<float>()[i], 2 * da, 1e-5 * da + 1e-6);
    EXPECT_NEAR(b->global.ptr<float>()[i], 2 * ga, 1e-5 * ga + 1e-6);
  }
  EXPECT_TRUE(a->medium.is_null()) << "no scene has a medium truth yet";
}

}  // namespace
}  // namespace procam::sim
