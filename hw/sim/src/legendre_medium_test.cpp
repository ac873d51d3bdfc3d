// SPDX-License-Identifier: MIT
// The scene's dynamic Legendre medium in the sim renderer: attenuation
// against the closed form, air-light (polarized, attenuated on both legs,
// shadowed) against fine quadrature, motion and reproducibility, parse
// errors.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>

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
// by exp(-sigma (l_cam + l_proj)), the lengths inside the box: to 2e-4
// relative (the projector leg is read from the (kGrid+1)^3 lattice of
// marched depths, bilinear on the box face it leaves by; a march per pixel
// gave 2e-5 at ~2x the cost).
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
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!(a[i] > 0)) continue;
    const Vec3 pt = point_of(fog->view(), i);
    const double t = std::exp(-0.002 * (medium_length(box, {0, 0, 0}, pt) + medium_length(box, proj, pt)));
    EXPECT_NEAR(b[i], a[i] * t, 2e-4 * a[i] + 1e-7) << i;
    worst = std::max(worst, std::abs(b[i] - a[i] * t) / a[i]);
    ++checked;
  }
  EXPECT_GT(checked, a.size() / 2);
  std::cout << "[ measured ] uniform fog attenuation: worst relative error " << worst << "\n";
}

// Independent reference for the air-light of one camera pixel in a box of
// uniform density `rho` (no surface inside the box, a uniform pattern of
// emitted light `e`): 4000-step midpoint quadrature of Eq. 6.5 with the
// closed-form optical depths of both legs (rho times the lengths inside the
// box), the projector image's bounds, an optional spherical occluder tested
// ray by ray, and the polarization in the dipole picture instead of Stokes
// vectors: with the Rayleigh ratios of the Mueller model normalised to the
// HG intensity, light polarized along e (perpendicular to the incident
// direction l) scattered towards o and analysed along a (perpendicular to
// o) has intensity p_HG 2 (a.e)^2 / (1 + cos^2 theta); unanalysed,
// p_HG 2 (1 - (e.o)^2) / (1 + cos^2 theta); unpolarized and analysed,
// p_HG (1 - (a.l)^2) / (1 + cos^2 theta). Device axes: the polariser's
// (analyser's) image-plane axis in 3D projected perpendicular to the ray.
struct Fog {
  Medium box;
  double rho = 0.5, sigma = 0.003, beta = 0.002, g = 0.3;
  bool rayleigh = true;
  std::optional<std::pair<Vec3, double>> occluder;  // sphere centre, radius (mm)
};

double air_quadrature(const SimRigConfig& rig, const Fog& f, uint32_t u, uint32_t v, double e, double pol_deg,
                      double ana_deg, double* shadowed_fraction = nullptr) {
  const Intrinsics& k = rig.cameras[0].calibration.intrinsics;
  const Rigid3& world_from_proj = rig.cameras[0].calibration.cam_from_proj;
  const Vec3 proj = world_from_proj.translation_mm;
  const Intrinsics& kp = rig.projector.intrinsics;
  const Vec3 dir = normalized(k.ray(u, v)), o = -dir;
  const double a = pol_deg * M_PI / 180, b = ana_deg * M_PI / 180;
  const Vec3 ep = world_from_proj.rotation * Vec3{std::cos(a), std::sin(a), 0};
  const Vec3 ea = Vec3{std::cos(b), std::sin(b), 0};
  const Vec3 av = normalized(ea - o * dot(ea, o));
  double t0 = 0, t1 = 0;
  if (!medium_interval(f.box, {0, 0, 0}, dir, t0, t1)) return 0.0;
  const int n = 4000;
  double air = 0, shadowed = 0, lit = 0;
  for (int s = 0; s < n; ++s) {
    const double t = t0 + (s + 0.5) * (t1 - t0) / n;
    const Vec3 y = dir * t, ly = y - proj;
    const Vec3 q = world_from_proj.inverse() * y;
    const double xp = kp.fx * q.x / q.z + kp.cx, yp = kp.fy * q.y / q.z + kp.cy;
    if (!(q.z > 0 && xp >= -0.5 && xp < kp.width - 0.5 && yp >= -0.5 && yp < kp.height - 0.5)) continue;
    const double d2 = dot(ly, ly), d = std::sqrt(d2);
    const Vec3 l = ly / d;
    ++lit;
    if (f.occluder) {  // segment proj -> y against the sphere
      const Vec3 oc = proj - f.occluder->first;
      const double bq = dot(oc, l), cq = dot(oc, oc) - f.occluder->second * f.occluder->second;
      const double disc = bq * bq - cq;
      if (disc > 0 && -bq - std::sqrt(disc) > 0 && -bq - std::sqrt(disc) < d) {
        ++shadowed;
        continue;
      }
    }
    const double c = dot(l, o), p = hg_phase(f.g, c);
    double phase = p;
    if (!f.rayleigh) {
      phase = std::isfinite(ana_deg) ? 0.5 * p : p;
    } else if (std::isfinite(pol_deg)) {
      const Vec3 ev = normalized(ep - l * dot(ep, l));
      phase = std::isfinite(ana_deg) ? 2 * p * dot(av, ev) * dot(av, ev) / (1 + c * c)
                                     : 2 * p * (1 - dot(ev, o) * dot(ev, o)) / (1 + c * c);
    } else if (std::isfinite(ana_deg)) {
      phase = p * (1 - dot(av, l) * dot(av, l)) / (1 + c * c);
    }
    const double tau = f.rho * ((t - t0) + medium_length(f.box, proj, y));
    air += f.beta * f.rho * phase * rig.projector.irradiance_at_1m * 1e6 * e / d2 * std::exp(-f.sigma * tau) *
           (t1 - t0) / n;
  }
  if (shadowed_fraction) *shadowed_fraction = lit > 0 ? shadowed / lit : 0.0;
  return air;
}

Fog box_fog() {
  Fog f;
  f.box.whole_scene = false;
  f.box.box_min_mm = {-300, -200, 450};
  f.box.box_max_mm = {300, 200, 760};
  return f;
}

std::string fog_json(const Fog& f) {
  char buf[400];
  std::snprintf(buf, sizeof buf,
                R"({"box_min_mm": [-300, -200, 450], "box_max_mm": [300, 200, 760], "n": 4, "density_uniform": %.17g,
                    "sigma_t_per_mm": %.17g, "sigma_s_per_mm": %.17g, "g": %.17g, "dop_model": "%s"})",
                f.rho, f.sigma, f.beta, f.g, f.rayleigh ? "rayleigh" : "none");
  return buf;
}

// Air-light (unpolarized light, no analyser) against the quadrature, with
// the projector leg's attenuation exp(-sigma tau_proj(Y)) in closed form:
// within 1% (~one midpoint sample per density-grid cell) at five pixels
// lit over the whole box.
// A black pattern gives none, a half-lit one (left projector columns) lies
// between, and with dop_model "none" an analyser passes exactly half.
TEST(LegendreMedium, AirLightMatchesFineQuadrature) {
  const SimRigConfig rig = small_rig();
  Fog f = box_fog();
  f.rayleigh = false;
  auto fog = scene_renderer(plane_with_fog(fog_json(f)), rig);
  ASSERT_TRUE(fog);
  const size_t w = rig.projector.intrinsics.width, h = rig.projector.intrinsics.height;
  PreparedPattern p = emitted_pattern(rig.projector, std::vector<float>(w * h, 0.5f));
  const auto img = render(*fog, p, Renderer::Parts::volume_only);
  const uint32_t kw = rig.cameras[0].calibration.intrinsics.width;
  for (auto [u, v] : {std::pair{80u, 50u}, {30u, 10u}, {150u, 90u}, {30u, 85u}, {140u, 12u}}) {
    const double air = air_quadrature(rig, f, u, v, 0.5, kNaN, kNaN);
    ASSERT_GT(air, 0.0) << u << "," << v;
    EXPECT_NEAR(img[v * kw + u], air, 0.01 * air) << u << "," << v;
  }
  // Without the projector leg the centre pixel would be brighter by
  // exp(sigma rho l_proj) ~ 1.4: the leg is not a rounding matter.
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
  fog->set_polarization(30.0, 0.0);
  const auto an = render(*fog, p, Renderer::Parts::volume_only);
  for (size_t i = 0; i < img.size(); ++i) ASSERT_NEAR(an[i], 0.5 * img[i], 1e-6 * img[i] + 1e-12);
}

// Polarized air-light (Rayleigh ratios, Eq. 5.35-5.36) against the dipole
// quadrature for parallel and crossed analysers at two polariser angles, an
// unpolarized projector behind an analyser, and no analyser: within 1% of
// the pixel's unanalysed air-light (the march's error) at five pixels whose
// rays the projector lights over the whole box (a frustum edge inside the
// box costs up to one of ~14 march samples). Malus on the axis: parallel +
// crossed = unanalysed to 1e-5.
TEST(LegendreMedium, PolarizedAirLightMatchesDipoleQuadrature) {
  const SimRigConfig rig = small_rig();
  const Fog f = box_fog();
  auto fog = scene_renderer(plane_with_fog(fog_json(f)), rig);
  ASSERT_TRUE(fog);
  const size_t w = rig.projector.intrinsics.width, h = rig.projector.intrinsics.height;
  PreparedPattern p = emitted_pattern(rig.projector, std::vector<float>(w * h, 0.5f));
  const uint32_t kw = rig.cameras[0].calibration.intrinsics.width;
  const std::pair<double, double> settings[] = {{0, 0}, {0, 90}, {45, 45}, {45, 135}, {kNaN, 0}, {kNaN, 90}, {0, kNaN}};
  std::vector<std::vector<double>> imgs;
  for (auto [pol, ana] : settings) {
    fog->set_polarization(pol, ana);
    imgs.push_back(render(*fog, p, Renderer::Parts::volume_only));
  }
  for (auto [u, v] : {std::pair{80u, 50u}, {30u, 10u}, {150u, 90u}, {30u, 85u}, {140u, 12u}}) {
    const size_t i = v * kw + u;
    const double total = air_quadrature(rig, f, u, v, 0.5, 0.0, kNaN);
    ASSERT_GT(total, 0.0);
    for (size_t s = 0; s < std::size(settings); ++s) {
      const double ref = air_quadrature(rig, f, u, v, 0.5, settings[s].first, settings[s].second);
      EXPECT_NEAR(imgs[s][i], ref, 0.01 * total) << u << "," << v << " polariser " << settings[s].first
                                                 << " analyser " << settings[s].second;
    }
    // Malus' sum rule holds where the analyser's axes at 0 and 90 deg stay
    // perpendicular after projection: on the optical axis. Off axis they
    // are not (second order in the ray's angle; 0.7% at the corner pixels).
    if (u == 80 && v == 50) {
      EXPECT_NEAR(imgs[0][i] + imgs[1][i], imgs[6][i], 1e-5 * imgs[6][i]);
      std::cout << "[ measured ] centre pixel, polariser 0: parallel " << imgs[0][i] << ", crossed " << imgs[1][i]
                << " (quadrature " << air_quadrature(rig, f, u, v, 0.5, 0, 0) << ", "
                << air_quadrature(rig, f, u, v, 0.5, 0, 90) << ")\n";
    }
  }
}

// Projector-ray occlusion: a sphere just in front of the projector (outside
// the fog box and the camera's view) shadows part of the box. Pixels whose
// whole lit ray lies in its shadow (by the analytic test) get no air-light;
// pixels whose ray it does not shadow keep the unoccluded value; partly
// shadowed ones match the quadrature to 10% (a shadow edge moves one of ~13
// march samples).
TEST(LegendreMedium, SamplesInAShadowAreDark) {
  const SimRigConfig rig = small_rig();
  Fog f = box_fog();
  f.rayleigh = false;
  const Rigid3& world_from_proj = rig.cameras[0].calibration.cam_from_proj;
  const Vec3 centre = world_from_proj * Vec3{0, 0, 80};
  f.occluder = std::pair{centre, 25.0};
  auto j = nlohmann::json::parse(kPlane);
  j["legendre_medium"] = nlohmann::json::parse(fog_json(f));
  j["objects"].push_back({{"type", "sphere"}, {"center_mm", {centre.x, centre.y, centre.z}}, {"radius_mm", 25}});
  auto scene = parse_scene(j, "test");
  ASSERT_TRUE(scene.ok()) << scene.status().to_string();
  auto occluded = scene_renderer(*scene, rig);
  auto open = scene_renderer(plane_with_fog(fog_json(f)), rig);
  ASSERT_TRUE(occluded && open);
  const size_t w = rig.projector.intrinsics.width, h = rig.projector.intrinsics.height;
  PreparedPattern p = emitted_pattern(rig.projector, std::vector<float>(w * h, 1.f));
  const auto a = render(*occluded, p, Renderer::Parts::volume_only), b = render(*open, p, Renderer::Parts::volume_only);
  const uint32_t kw = rig.cameras[0].calibration.intrinsics.width;
  int dark = 0, clear = 0, partial = 0;
  for (uint32_t v = 5; v < 100; v += 15)
    for (uint32_t u = 2; u < kw; u += 6) {
      double frac = 0;
      const double ref = air_quadrature(rig, f, u, v, 1.0, kNaN, kNaN, &frac);
      const size_t i = v * kw + u;
      if (frac == 1.0) {
        EXPECT_EQ(a[i], 0.0) << u << "," << v;
        EXPECT_GT(b[i], 0.0) << u << "," << v;
        ++dark;
      } else if (frac == 0.0) {
        EXPECT_NEAR(a[i], b[i], 1e-6 * b[i]) << u << "," << v;
        ++clear;
      } else {
        EXPECT_NEAR(a[i], ref, 0.1 * b[i]) << u << "," << v << " shadowed " << frac;
        ++partial;
      }
    }
  std::cout << "[ measured ] pixels in full shadow " << dark << ", clear " << clear << ", partly " << partial << "\n";
  EXPECT_GT(dark, 5);
  EXPECT_GT(clear, 5);
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

// Advected albedo omega (beta = omega sigma, a passive scalar carried like
// the density). A uniform omega = 0.5 renders like sigma_s = sigma_t / 2
// (1e-6), before and after the swirl. Swapping the roles -- a density blob
// under omega = 1 against a uniform density under an albedo blob of the same
// shape -- gives the same beta r along every ray, so the same air-light up
// to the (tiny, sigma = 1e-5 /mm) attenuation: within 1% at t = 0 and after
// 1 s of a 200 mm/s swirl, while the image itself moves (the albedo is
// advected, not frozen).
TEST(LegendreMedium, AdvectedAlbedoScattersLikeDensity) {
  const SimRigConfig rig = small_rig();
  const size_t w = rig.projector.intrinsics.width, h = rig.projector.intrinsics.height;
  PreparedPattern p = emitted_pattern(rig.projector, std::vector<float>(w * h, 1.f));
  const std::string box = R"("box_min_mm": [-300, -200, 450], "box_max_mm": [300, 200, 760], "n": 6,
                              "swirl_mm_s": 200, )";
  auto half_a = scene_renderer(plane_with_fog("{" + box + R"("density_uniform": 0.5, "sigma_t_per_mm": 0.003,
      "sigma_s_per_mm": 0.0, "albedo_uniform": 0.5})"), rig);
  auto half_b = scene_renderer(plane_with_fog("{" + box + R"("density_uniform": 0.5, "sigma_t_per_mm": 0.003,
      "sigma_s_per_mm": 0.0015})"), rig);
  const std::string blob = R"({"center_mm": [120, 0, 600], "radius_mm": 120, "peak": 0.5})";
  auto dens = scene_renderer(plane_with_fog("{" + box + R"("blobs": [)" + blob + R"(], "sigma_t_per_mm": 1e-5,
      "sigma_s_per_mm": 1e-5, "albedo_uniform": 1.0})"), rig);
  auto alb = scene_renderer(plane_with_fog("{" + box + R"("density_uniform": 1.0, "sigma_t_per_mm": 1e-5,
      "sigma_s_per_mm": 0.0, "albedo_uniform": 0.0, "albedo_blobs": [)" + blob + "]}"), rig);
  ASSERT_TRUE(half_a && half_b && dens && alb);
  std::vector<double> alb0;
  for (double t : {0.0, 1.0}) {
    for (auto* r : {half_a.get(), half_b.get(), dens.get(), alb.get()}) set_legendre_time(*r, t);
    const auto a = render(*half_a, p, Renderer::Parts::volume_only), b = render(*half_b, p, Renderer::Parts::volume_only);
    for (size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(a[i], b[i], 1e-6 * b[i] + 1e-12) << i << " t=" << t;
    const auto d = render(*dens, p, Renderer::Parts::volume_only), e = render(*alb, p, Renderer::Parts::volume_only);
    double sd = 0, diff = 0, moved = 0;
    for (size_t i = 0; i < d.size(); ++i) {
      sd += d[i];
      diff += std::abs(d[i] - e[i]);
      if (!alb0.empty()) moved += std::abs(e[i] - alb0[i]);
    }
    ASSERT_GT(sd, 0.0);
    EXPECT_LT(diff, 0.01 * sd) << "t=" << t;
    if (!alb0.empty()) {
      EXPECT_GT(moved, 0.05 * sd);  // the albedo blob turned with the flow
    }
    alb0 = e;
  }
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
  EXPECT_FALSE(bad(R"({"box_min_mm": [0, 0, 0], "box_max_mm": [1, 1, 1], "sigma_t_per_mm": 0.1, "sigma_s_per_mm": 0.1,
                       "dop_model": "mie"})").ok());
  EXPECT_FALSE(bad(R"({"box_min_mm": [0, 0, 0], "box_max_mm": [1, 1, 1], "sigma_t_per_mm": 0.1, "sigma_s_per_mm": 0.1,
                       "albedo_uniform": 1.5})").ok());
  const auto ok = bad(R"({"box_min_mm": [0, 0, 0], "box_max_mm": [1, 1, 1], "sigma_t_per_mm": 0.1, "sigma_s_per_mm": 0.1})");
  ASSERT_TRUE(ok.ok()) << ok.status().to_string();
  EXPECT_EQ(ok->legendre_medium->n, 5);
  EXPECT_EQ(ok->legendre_medium->dop_model, Medium::DopModel::rayleigh);
  EXPECT_FALSE(ok->legendre_medium->has_albedo());
}

}  // namespace
}  // namespace procam::sim::test
