// SPDX-License-Identifier: MIT
// Helmholtz stereo in a medium (Eq. 5.32-5.34) against the renderer's truth
// depth and normals, and against the medium-free Helmholtz stereo (Zickler et
// al.) on the same images.
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <cstdio>
#include <numbers>

#include "helmholtz.hpp"
#include "normal_integration.hpp"
#include "test_rig.hpp"

namespace procam::media_stereo {
namespace {

constexpr uint32_t kW = 64, kH = 48;
constexpr double kF = 87.0;
constexpr int kPairs = 8;

// Eight reciprocal pairs: a 200 mm source-sensor arm through the reference
// camera at the origin, turned in 22.5-degree steps (§5.4.2, Fig. 5.17). The
// surfaces are untextured (constant albedo): Helmholtz stereo needs no
// texture, and texture makes s3/s2 jump between depth samples.
HelmholtzInput capture(const SyntheticScene& scene, const MediumParams& m, RenderedView* truth) {
  HelmholtzInput in;
  in.reference = look_at_camera(kW, kH, kF, {0, 0, 0}, {0, 0, 520});
  in.light_intensity = test::kLightIntensity;
  in.medium = m;
  for (int j = 0; j < kPairs; ++j) {
    const double a = j * std::numbers::pi / kPairs;
    const Vec3 pa{100 * std::cos(a), 100 * std::sin(a), 0};
    ReciprocalPair pr;
    pr.cam_a = look_at_camera(kW, kH, kF, pa, {0, 0, 520});
    pr.cam_b = look_at_camera(kW, kH, kF, -pa, {0, 0, 520});
    pr.image_a = render(scene, pr.cam_a, pr.cam_b.centre(), test::kLightIntensity, m).image;
    pr.image_b = render(scene, pr.cam_b, pr.cam_a.centre(), test::kLightIntensity, m).image;
    in.pairs.push_back(std::move(pr));
  }
  if (truth) *truth = render(scene, in.reference, {0, 0, 0}, test::kLightIntensity, {});
  return in;
}

SyntheticScene untextured(SceneKind k) {
  SyntheticScene s = test::scene_of(k);
  s.textured = false;
  return s;
}

DepthSearch search() {
  DepthSearch d;
  d.window = 5;
  d.z_min_mm = 420;
  d.z_max_mm = 640;
  d.z_step_mm = 1;
  d.min_signal = 1e-4;
  return d;
}

struct Errors {
  double normal_median_deg = 0, normal_p90_deg = 0, depth_rms_mm = 0, valid = 0;
};

Errors errors(const HelmholtzResult& r, const RenderedView& t) {
  std::vector<double> ang, dz;
  size_t total = 0;
  for (uint32_t y = 3; y + 3 < kH; ++y)
    for (uint32_t x = 3; x + 3 < kW; ++x) {
      const size_t i = size_t{y} * kW + x;
      if (!std::isfinite(t.depth_mm[i])) continue;
      ++total;
      if (!std::isfinite(r.depth_mm[i])) continue;
      EXPECT_TRUE(std::isfinite(r.normal[i].x) && std::isfinite(r.normal[i].y) && std::isfinite(r.normal[i].z));
      ang.push_back(std::acos(std::clamp(dot(r.normal[i], t.normal[i]), -1.0, 1.0)) * 180 / std::numbers::pi);
      dz.push_back(static_cast<double>(r.depth_mm[i]) - static_cast<double>(t.depth_mm[i]));
    }
  return {test::percentile(ang, 0.5), test::percentile(ang, 0.9), test::rms(dz),
          total ? static_cast<double>(ang.size()) / static_cast<double>(total) : 0.0};
}

class HelmholtzScenes : public ::testing::TestWithParam<SceneKind> {};

// Claim: with the backscatter removed, normals within 3.5 deg (median) and
// 16 deg (90th pct) of the truth on >= 90 % of the pixels; the medium-free
// Helmholtz stereo on the same images is worse in median normal angle by
// >= 3x. Depth from the rank condition alone is coarse on these untextured
// surfaces (RMS < 35 mm asserted; the thesis integrates the normals for depth,
// which is not done here).
TEST_P(HelmholtzScenes, BackscatterRemovalRecoversDepthAndNormals) {
  RenderedView truth;
  const auto in = capture(untextured(GetParam()), test::tank_medium(), &truth);
  const Errors em = errors(helmholtz_stereo(in, search(), true), truth);
  const Errors ez = errors(helmholtz_stereo(in, search(), false), truth);
  std::printf("scene %d: media normal median %.2f p90 %.2f deg depth rms %.2f mm valid %.3f | zickler normal median "
              "%.2f p90 %.2f deg depth rms %.2f mm valid %.3f\n",
              static_cast<int>(GetParam()), em.normal_median_deg, em.normal_p90_deg, em.depth_rms_mm, em.valid,
              ez.normal_median_deg, ez.normal_p90_deg, ez.depth_rms_mm, ez.valid);
  EXPECT_LT(em.normal_median_deg, 3.5);
  EXPECT_LT(em.normal_p90_deg, 16.0);
  EXPECT_LT(em.depth_rms_mm, 35.0);
  EXPECT_GE(em.valid, 0.9);
  EXPECT_GE(ez.normal_median_deg, 3.0 * em.normal_median_deg);
}

// Fig. 5.18: the Helmholtz normals integrated (normal_integration.hpp), seeded
// by the rank-minimum depth, against the renderer's truth depth.
TEST_P(HelmholtzScenes, IntegratedNormalsImproveTheRankMinimumDepth) {
  RenderedView truth;
  const auto in = capture(untextured(GetParam()), test::tank_medium(), &truth);
  const HelmholtzResult r = helmholtz_stereo(in, search(), true);
  HelmholtzResult integrated = r;
  integrated.depth_mm = integrate_normals(in.reference, r.normal, r.depth_mm);
  const Errors rank = errors(r, truth), integ = errors(integrated, truth);
  // Shape: the error left after removing its median (the seed's offset).
  std::vector<double> e;
  for (size_t i = 0; i < truth.depth_mm.size(); ++i)
    if (std::isfinite(integrated.depth_mm[i]) && std::isfinite(truth.depth_mm[i]))
      e.push_back(static_cast<double>(integrated.depth_mm[i] - truth.depth_mm[i]));
  const double offset = test::percentile(e, 0.5);
  for (double& v : e) v -= offset;
  std::printf("scene %d: depth RMS rank minimum %.2f mm -> integrated normals %.2f mm (valid %.3f), offset %.2f mm, "
              "shape RMS %.2f mm\n",
              static_cast<int>(GetParam()), rank.depth_rms_mm, integ.depth_rms_mm, integ.valid, offset, test::rms(e));
  // Measured: 10.5 -> 5.5 (shape 0.40), 33.0 -> 8.7 (shape 12.8), 21.9 -> 18.6
  // (shape 20.4) mm. The offset is the seed's mean error over each region
  // the gradients connect (the half-sphere is cut from its board at the
  // grazing rim); the inclined plane's shape error is its normals' bias
  // (median 2 deg) integrated over 370 mm.
  EXPECT_GE(integ.valid, 0.9);
  EXPECT_LT(integ.depth_rms_mm, rank.depth_rms_mm);
  EXPECT_LT(test::rms(e), GetParam() == SceneKind::fronto_plane ? 1.0 : 25.0);
}

INSTANTIATE_TEST_SUITE_P(Objects, HelmholtzScenes,
                         ::testing::Values(SceneKind::fronto_plane, SceneKind::inclined_plane, SceneKind::half_sphere));

// Clear air: with nothing to remove both variants give identical maps and
// find the truth. (A reciprocal specular lobe, scene.specular, gave a 10 deg
// median at this resolution: not asserted, see docs/media-stereo.md.)
TEST(Helmholtz, ClearAirMatchesTruthAndZickler) {
  RenderedView truth;
  auto scene = untextured(SceneKind::half_sphere);
  const auto in = capture(scene, {}, &truth);
  const auto a = helmholtz_stereo(in, search(), true), b = helmholtz_stereo(in, search(), false);
  for (size_t i = 0; i < a.depth_mm.size(); ++i)
    if (!std::isnan(a.depth_mm[i])) {
      ASSERT_EQ(a.depth_mm[i], b.depth_mm[i]);
    }
  const Errors e = errors(a, truth);
  std::printf("clear air: normal median %.2f p90 %.2f deg depth rms %.2f mm valid %.3f\n",
              e.normal_median_deg, e.normal_p90_deg, e.depth_rms_mm, e.valid);
  EXPECT_LT(e.normal_median_deg, 3.5);
  EXPECT_LT(e.depth_rms_mm, 35.0);
}

// The integrator alone: the renderer's exact normals and a seed 25 mm off in
// a pseudo-random pattern give back the truth depth (the seed only fixes the
// constant); grazing and invalid pixels stay NaN.
TEST(NormalIntegration, ExactNormalsRecoverTruthDepthFromANoisySeed) {
  for (SceneKind k : {SceneKind::fronto_plane, SceneKind::inclined_plane, SceneKind::half_sphere}) {
    const PinholeCamera cam = look_at_camera(kW, kH, kF, {0, 0, 0}, {0, 0, 520});
    const RenderedView t = render(untextured(k), cam, {0, 0, 0}, test::kLightIntensity, {});
    std::vector<float> seed = t.depth_mm;
    std::vector<Vec3> normals = t.normal;
    uint32_t state = 12345;
    for (size_t i = 0; i < seed.size(); ++i) {
      state = state * 1664525u + 1013904223u;
      seed[i] += static_cast<float>(25.0 * ((state >> 8) / 16777216.0 * 2 - 1));
      if (!std::isfinite(t.depth_mm[i])) normals[i] = {NAN, NAN, NAN};
    }
    const auto z = integrate_normals(cam, normals, seed);
    std::vector<double> e, e_seed;
    for (size_t i = 0; i < z.size(); ++i) {
      if (!std::isfinite(t.depth_mm[i])) {
        EXPECT_TRUE(std::isnan(z[i]));
        continue;
      }
      if (!std::isfinite(z[i])) continue;
      e.push_back(static_cast<double>(z[i] - t.depth_mm[i]));
      e_seed.push_back(static_cast<double>(seed[i] - t.depth_mm[i]));
    }
    std::printf("scene %d: exact normals, seed RMS %.1f mm -> integrated RMS %.3f mm over %zu px\n",
                static_cast<int>(k), test::rms(e_seed), test::rms(e), e.size());
    // Planes: 0.39 / 0.40 mm measured. The half-sphere (2.1 mm): the
    // two-pixel gradient average is crude where the surface curves away
    // towards its rim (edges steeper than 2 %/px are dropped there).
    EXPECT_LT(test::rms(e), k == SceneKind::half_sphere ? 3.0 : 0.6);
    EXPECT_GT(static_cast<double>(e.size()), 0.9 * static_cast<double>(e_seed.size()));
  }
}

TEST(Helmholtz, ZeroSignalAndTooFewPairsAreInvalid) {
  RenderedView truth;
  auto in = capture(untextured(SceneKind::fronto_plane), {}, &truth);
  for (auto& pr : in.pairs) {
    std::fill(pr.image_a.begin(), pr.image_a.end(), 0.0f);
    std::fill(pr.image_b.begin(), pr.image_b.end(), 0.0f);
  }
  const auto r = helmholtz_stereo(in, search(), true);
  for (float v : r.depth_mm) ASSERT_TRUE(std::isnan(v));
  in.pairs.resize(2);
  const auto r2 = helmholtz_stereo(in, search(), true);
  for (float v : r2.depth_mm) ASSERT_TRUE(std::isnan(v));
}

}  // namespace
}  // namespace procam::media_stereo
