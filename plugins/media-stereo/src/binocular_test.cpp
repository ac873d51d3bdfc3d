// SPDX-License-Identifier: MIT
// Binocular stereo in a medium (Eq. 5.22-5.23) against the renderer's truth
// depth, and against the clear-air constraint (Eq. 5.20) on the same images.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "binocular.hpp"
#include "medium_fit.hpp"
#include "test_rig.hpp"

namespace procam::media_stereo {
namespace {

struct Scan {
  RenderedView left, right;
  BinocularInput in;
};

Scan scan(SceneKind kind, const MediumParams& m) {
  const test::BinocularRig rig;
  Scan s;
  const auto scene = test::scene_of(kind);
  s.left = render(scene, rig.left, rig.light, test::kLightIntensity, m);
  s.right = render(scene, rig.right, rig.light, test::kLightIntensity, m);
  s.in = {rig.left, rig.right, s.left.image, s.right.image, rig.light, test::kLightIntensity, m, std::nullopt};
  return s;
}

DepthSearch search() {
  DepthSearch d;
  d.min_signal = 1e-4;  // ~1/1000 of the direct signal at 500 mm
  return d;
}

// Pixels whose truth point is seen by the right camera too (no occlusion).
std::vector<char> both_visible(const Scan& s) {
  std::vector<char> mask(s.left.image.size(), 0);
  for (size_t i = 0; i < mask.size(); ++i) {
    if (!std::isfinite(s.left.depth_mm[i])) continue;
    const auto x = static_cast<uint32_t>(i % s.in.left.width), y = static_cast<uint32_t>(i / s.in.left.width);
    const Vec3 p = s.in.left.centre() + s.in.left.ray_world(x, y) * static_cast<double>(s.left.depth_mm[i]);
    double u = 0, v = 0, z = 0;
    if (!s.in.right.project(p, u, v, z) || u < 4 || v < 4 || u > s.in.right.width - 5.0 || v > s.in.right.height - 5.0)
      continue;
    const auto ui = static_cast<uint32_t>(std::lround(u)), vi = static_cast<uint32_t>(std::lround(v));
    if (std::abs(static_cast<double>(s.right.depth_mm[size_t{vi} * s.in.right.width + ui]) - z) > 3.0) continue;
    mask[i] = x >= 4 && y >= 4 && x + 4 < s.in.left.width && y + 4 < s.in.left.height && s.left.direct[i] > 0.0f;
  }
  return mask;
}

struct Stats {
  double rms_mm = 0, valid = 0, median_abs_mm = 0;
};

Stats stats(const std::vector<float>& depth, const Scan& s, const std::vector<char>& mask) {
  std::vector<double> e;
  size_t total = 0;
  for (size_t i = 0; i < depth.size(); ++i) {
    if (std::isfinite(depth[i])) {
      EXPECT_GT(depth[i], 0.0f);
    }
    if (!mask[i]) continue;
    ++total;
    if (std::isfinite(depth[i])) e.push_back(static_cast<double>(depth[i]) - static_cast<double>(s.left.depth_mm[i]));
  }
  std::vector<double> a;
  for (double v : e) a.push_back(std::abs(v));
  return {test::rms(e), total ? static_cast<double>(e.size()) / static_cast<double>(total) : 0.0,
          test::percentile(a, 0.5)};
}

class BinocularScenes : public ::testing::TestWithParam<SceneKind> {};

// Claim: with the medium known, the media constraint recovers depth on >= 95 %
// of the pixels both cameras see (lit, not occluded), with RMS below 1 mm on
// the fronto-parallel plane, 2 mm on the 30-degree plane (the window assumes
// fronto-parallel patches) and 25 mm on the half-sphere (outliers on its
// grazing flanks, where the window assumption fails; median |error| < 1 mm),
// and beats the clear-air constraint by >= 3x in RMS on every object.
TEST_P(BinocularScenes, MediaConstraintBeatsClearAir) {
  const Scan s = scan(GetParam(), test::tank_medium());
  const auto mask = both_visible(s);
  const auto media = binocular_depth(s.in, search(), Constraint::media);
  const auto clear = binocular_depth(s.in, search(), Constraint::clear_air);
  const Stats sm = stats(media, s, mask), sc = stats(clear, s, mask);
  double bsum = 0, dsum = 0;
  for (size_t i = 0; i < mask.size(); ++i)
    if (mask[i]) bsum += static_cast<double>(s.left.backscatter[i]), dsum += static_cast<double>(s.left.direct[i]);
  std::printf("scene %d: B/D %.2f  media rms %.3f mm median|e| %.3f mm (valid %.3f)  clear-air rms %.3f mm median|e| "
              "%.3f mm (valid %.3f)  factor %.1f\n",
              static_cast<int>(GetParam()), bsum / dsum, sm.rms_mm, sm.median_abs_mm, sm.valid, sc.rms_mm,
              sc.median_abs_mm, sc.valid, sc.rms_mm / sm.rms_mm);
  const double max_rms = GetParam() == SceneKind::fronto_plane ? 1.0 : GetParam() == SceneKind::inclined_plane ? 2.0 : 25.0;
  EXPECT_LT(sm.rms_mm, max_rms);
  EXPECT_LT(sm.median_abs_mm, 1.0);
  EXPECT_GE(sm.valid, 0.95);
  EXPECT_GE(sc.rms_mm, 3.0 * sm.rms_mm);
}

INSTANTIATE_TEST_SUITE_P(Objects, BinocularScenes,
                         ::testing::Values(SceneKind::fronto_plane, SceneKind::inclined_plane, SceneKind::half_sphere));

TEST(Binocular, SigmaZeroReproducesClearAirExactly) {
  const Scan s = scan(SceneKind::inclined_plane, MediumParams{});
  const auto media = binocular_depth(s.in, search(), Constraint::media);
  const auto clear = binocular_depth(s.in, search(), Constraint::clear_air);
  size_t valid = 0;
  for (size_t i = 0; i < media.size(); ++i) {
    ASSERT_EQ(std::isnan(media[i]), std::isnan(clear[i])) << i;
    if (!std::isnan(media[i])) {
      ASSERT_EQ(media[i], clear[i]) << i;
      ++valid;
    }
  }
  EXPECT_GT(valid, media.size() / 2);
  const Stats st = stats(clear, s, both_visible(s));
  EXPECT_LT(st.rms_mm, 2.0);  // clear air on clear-air images works
}

TEST(Binocular, ZeroSignalAndSaturatedPixelsAreInvalid) {
  Scan s = scan(SceneKind::fronto_plane, test::tank_medium());
  // Zero signal: a black patch (albedo 0) leaves nothing but backscatter.
  for (uint32_t y = 40; y < 56; ++y)
    for (uint32_t x = 56; x < 72; ++x) {
      const size_t i = size_t{y} * s.in.left.width + x;
      s.in.left_image[i] = s.left.backscatter[i];
    }
  // Saturated backscatter: a block at the camera's full scale.
  DepthSearch d = search();
  d.saturation = 10.0;
  for (uint32_t y = 10; y < 20; ++y)
    for (uint32_t x = 10; x < 20; ++x) s.in.left_image[size_t{y} * s.in.left.width + x] = 10.0f;
  const auto depth = binocular_depth(s.in, d, Constraint::media);
  for (uint32_t y = 44; y < 52; ++y)
    for (uint32_t x = 60; x < 68; ++x) EXPECT_TRUE(std::isnan(depth[size_t{y} * s.in.left.width + x])) << x << "," << y;
  for (uint32_t y = 10; y < 20; ++y)
    for (uint32_t x = 10; x < 20; ++x) EXPECT_TRUE(std::isnan(depth[size_t{y} * s.in.left.width + x]));
  for (float v : depth) EXPECT_FALSE(std::isinf(v));
}

// The whole chain: medium parameters fitted from one medium-only image of the
// stereo rig's left camera (3 % noise; the fit is weaker here than in the
// §5.4.1 geometry: σ about 25 % off), then used by the constraint on the
// inclined plane: RMS < 6 mm, still >= 10x better than clear air (88 mm).
TEST(Binocular, FittedMediumFeedsTheConstraint) {
  const MediumParams truth = test::tank_medium();
  const test::BinocularRig rig;
  auto img = render_medium_only(rig.left, rig.light, test::kLightIntensity, truth, 2000);
  double mean = 0;
  for (float v : img) mean += static_cast<double>(v);
  mean /= static_cast<double>(img.size());
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 0.03 * mean);
  for (float& v : img) v = static_cast<float>(static_cast<double>(v) + noise(rng));
  const auto fit = fit_medium(rig.left, img, rig.light, test::kLightIntensity, 2000, 4);
  ASSERT_TRUE(fit.ok);
  Scan s = scan(SceneKind::inclined_plane, truth);
  s.in.medium = fit.medium;
  const auto depth = binocular_depth(s.in, search(), Constraint::media);
  const Stats st = stats(depth, s, both_visible(s));
  std::printf("fitted medium sigma %.5f beta %.5f g %.3f: rms %.3f mm valid %.3f\n", fit.medium.sigma_per_mm,
              fit.medium.beta_per_mm, fit.medium.g, st.rms_mm, st.valid);
  EXPECT_LT(st.rms_mm, 6.0);
  EXPECT_GE(st.valid, 0.95);
  EXPECT_LT(10.0 * st.rms_mm, stats(binocular_depth(s.in, search(), Constraint::clear_air), s, both_visible(s)).rms_mm);
}

}  // namespace
}  // namespace procam::media_stereo
