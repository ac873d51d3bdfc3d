// SPDX-License-Identifier: MIT
// Renderer physics against independent formulas: Lambertian direct light,
// linearity in the emitted pattern, thin-lens defocus edge widths, projector
// emission curve, and ground-truth projector coordinates.
#include "procam/hw/sim/renderer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "procam/hw/sim/ground_truth.hpp"
#include "procam/hw/sim/sim_rig.hpp"
#include "shipped_test_util.hpp"

namespace procam::sim {
namespace {

using test::default_rig;
using test::shipped_scene;
Image constant_u8(uint32_t w, uint32_t h, uint8_t value) {
  Image im(w, h, PixelType::u8);
  std::fill(im.data(), im.data() + im.size_bytes(), value);
  return im;
}

TEST(GroundTruth, ProjectorCoordinatesMatchIndependentProjection) {
  const SimRigConfig rig = default_rig();
  const CameraCalibration& cam = rig.cameras[0].calibration;
  auto v = prepare_view(shipped_scene("tilted-box"), rig.projector, cam, 2);
  ASSERT_TRUE(v.ok());
  const hw::GroundTruth gt = ground_truth_from_view(*v);
  const Intrinsics& K = cam.intrinsics;
  const Intrinsics& Kp = rig.projector.intrinsics;
  const Rigid3 proj_from_cam = cam.cam_from_proj.inverse();
  size_t lit = 0, unlit_surface = 0;
  for (uint32_t y = 0; y < K.height; y += 2) {
    for (uint32_t x = 0; x < K.width; x += 2) {
      const double z = gt.depth_mm.at<float>(x, y);
      ASSERT_TRUE(std::isfinite(z));  // background plane fills the view
      const float col = gt.proj_col.at<float>(x, y), row = gt.proj_row.at<float>(x, y);
      if (gt.lit.at<uint8_t>(x, y) == 0) {
        EXPECT_TRUE(std::isnan(col) && std::isnan(row));
        ++unlit_surface;
        continue;
      }
      ASSERT_EQ(gt.lit.at<uint8_t>(x, y), 255);
      // X_cam = z * ((u - cx)/fx, (v - cy)/fy, 1); X_proj = R^T (X_cam - t).
      const Vec3 xc{(x - K.cx) / K.fx * z, (y - K.cy) / K.fy * z, z};
      const Vec3 xp = proj_from_cam * xc;
      const double u_p = Kp.fx * xp.x / xp.z + Kp.cx, v_p = Kp.fy * xp.y / xp.z + Kp.cy;
      ASSERT_NEAR(col, u_p, 1e-3) << x << "," << y;
      ASSERT_NEAR(row, v_p, 1e-3) << x << "," << y;
      EXPECT_GE(col, -0.5f);
      EXPECT_LT(col, static_cast<float>(Kp.width) - 0.5f);
      ++lit;
    }
  }
  EXPECT_GT(lit, 200000u);
  EXPECT_GT(unlit_surface, 3000u);  // the box's shadow
}

TEST(DirectLight, PlaneMatchesLambertianFormula) {
  const SimRigConfig rig = default_rig();
  const Scene scene = shipped_scene("plane");
  const Plane& pl = std::get<Plane>(scene.objects[0].shape);
  const double albedo = scene.objects[0].material.albedo;
  const CameraCalibration& cam = rig.cameras[0].calibration;
  auto v = prepare_view(scene, rig.projector, cam, 2);
  ASSERT_TRUE(v.ok());
  Renderer renderer(*v, rig.projector, 2);
  const Vec3 c_p = cam.cam_from_proj.translation_mm;  // projector centre, camera frame
  const Vec3 n = pl.normal * (1.0 / norm(pl.normal));
  for (uint8_t value : {uint8_t{255}, uint8_t{100}}) {
    Image pat = constant_u8(rig.projector.intrinsics.width, rig.projector.intrinsics.height, value);
    auto prepared = PreparedPattern::from_pattern(pat.view(), rig.projector);
    ASSERT_TRUE(prepared.ok());
    std::vector<float> radiance(v->pixel_count());
    ASSERT_TRUE(renderer.render_radiance(*prepared, radiance.data(), true).ok());
    const double emitted = rig.projector.black_level +
                           (1 - rig.projector.black_level) * std::pow(value / 255.0, rig.projector.gamma);
    int checked = 0;
    for (uint32_t y = 20; y < cam.intrinsics.height; y += 95) {
      for (uint32_t x = 20; x < cam.intrinsics.width; x += 155) {
        const Vec3 d = cam.intrinsics.ray(x, y);
        auto s = test::ref_ray_plane({0, 0, 0}, d, pl.point_mm, n);
        ASSERT_TRUE(s.has_value());
        const Vec3 X = d * *s;
        const Vec3 to_p = c_p - X;
        const double dist = norm(to_p);
        const double cos_t = std::abs(dot(n, to_p)) / dist;
        const double E = rig.projector.irradiance_at_1m * 1e6 * cos_t / (dist * dist) * emitted;
        const double expected = albedo / M_PI * (E + scene.ambient);
        const float got = radiance[size_t{y} * cam.intrinsics.width + x];
        EXPECT_NEAR(got, expected, 1e-4 * expected) << "pixel " << x << "," << y << " value " << int{value};
        ++checked;
      }
    }
    EXPECT_GE(checked, 40);
  }
}

TEST(Projector, EmissionCurveForAllPixelTypes) {
  ProjectorModel p;
  p.intrinsics = {4, 1, 4, 4, 1.5, 0};
  p.black_level = 0.02;
  p.gamma = 2.2;
  auto expect = [&](double value) { return 0.02 + 0.98 * std::pow(std::clamp(value, 0.0, 1.0), 2.2); };
  Image u16(4, 1, PixelType::u16, 1, 12);
  const uint16_t codes[4] = {0, 1000, 2048, 4095};
  for (uint32_t x = 0; x < 4; ++x) u16.at<uint16_t>(x, 0) = codes[x];
  auto a = PreparedPattern::from_pattern(u16.view(), p);
  ASSERT_TRUE(a.ok());
  for (uint32_t x = 0; x < 4; ++x)
    EXPECT_NEAR(a->level(0)[a->stride() + 1 + x], expect(codes[x] / 4095.0), 1e-6);
  Image f32(4, 1, PixelType::f32);
  const float vals[4] = {-0.5f, 0.3f, 0.77777f, 2.0f};
  for (uint32_t x = 0; x < 4; ++x) f32.at<float>(x, 0) = vals[x];
  auto b = PreparedPattern::from_pattern(f32.view(), p);
  ASSERT_TRUE(b.ok());
  for (uint32_t x = 0; x < 4; ++x)
    EXPECT_NEAR(b->level(0)[b->stride() + 1 + x], expect(static_cast<double>(vals[x])), 1e-6);
  Image wrong(5, 1, PixelType::u8);
  auto c = PreparedPattern::from_pattern(wrong.view(), p);
  ASSERT_FALSE(c.ok());
  EXPECT_EQ(c.status().code(), Code::invalid_argument);
  EXPECT_NE(c.status().message().find("5x1"), std::string::npos);
  EXPECT_NE(c.status().message().find("4x1"), std::string::npos);
}

// ---- Linearity ----------------------------------------------------------------

TEST(Linearity, RadianceIsLinearInEmittedLightAcrossBlurLevels) {
  ProjectorModel proj;
  proj.intrinsics = {640, 400, 800.0, 800.0, 319.5, 199.5};
  proj.aperture_mm = 25;
  proj.focus_mm = 500;
  CameraCalibration cam;
  cam.intrinsics = {640, 400, 850.0, 850.0, 319.5, 199.5};
  cam.cam_from_proj.rotation = rotation_from_euler_deg(0, -8, 0);
  cam.cam_from_proj.translation_mm = {120, 0, 0};
  Scene scene;
  Plane pl;
  pl.point_mm = {0, 0, 850};
  pl.normal = normalized(Vec3{0.6, 0.1, -1});
  scene.objects.push_back({"", pl, {0.7}});
  scene.objects.push_back({"", Sphere{{-60, 0, 560}, 60}, {0.9}});
  scene.ambient = 0.3;
  auto v = prepare_view(scene, proj, cam, 2);
  ASSERT_TRUE(v.ok());
  Renderer renderer(*v, proj, 2);
  // The depth range spans several blur levels.
  std::vector<size_t> per_level(kBlurLevelSigmaPx.size(), 0);
  for (size_t i = 0; i < v->pixel_count(); ++i)
    if (v->lit[i]) ++per_level[renderer.defocus().level[i]];
  size_t levels_used = 0;
  for (size_t n : per_level) levels_used += n > 1000 ? 1u : 0u;
  ASSERT_GE(levels_used, 4u);

  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uni(0.f, 1.f);
  Image p1(640, 400, PixelType::f32), p2(640, 400, PixelType::f32), p12(640, 400, PixelType::f32);
  for (size_t i = 0; i < p1.pixel_count(); ++i) {
    // Random values plus a stripe structure so blur matters.
    const float s = ((i % 640) / 7) % 2 ? 1.f : 0.f;
    p1.ptr<float>()[i] = uni(rng) * s;
    p2.ptr<float>()[i] = 2.f * uni(rng);
    p12.ptr<float>()[i] = p1.ptr<float>()[i] + p2.ptr<float>()[i];
  }
  auto render = [&](const Image& e) {
    auto pp = PreparedPattern::from_emitted(e);
    EXPECT_TRUE(pp.ok());
    std::vector<float> out(v->pixel_count());
    EXPECT_TRUE(renderer.render_radiance(*pp, out.data(), /*include_ambient=*/false).ok());
    return out;
  };
  const auto r1 = render(p1), r2 = render(p2), r12 = render(p12);
  size_t nonzero = 0;
  for (size_t i = 0; i < r12.size(); ++i) {
    ASSERT_NEAR(r12[i], r1[i] + r2[i], 1e-5f * std::abs(r12[i]) + 1e-9f) << "pixel " << i;
    nonzero += r12[i] > 0 ? 1u : 0u;
  }
  EXPECT_GT(nonzero, r12.size() / 2);
  // Scaling: radiance(3 P) = 3 radiance(P).
  Image p3 = p1;
  for (size_t i = 0; i < p3.pixel_count(); ++i) p3.ptr<float>()[i] *= 3.f;
  const auto r3 = render(p3);
  for (size_t i = 0; i < r3.size(); i += 7) ASSERT_NEAR(r3[i], 3.f * r1[i], 1e-5f * std::abs(r3[i]) + 1e-9f);
  // Ambient is the only affine part: with it, radiance(0) = albedo/π·ambient.
  Image zero(640, 400, PixelType::f32);
  auto pz = PreparedPattern::from_emitted(zero);
  std::vector<float> rz(v->pixel_count());
  ASSERT_TRUE(renderer.render_radiance(*pz, rz.data(), true).ok());
  for (size_t i = 0; i < rz.size(); i += 101) {
    if (v->object[i] >= 0) {
      ASSERT_NEAR(static_cast<double>(rz[i]), static_cast<double>(v->albedo[i]) / M_PI * 0.3, 1e-6);
    }
  }
}

// ---- Defocus ------------------------------------------------------------------

// Projector and camera with parallel axes, so a fronto-parallel plane at z has
// projector-axis depth z everywhere (constant blur).
struct EdgeRig {
  ProjectorModel proj;
  CameraCalibration cam;
  std::unique_ptr<Renderer> renderer;
  PreparedPattern pattern;
  static constexpr double kPlaneZ = 800;

  explicit EdgeRig(double aperture_mm) {
    proj.intrinsics = {640, 400, 800.0, 800.0, 319.5, 199.5};
    proj.black_level = 0;
    proj.gamma = 1;
    proj.aperture_mm = aperture_mm;
    proj.focus_mm = kPlaneZ;
    cam.intrinsics = {640, 400, 900.0, 900.0, 319.5, 199.5};
    cam.cam_from_proj.translation_mm = {100, 0, 0};
    Scene scene;
    Plane pl;
    pl.point_mm = {0, 0, kPlaneZ};
    pl.normal = {0, 0, -1};
    scene.objects.push_back({"", pl, {0.7}});
    auto v = prepare_view(scene, proj, cam, 2);
    EXPECT_TRUE(v.ok());
    renderer = std::make_unique<Renderer>(*v, proj, 2);
    Image step(640, 400, PixelType::u8);  // 0 left of column 320, 255 from it
    for (uint32_t y = 0; y < 400; ++y)
      for (uint32_t x = 320; x < 640; ++x) step.at<uint8_t>(x, y) = 255;
    pattern = *PreparedPattern::from_pattern(step.view(), proj);
  }
  // Predicted Gaussian σ at the plane for a focus setting.
  double predicted_sigma(double focus_mm) const {
    return aperture() * proj.intrinsics.fx * std::abs(1 / focus_mm - 1 / kPlaneZ) / 4;
  }
  double aperture() const { return proj.aperture_mm; }
  // Focus distance that gives blur σ at the plane (focus in front of it).
  double focus_for_sigma(double sigma) const {
    return 1.0 / (1.0 / kPlaneZ + 4 * sigma / (aperture() * proj.intrinsics.fx));
  }
  // (projector column, normalised intensity) along camera row 200.
  std::vector<std::pair<double, double>> profile(double focus_mm) {
    renderer->set_focus_mm(focus_mm);
    std::vector<float> rad(renderer->view().pixel_count());
    EXPECT_TRUE(renderer->render_radiance(pattern, rad.data(), false).ok());
    std::vector<std::pair<double, double>> out;
    const PreparedView& v = renderer->view();
    for (uint32_t x = 0; x < v.width; ++x) {
      const size_t i = 200 * size_t{v.width} + x;
      if (!v.lit[i]) continue;
      out.emplace_back(v.proj_x[i], rad[i] / v.direct_gain[i]);
    }
    return out;
  }
  // 10–90 % rise width in projector pixels, linear interpolation between samples.
  static double edge_width(const std::vector<std::pair<double, double>>& p) {
    auto crossing = [&](double level) {
      for (size_t k = 1; k < p.size(); ++k) {
        if (p[k - 1].second < level && p[k].second >= level) {
          const double t = (level - p[k - 1].second) / (p[k].second - p[k - 1].second);
          return p[k - 1].first + t * (p[k].first - p[k - 1].first);
        }
      }
      return std::nan("");
    };
    return crossing(0.9) - crossing(0.1);
  }
};

TEST(Defocus, EdgeWidthMatchesThinLensSigma) {
  EdgeRig rig(20.0);
  const double k1090 = 2 * 1.2815515655;  // 10–90 % width of a Gaussian edge / σ
  double previous = 0;
  for (double sigma : {1.5, 3.0, 4.0, 6.0, 10.0}) {
    const double focus = rig.focus_for_sigma(sigma);
    ASSERT_NEAR(rig.predicted_sigma(focus), sigma, 1e-9);
    const double w = EdgeRig::edge_width(rig.profile(focus));
    EXPECT_NEAR(w / (k1090 * sigma), 1.0, 0.2) << "sigma " << sigma << " width " << w;
    EXPECT_GT(w, previous);  // blur grows with |1/f − 1/z|
    previous = w;
  }
}

TEST(Defocus, FocusedEdgeIsOnePixelSharp) {
  EdgeRig rig(20.0);
  const auto prof = rig.profile(EdgeRig::kPlaneZ);  // in focus
  ASSERT_GT(prof.size(), 500u);
  size_t lo = 0, hi = 0;
  for (const auto& [x, value] : prof) {
    // Box pixels: projector pixel i spans [i − 0.5, i + 0.5): pattern[319] = 0, pattern[320] = 1.
    if (std::abs(x - 319.5) < 1e-3) continue;
    const double expected = x >= 319.5 ? 1.0 : 0.0;
    ASSERT_NEAR(value, expected, 1e-6) << "proj x " << x;
    (expected > 0 ? hi : lo)++;
  }
  EXPECT_GT(lo, 100u);
  EXPECT_GT(hi, 100u);
  // No intermediate sample: the 10–90 % rise happens within one camera pixel (< 1 projector px).
  EXPECT_LT(EdgeRig::edge_width(prof), 1.0);
}

TEST(Defocus, FocusSettingChangesBlurAndResets) {
  EdgeRig rig(20.0);
  const double near_focus = rig.focus_for_sigma(5.0);
  const double w_default = EdgeRig::edge_width(rig.profile(0));  // <= 0: projector default (in focus)
  const double w_near = EdgeRig::edge_width(rig.profile(near_focus));
  const double w_back = EdgeRig::edge_width(rig.profile(-1));
  EXPECT_LT(w_default, 1.0);
  EXPECT_NEAR(w_near / (2 * 1.2815515655 * 5.0), 1.0, 0.2);
  EXPECT_DOUBLE_EQ(w_back, w_default);
  // Focus behind the plane blurs symmetrically in 1/f: same |1/f − 1/z| → same width.
  const double near2 = rig.focus_for_sigma(2.5);
  const double far2 = 1.0 / (2.0 / EdgeRig::kPlaneZ - 1.0 / near2);
  ASSERT_GT(far2, EdgeRig::kPlaneZ);
  const double w_near2 = EdgeRig::edge_width(rig.profile(near2));
  EXPECT_NEAR(EdgeRig::edge_width(rig.profile(far2)), w_near2, 1e-3 * w_near2);
  EXPECT_NEAR(w_near2 / (2 * 1.2815515655 * 2.5), 1.0, 0.2);
  // Zero aperture: pinhole, sharp at any focus.
  EdgeRig pinhole(0.0);
  EXPECT_LT(EdgeRig::edge_width(pinhole.profile(300)), 1.0);
}

TEST(Defocus, BlurStackPreservesFlatFieldAwayFromBorders) {
  ProjectorModel proj;
  proj.intrinsics = {200, 120, 300.0, 300.0, 99.5, 59.5};
  Image flat(200, 120, PixelType::f32);
  std::fill(flat.ptr<float>(), flat.ptr<float>() + flat.pixel_count(), 0.25f);
  auto p = PreparedPattern::from_emitted(flat);
  ASSERT_TRUE(p.ok());
  p->build_levels(kBlurLevelSigmaPx.size());
  ASSERT_EQ(p->levels_built(), kBlurLevelSigmaPx.size());
  for (size_t k = 0; k < kBlurLevelSigmaPx.size(); ++k) {
    // Centre pixel is more than 3σ+1 from every border up to σ = 16.
    EXPECT_NEAR(p->level(k)[61 * p->stride() + 101], 0.25f, 1e-6f) << "level " << k;
  }
}

// Camera defocus (thin lens, optional): a sharp projected edge seen through a
// defocused camera lens. Reference: the sharp image convolved in the test
// with a Gaussian integrated over each pixel, σ from the thin-lens formula
// written out here (b = A·fx·|1/focus − 1/z|, σ = b/4).
TEST(CameraDefocus, BlursTheImageByTheThinLensSigma) {
  EdgeRig rig(0.0);  // sharp projector
  Renderer& r = *rig.renderer;
  const PreparedView& v = r.view();
  const size_t n = v.pixel_count();
  std::vector<float> sharp(n), blurred(n);
  ASSERT_TRUE(r.render_radiance(rig.pattern, sharp.data(), false).ok());
  const double A = 10.0, fx = v.camera.intrinsics.fx;
  auto phi = [](double t) { return 0.5 * std::erfc(-t / std::sqrt(2.0)); };
  for (double sigma : {2.0, 3.0}) {
    const double focus = 1.0 / (1.0 / EdgeRig::kPlaneZ + 4 * sigma / (A * fx));
    r.set_camera_lens({A, focus});
    ASSERT_TRUE(r.render_radiance(rig.pattern, blurred.data(), false).ok());
    // Row 200, 1-D reference along x (a vertical edge: the y blur of a
    // y-constant image changes nothing away from the border).
    double worst = 0, plateau = 0;
    for (uint32_t x = 40; x + 40 < v.width; ++x) {
      double ref = 0;
      for (int j = -20; j <= 20; ++j)
        ref += (phi((j + 0.5) / sigma) - phi((j - 0.5) / sigma)) *
               static_cast<double>(sharp[static_cast<size_t>(200 * int64_t{v.width} + int64_t{x} + j)]);
      plateau = std::max(plateau, ref);
      worst = std::max(worst, std::abs(static_cast<double>(blurred[200 * size_t{v.width} + x]) - ref));
    }
    std::printf("camera defocus sigma %.1f px: max |sim - reference| = %.4f of the plateau\n", sigma, worst / plateau);
    // σ = 2 is a stack level (exact); σ = 3 blends levels 2 and 4 by variance.
    EXPECT_LT(worst / plateau, sigma == 2.0 ? 0.002 : 0.04);
  }
  r.set_camera_lens({});  // aperture 0: pinhole again, identical to the sharp image
  ASSERT_TRUE(r.render_radiance(rig.pattern, blurred.data(), false).ok());
  EXPECT_EQ(blurred, sharp);
}

}  // namespace
}  // namespace procam::sim
