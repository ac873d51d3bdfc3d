// SPDX-License-Identifier: MIT
// The scene's dynamic Legendre medium in the sim renderer: attenuation
// against the closed form, air-light against fine quadrature, motion and
// reproducibility, parse errors.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <iostream>

#include "legendre_medium.hpp"
#include "medium_test_util.hpp"
#include "procam/hw/sim/global.hpp"
#include "procam/hw/sim/sim_rig.hpp"

namespace procam::sim::test {
namespace {

const char* kFog = R"({"box_min_mm": [-300, -200, 450], "box_max_mm": [300, 200, 760], "n": 4,
                       "density_uniform": 1.0, "sigma_t_per_mm": 0.002, "sigma_s_per_mm": 0.0})";

Scene plane_with_fog(const std::string& fog) {
  auto j = nlohmann::json::parse(kPlane);
  if (!fog.empty()) j["legendre_medium"] = nlohmann::json::parse(fog);
  auto s = parse_scene(j, "test");
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  return s.ok() ? *s : Scene{};
}

std::unique_ptr<Renderer> scene_renderer(const Scene& scene, const SimRigConfig& rig) {
  const CameraCalibration& cam = rig.cameras[0].calibration;
  auto r = make_scene_renderer(scene, rig.projector, cam, cam.cam_from_proj, GlobalOptions{}, 2);
  EXPECT_TRUE(r.ok()) << r.status().to_string();
  return r.ok() ? std::move(r).value() : nullptr;
}

// Eq. 6.4 on both legs, uniform density 1: every lit surface pixel is dimmed
// by exactly exp(-sigma (l_cam + l_proj)), the lengths inside the box.
TEST(LegendreMedium, UniformFogAttenuatesLikeTheClosedForm) {
  const SimRigConfig rig = small_rig();
  auto clear = scene_renderer(plane_with_fog(""), rig);
  auto fog = scene_renderer(plane_with_fog(kFog), rig);
  ASSERT_TRUE(clear && fog);
  PreparedPattern p = emitted_pattern(rig.projector, std::vector<float>(rig.projector.intrinsics.width *
                                                                            rig.projector.intrinsics.height, 1.f));
  const auto a = render(*clear, p), b = render(*fog, p);
  Medium box;
  box.whole_scene = false;
  box.box_min_mm = {-300, -200, 450};
  box.box_max_mm = {300, 200, 760};
  const Vec3 proj = rig.cameras[0].calibration.cam_from_proj.translation_mm;
  size_t checked = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!(a[i] > 0)) continue;
    const Vec3 pt = point_of(fog->view(), i);
    const double t = std::exp(-0.002 * (medium_length(box, {0, 0, 0}, pt) + medium_length(box, proj, pt)));
    EXPECT_NEAR(b[i], a[i] * t, 2e-5 * a[i] + 1e-7) << i;
    ++checked;
  }
  EXPECT_GT(checked, a.size() / 2);
}

// Air-light of the centre pixel (uniform density, no surface behind it in
// the box, uniform pattern that lights the whole ray) against a 4000-step
// quadrature of the same single-scattering integral: within 1% (~one
// midpoint sample per density-grid cell).
TEST(LegendreMedium, AirLightMatchesFineQuadrature) {
  const SimRigConfig rig = small_rig();
  auto fog = scene_renderer(
      plane_with_fog(R"({"box_min_mm": [-300, -200, 450], "box_max_mm": [300, 200, 760], "n": 4,
                        "density_uniform": 0.5, "sigma_t_per_mm": 0.003, "sigma_s_per_mm": 0.002, "g": 0.3})"),
      rig);
  ASSERT_TRUE(fog);
  const size_t w = rig.projector.intrinsics.width, h = rig.projector.intrinsics.height;
  PreparedPattern p = emitted_pattern(rig.projector, std::vector<float>(w * h, 0.5f));
  const auto img = render(*fog, p, Renderer::Parts::volume_only);
  const Intrinsics& k = rig.cameras[0].calibration.intrinsics;
  const uint32_t u = 80, v = 50;
  const Vec3 dir = normalized(k.ray(u, v));
  const Vec3 proj = rig.cameras[0].calibration.cam_from_proj.translation_mm;
  // The ray enters the box at z = 450 and meets the plane (z = 800) outside
  // it, so it leaves at z = 760.
  const double t0 = 450 / dir.z, t1 = 760 / dir.z;
  const int n = 4000;
  double air = 0;
  for (int s = 0; s < n; ++s) {
    const double t = t0 + (s + 0.5) * (t1 - t0) / n;
    const Vec3 y = dir * t, ly = y - proj;
    const double d2 = dot(ly, ly);
    air += 0.002 * 0.5 * hg_phase(0.3, dot(ly, -dir) / std::sqrt(d2)) * rig.projector.irradiance_at_1m * 1e6 * 0.5 /
           d2 * std::exp(-0.003 * 0.5 * (t - t0)) * (t1 - t0) / n;
  }
  EXPECT_NEAR(img[v * k.width + u], air, 0.01 * air);
  EXPECT_GT(air, 0.0);
  // Lit by the pattern: black gives no air-light, a half-lit pattern (left
  // projector columns only) lies between, and an analyser passes half.
  PreparedPattern black = emitted_pattern(rig.projector, std::vector<float>(w * h, 0.f));
  for (double x : render(*fog, black, Renderer::Parts::volume_only)) ASSERT_EQ(x, 0.0);
  std::vector<float> half(w * h, 0.f);
  for (size_t y = 0; y < h; ++y)
    for (size_t x = 0; x < w / 2; ++x) half[y * w + x] = 0.5f;
  PreparedPattern hp = emitted_pattern(rig.projector, half);
  const auto hi = render(*fog, hp, Renderer::Parts::volume_only);
  double sum_full = 0, sum_half = 0;
  for (size_t i = 0; i < img.size(); ++i) sum_full += img[i], sum_half += hi[i];
  EXPECT_GT(sum_half, 0.2 * sum_full);
  EXPECT_LT(sum_half, 0.8 * sum_full);
  fog->set_polarization(std::nan(""), 0.0);
  const auto an = render(*fog, p, Renderer::Parts::volume_only);
  for (size_t i = 0; i < img.size(); ++i) ASSERT_NEAR(an[i], 0.5 * img[i], 1e-6 * img[i] + 1e-12);
}

// A blob carried by the swirl: the air-light image changes with time, its
// centroid moves, and asking for t = 0 again gives the first image back.
TEST(LegendreMedium, DriftingBlobMovesAndRewindsExactly) {
  const SimRigConfig rig = small_rig();
  auto fog = scene_renderer(
      plane_with_fog(R"({"box_min_mm": [-300, -200, 450], "box_max_mm": [300, 200, 760], "n": 6,
                        "blobs": [{"center_mm": [120, 0, 600], "radius_mm": 120, "peak": 1.0}],
                        "swirl_mm_s": 200, "sigma_t_per_mm": 0.002, "sigma_s_per_mm": 0.002})"),
      rig);
  ASSERT_TRUE(fog);
  const size_t w = rig.projector.intrinsics.width, h = rig.projector.intrinsics.height;
  PreparedPattern p = emitted_pattern(rig.projector, std::vector<float>(w * h, 1.f));
  auto centroid = [&](const std::vector<double>& img) {
    double sx = 0, sy = 0, s = 0;
    for (size_t i = 0; i < img.size(); ++i) {
      sx += img[i] * static_cast<double>(i % 160);
      sy += img[i] * static_cast<double>(i / 160);
      s += img[i];
    }
    return std::array<double, 3>{sx / s, sy / s, s};
  };
  ASSERT_EQ(set_legendre_time(*fog, 0.0), 0);
  const auto a = render(*fog, p, Renderer::Parts::volume_only);
  const double e0 = dynamic_cast<const LegendreMediumComponent&>(*fog->components().back()).fluid().kinetic_energy();
  EXPECT_GE(set_legendre_time(*fog, 1.0), 1);
  const auto b = render(*fog, p, Renderer::Parts::volume_only);
  const auto ca = centroid(a), cb = centroid(b);
  std::cout << "[ measured ] air-light centroid moved " << std::hypot(cb[0] - ca[0], cb[1] - ca[1])
            << " px in 1 s (160x100 camera)\n";
  // 200 mm/s swirl for 1 s: the blob (at +120 mm in x) turns by tens of mm,
  // several pixels at 225 px / 600 mm.
  EXPECT_GT(std::hypot(cb[0] - ca[0], cb[1] - ca[1]), 2.0) << ca[0] << "," << ca[1] << " -> " << cb[0] << "," << cb[1];
  EXPECT_LE(dynamic_cast<const LegendreMediumComponent&>(*fog->components().back()).fluid().kinetic_energy(),
            e0 * (1 + 1e-12));
  EXPECT_EQ(set_legendre_time(*fog, 0.0), 0);
  const auto c = render(*fog, p, Renderer::Parts::volume_only);
  for (size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a[i], c[i]) << i;
  for (double x : b) ASSERT_TRUE(std::isfinite(x));
}

// Through the rig: the shipped scene loads, and consecutive captures of a
// white frame see the fog at consecutive times (the frames differ, stay
// finite, and the medium's clock follows the frame ids).
TEST(LegendreMedium, RigCapturesSeeTheMediumMove) {
  using namespace std::chrono_literals;
  SimRigConfig cfg = small_rig();  // 160x100: the march is per pixel
  cfg.scene = "legendre-fog";
  auto rig = SimRig::create(cfg, {configs_dir() + "/rigs", {configs_dir() + "/scenes"}});
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  const Intrinsics& k = (*rig)->projector_intrinsics();
  Image white(k.width, k.height, PixelType::u8);
  std::fill(white.ptr<uint8_t>(), white.ptr<uint8_t>() + size_t{k.width} * k.height, uint8_t{255});
  ASSERT_TRUE((*rig)->projector().show(white.view(), 1).ok());
  auto f1 = (*rig)->camera(0).capture(100ms);
  for (int i = 0; i < 15; ++i) ASSERT_TRUE((*rig)->camera(0).capture(100ms).ok());
  auto f2 = (*rig)->camera(0).capture(100ms);
  ASSERT_TRUE(f1.ok() && f2.ok());
  ASSERT_EQ(f1->image.width(), f2->image.width());
  double diff = 0;
  ASSERT_EQ(f1->image.size_bytes(), f2->image.size_bytes());
  const size_t n = f1->image.size_bytes();
  const uint8_t* a = f1->image.ptr<uint8_t>();
  const uint8_t* b = f2->image.ptr<uint8_t>();
  for (size_t i = 0; i < n; ++i) diff += std::abs(int{a[i]} - int{b[i]});
  std::cout << "[ measured ] mean |frame 0 - frame 16| = " << diff / static_cast<double>(n) << " DN\n";
  EXPECT_GT(diff / static_cast<double>(n), 0.05);  // half a second of drift changes the frame
}

TEST(LegendreMedium, BadSpecsAreRefused) {
  auto bad = [](const std::string& fog) {
    auto j = nlohmann::json::parse(kPlane);
    j["legendre_medium"] = nlohmann::json::parse(fog);
    return parse_scene(j, "test");
  };
  EXPECT_FALSE(bad(R"({"box_min_mm": [0, 0, 0], "box_max_mm": [1, 1, 1], "n": 2, "sigma_t_per_mm": 0.1, "sigma_s_per_mm": 0.1})").ok());
  EXPECT_FALSE(bad(R"({"box_min_mm": [0, 0, 0], "box_max_mm": [1, 0, 1], "sigma_t_per_mm": 0.1, "sigma_s_per_mm": 0.1})").ok());
  EXPECT_FALSE(bad(R"({"box_min_mm": [0, 0, 0], "box_max_mm": [1, 1, 1], "sigma_t_per_mm": 0.1, "sigma_s_per_mm": 0.2})").ok());
  EXPECT_FALSE(bad(R"({"box_min_mm": [0, 0, 0], "box_max_mm": [1, 1, 1], "sigma_t_per_mm": 0.1, "sigma_s_per_mm": 0.1,
                       "blobs": [{"center_mm": [0, 0, 0], "radius_mm": 0}]})").ok());
  const auto ok = bad(R"({"box_min_mm": [0, 0, 0], "box_max_mm": [1, 1, 1], "sigma_t_per_mm": 0.1, "sigma_s_per_mm": 0.1})");
  ASSERT_TRUE(ok.ok()) << ok.status().to_string();
  EXPECT_EQ(ok->legendre_medium->n, 5);
}

}  // namespace
}  // namespace procam::sim::test
