// SPDX-License-Identifier: MIT
// Participating media (medium.hpp, docs/media.md): polarization through the
// renderer (Malus' law, depolarized surfaces), the D/A/B magnitudes of the
// chart tanks, the ground-truth maps and the sim rig end to end.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "medium_test_util.hpp"
#include "procam/hw/sim/ground_truth.hpp"
#include "procam/hw/sim/sensor.hpp"

namespace procam::sim {
namespace {

using namespace test;  // the medium test helpers (medium_test_util.hpp)

// ---- polarization ----------------------------------------------------------------

TEST(MediumPolarization, SurfaceLightIsDepolarizedAnAnalyserPassesHalf) {
  const SimRigConfig rig = small_rig();
  auto r = renderer_for(plane_with(""), rig);
  ASSERT_TRUE(r);
  auto white = emitted_pattern(rig.projector, std::vector<float>(1280 * 800, 1.f));
  const auto open = render(*r, white);
  r->set_polarization(20, 73);
  const auto analysed = render(*r, white);
  for (size_t i = 0; i < open.size(); ++i) ASSERT_EQ(analysed[i], static_cast<double>(0.5f * static_cast<float>(open[i])));
}

// Malus' law for partially polarized light: I(ψ) = (I + Q cos2φ + U sin2φ)/2,
// so I(ψ) + I(ψ + 90°) = I without analyser, and three angles predict a fourth.
TEST(MediumPolarization, BackscatterFollowsMalusLaw) {
  const SimRigConfig rig = small_rig();
  auto r = renderer_for(shipped_scene("media-chart-moderate"), rig);
  ASSERT_TRUE(r);
  auto white = emitted_pattern(rig.projector, std::vector<float>(1280 * 800, 1.f));
  for (double pol : {kNaN, 0.0, 30.0, 90.0}) {
    r->set_polarization(pol, kNaN);
    const auto open = render(*r, white, Renderer::Parts::volume_only);
    std::vector<std::vector<double>> at;
    for (double psi : {0.0, 45.0, 90.0, 135.0, 20.0}) {
      r->set_polarization(pol, psi);
      at.push_back(render(*r, white, Renderer::Parts::volume_only));
    }
    double max_dop = 0;
    for (size_t i = 0; i < open.size(); i += 7) {
      if (!(open[i] > 0)) continue;
      ASSERT_NEAR(at[0][i] + at[2][i], open[i], 1e-5 * open[i]);
      ASSERT_NEAR(at[1][i] + at[3][i], open[i], 1e-5 * open[i]);
      // From ψ = 0, 45, 90: I/2 ± Q'/2, I/2 + U'/2 (frame-rotated Stokes); predict ψ = 20°.
      const double i0 = at[0][i], i45 = at[1][i], i90 = at[2][i];
      const double qq = i0 - i90, uu = 2 * i45 - (i0 + i90);
      const double c = std::cos(40 * M_PI / 180), s = std::sin(40 * M_PI / 180);
      ASSERT_NEAR(at[4][i], 0.5 * ((i0 + i90) + qq * c + uu * s), 1e-5 * open[i]);
      max_dop = std::max(max_dop, std::hypot(qq, uu) / open[i]);
    }
    // Backscatter of polarized light stays strongly polarized (appendix, Fig. 5.19).
    if (std::isfinite(pol)) EXPECT_GT(max_dop, 0.5) << pol;
    else EXPECT_LT(max_dop, 0.2) << "near-backward single scattering of unpolarized light is weakly polarized";
  }
}

TEST(MediumPolarization, DepolarizingMediumPassesHalfAtAnyAngle) {
  const SimRigConfig rig = small_rig();
  auto r = renderer_for(plane_with(R"({"sigma_t_per_mm": 0.003, "sigma_s_per_mm": 0.003, "g": 0.8,
      "dop_model": "none"})"), rig);
  ASSERT_TRUE(r);
  auto white = emitted_pattern(rig.projector, std::vector<float>(1280 * 800, 1.f));
  const auto open = render(*r, white, Renderer::Parts::volume_only);
  r->set_polarization(10, 100);
  const auto analysed = render(*r, white, Renderer::Parts::volume_only);
  for (size_t i = 0; i < open.size(); ++i) ASSERT_NEAR(analysed[i], 0.5 * open[i], 1e-6 * open[i]);
}

// Stretch: a Monte Carlo reference with multiple scattering. With one vertex
// it estimates the single-scattering integral (checks the renderer's B
// independently of its quadrature); in a thin, small tank the

TEST(MediumClaims, HeavierMilkLowersTheDirectShareAndRaisesBackscatter) {
  const SimRigConfig rig = small_rig();
  auto white = emitted_pattern(rig.projector, std::vector<float>(1280 * 800, 1.f));
  double ratio_db[2] = {0, 0}, direct_share[2] = {0, 0};
  const char* names[2] = {"media-chart-moderate", "media-chart-heavy"};
  for (int k = 0; k < 2; ++k) {
    auto r = renderer_for(shipped_scene(names[k]), rig);
    ASSERT_TRUE(r);
    std::vector<float> af(r->view().pixel_count());
    ASSERT_TRUE(r->render_component(white, af.data(), "medium-indirect").ok());
    const auto d = render(*r, white, Renderer::Parts::direct_only), b = render(*r, white, Renderer::Parts::volume_only);
    double sd = 0, sa = 0, sb = 0;
    for (size_t i = 0; i < d.size(); ++i)
      if (r->view().object[i] == 1) {  // the white patch (albedo 0.8)
        sd += d[i];
        sa += static_cast<double>(af[i]);
        sb += b[i];
      }
    ASSERT_GT(sd, 0);
    ratio_db[k] = sb / sd;
    direct_share[k] = sd / (sd + sa);
    std::printf("%s white patch: D %.4g  A %.4g  B %.4g ru (sums), B/D %.3f, D/(D+A) %.3f\n", names[k], sd, sa, sb,
                ratio_db[k], direct_share[k]);
  }
  EXPECT_GT(ratio_db[1], 4 * ratio_db[0]);
  EXPECT_LT(direct_share[1], direct_share[0]);
}

// ---- ground truth ----------------------------------------------------------------

TEST(MediumTruth, MapsHoldDAandBAndTheDopOfB) {
  const SimRigConfig rig = small_rig();
  const Scene scene = shipped_scene("media-chart-moderate");
  auto r = renderer_for(scene, rig);
  ASSERT_TRUE(r);
  const SensorModel& s = rig.cameras[0].sensor;
  hw::GroundTruth gt;
  ASSERT_TRUE(add_medium_components(gt, *r, &*scene.medium, rig.projector, s, 12000, 0, 0.0).ok());
  ASSERT_FALSE(gt.medium_backscatter.empty());
  EXPECT_DOUBLE_EQ(gt.medium["extinction_per_mm"].get<double>(), scene.medium->sigma_t_per_mm);
  auto white = emitted_pattern(rig.projector, std::vector<float>(1280 * 800, 1.f));
  // White through the projector's emission curve is emitted 1.
  const auto b = render(*r, white, Renderer::Parts::volume_only), d = render(*r, white, Renderer::Parts::direct_only);
  const double k = expected_dn(s, 1.0, 12000, 0);
  size_t with_b = 0;
  for (size_t i = 0; i < b.size(); ++i) {
    EXPECT_NEAR(static_cast<double>(gt.medium_backscatter.ptr<float>()[i]), b[i] * k, 1e-5 * b[i] * k + 1e-9);
    EXPECT_NEAR(static_cast<double>(gt.medium_direct.ptr<float>()[i]), d[i] * k, 1e-5 * d[i] * k + 1e-9);
    EXPECT_GE(gt.medium_indirect.ptr<float>()[i], 0.f);
    const float dop = gt.medium_backscatter_dop.ptr<float>()[i];
    if (b[i] > 0) {
      ASSERT_TRUE(dop >= 0.f && dop <= 1.f) << dop;
      ++with_b;
    } else {
      EXPECT_TRUE(std::isnan(dop));
    }
  }
  EXPECT_GT(with_b, b.size() * 9 / 10);
  hw::GroundTruth none;
  ASSERT_TRUE(add_medium_components(none, *renderer_for(plane_with(""), rig), nullptr, rig.projector, s, 12000, 0,
                                    kNaN).ok());
  EXPECT_TRUE(none.medium_backscatter.empty());
}

// The rig end to end: the frame settings' polariser / analyser change the
// frame in a medium (polarized flood: crossed vs parallel analyser), and the
// rig's ground truth carries and writes the medium maps.
TEST(MediumRig, PolariserAndAnalyserTakeEffectAndTruthIsWritten) {
  nlohmann::json j = test::read_json(test::configs_dir() + "/rigs/sim.json");
  j["scene"] = "media-chart-heavy";
  j["threads"] = 2;
  j["cameras"][0]["intrinsics"] = {{"width", 160}, {"height", 100}, {"fx", 225.0}, {"fy", 225.0}, {"cx", 79.5}, {"cy", 49.5}};
  j["cameras"][0]["shot_noise"] = false;
  j["cameras"][0]["read_noise_e"] = 0;
  j["cameras"][0]["bit_depth"] = 12;
  auto cfg = parse_sim_rig_config(j);
  ASSERT_TRUE(cfg.ok()) << cfg.status().to_string();
  auto rig = SimRig::create(*cfg, {test::configs_dir() + "/rigs", {test::configs_dir() + "/scenes"}});
  ASSERT_TRUE(rig.ok()) << rig.status().to_string();
  SimRig& r = **rig;
  Image white(1280, 800, PixelType::u8);
  std::fill(white.data(), white.data() + white.size_bytes(), uint8_t{255});
  ASSERT_TRUE(r.projector().show(white.view(), 1).ok());
  auto mean_dn = [&](double analyser) {
    hw::CameraSettings s;
    s.polarizer_deg = analyser;
    EXPECT_TRUE(r.camera(0).configure(s).ok());
    auto f = r.camera(0).capture(std::chrono::milliseconds(100));
    EXPECT_TRUE(f.ok());
    double sum = 0;
    const auto* p = reinterpret_cast<const uint16_t*>(f->image.data());
    for (size_t i = 0; i < f->image.pixel_count(); ++i) sum += p[i];
    return sum / static_cast<double>(f->image.pixel_count());
  };
  ASSERT_TRUE(r.projector().set_polarizer_deg(0).ok());
  const double open = mean_dn(kNaN), a0 = mean_dn(0), a90 = mean_dn(90);
  // Backscatter keeps the projector's polarization: one analyser angle blocks
  // most of it, the other passes most; surface light (D and A) is halved by both.
  // Measured a0/a90 = 1.32 since A is forward scattering on both legs (the
  // surface light D + A grew from ~3 D to ~9 D here); it was > 1.5 with A on
  // the projector's leg only. Bound lowered from 1.5 to 1.25 for that reason.
  EXPECT_GT(std::max(a0, a90), 1.25 * std::min(a0, a90)) << a0 << " " << a90;
  EXPECT_NEAR(a0 + a90, open, 0.01 * open);
  EXPECT_LT(a90, a0) << "near-backward scattering keeps the polarization direction: the crossed analyser is best";
  ASSERT_TRUE(r.projector().set_polarizer_deg(45).ok());
  EXPECT_LT(mean_dn(135), mean_dn(45)) << "the same at 45 degrees";
  auto gt = r.ground_truth(0);
  ASSERT_TRUE(gt.ok()) << gt.status().to_string();
  ASSERT_FALSE(gt->medium_backscatter.empty());
  EXPECT_NEAR(gt->medium["scattering_per_mm"].get<double>(), 0.010744, 1e-12);
  // The heavy tank's B is mostly multiple-scattered (media-chart-heavy turns
  // it on, docs/media.md "Multiple scattering"): polarized light backscatters
  // partly polarized, DOP ≈ 0.3 (single scattering alone: ≈ 1).
  size_t partly = 0;
  for (size_t i = 0; i < gt->medium_backscatter_dop.pixel_count(); ++i) {
    const float dop = gt->medium_backscatter_dop.ptr<float>()[i];
    partly += dop > 0.15f && dop < 0.6f;
  }
  EXPECT_GT(partly, gt->medium_backscatter_dop.pixel_count() * 9 / 10) << "polarized light backscatters partly polarized";
  ASSERT_TRUE(gt->medium.contains("multiple_scattering"));
  EXPECT_GT(gt->medium["multiple_scattering"]["ratio_to_single"].get<double>(), 2.0);
  const std::string dir = test::temp_dir("medium_truth");
  ASSERT_TRUE(write_ground_truth(*gt, dir).ok());
  EXPECT_TRUE(std::filesystem::exists(dir + "/medium_backscatter.exr"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/medium_backscatter_dop.exr"));
}

}  // namespace
}  // namespace procam::sim
