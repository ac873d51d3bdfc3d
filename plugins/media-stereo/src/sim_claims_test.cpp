// SPDX-License-Identifier: MIT
// `binocular` end to end through the rig (issue 13 item 4, thesis §5.4.1,
// Fig. 5.14): configs/rigs/sim-tank-stereo.json (two cameras, the projector
// flooding as the light) and the media-stereo-rig-* scenes (whole-scene
// medium σ 0.0025, β 0.0022 /mm, g 0.5: backscatter 2-4x the direct signal).
//
//  1. The sim's backscatter for BOTH cameras against an independent midpoint
//     integral of Eq. 5.13/5.16 written here (projector image and the
//     half-sphere's volume shadow tested point by point), in DN: checks the
//     sim renders a second camera's B along that camera's own rays.
//  2. The plugin loaded by the plugin host (in process), driven by
//     engine::run_scan (which picks each frame's camera by
//     settings.camera_index), against the sim's truth depth of camera 0: the
//     media constraint against the clear-air one on the same frames (the
//     scan's recorded frames, decoded again by engine::run_offline, which
//     must reproduce the live depth map exactly).
//  3. 8-, 12-, 16-bit and float frames (the sim's 12-bit frames re-quantised).
//
// The medium and the light's photometric scale are the plugin's params: the
// test gives the scene's σ, β, g and I0 = irradiance_at_1m·10⁶ · exposure ·
// sensitivity / full_well (the sim's sensor model at 0 dB, hw/sim models.hpp,
// in full-scale units), i.e. a calibrated light and camera.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include "binocular_session.hpp"
#include "scatter_model.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"
#include "host_input_util.hpp"
#include "test_rig.hpp"

namespace procam::media_stereo {
namespace {

const std::string kConfigs = std::string(PROCAM_SOURCE_DIR) + "/configs";
constexpr double kSigma = 0.0025, kBeta = 0.0022, kG = 0.5;  // the media-stereo-rig-* scenes
constexpr double kZMin = 380, kZMax = 700;

nlohmann::json rig_config() {
  std::ifstream f(kConfigs + "/rigs/sim-tank-stereo.json");
  return nlohmann::json::parse(f);
}

// I0 in full-scale units·mm² (see the file comment).
double light_fullscale(const nlohmann::json& cfg) {
  const nlohmann::json& c = cfg["cameras"][0];
  return cfg["projector"]["irradiance_at_1m"].get<double>() * 1e6 * c["exposure_us"].get<double>() *
         c["sensitivity"].get<double>() / c["full_well_e"].get<double>();
}

// DN per radiance unit of camera 0 (models.hpp: e = exposure·sensitivity·L, DN = e·max_dn/full_well at 0 dB).
double dn_per_ru(const nlohmann::json& cfg) {
  const nlohmann::json& c = cfg["cameras"][0];
  const double max_dn = std::ldexp(1.0, c["bit_depth"].get<int>()) - 1;
  return c["exposure_us"].get<double>() * c["sensitivity"].get<double>() * max_dn / c["full_well_e"].get<double>();
}

nlohmann::json params(const nlohmann::json& cfg, const std::string& constraint) {
  return {{"constraint", constraint}, {"sigma_per_mm", kSigma}, {"beta_per_mm", kBeta},        {"g", kG},
          {"light_intensity", light_fullscale(cfg)}, {"z_min_mm", kZMin}, {"z_max_mm", kZMax},
          {"z_step_mm", 2.0},  {"window", 7}};
}

struct Fixture {
  std::unique_ptr<hw::Rig> rig;
  hw::GroundTruth truth[2];
  Rigid3 world_from_cam[2];
  Intrinsics k[2];
};

bool open_rig(const std::string& scene, Fixture& f) {
  auto rig = hw::create_rig(rig_config(), {kConfigs + "/rigs", {kConfigs + "/scenes"}});
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  if (!rig.ok()) return false;
  f.rig = std::move(rig).value();
  const Status st = f.rig->apply_scan_options({{"scene", scene}});
  EXPECT_TRUE(st.ok()) << st.to_string();
  if (!st.ok() || f.rig->camera_count() != 2) return false;
  const Rigid3 cam0_from_proj = f.rig->camera_calibrations()[0].cam_from_proj;
  for (size_t i = 0; i < 2; ++i) {
    auto gt = f.rig->ground_truth(i);
    EXPECT_TRUE(gt.ok()) << gt.status().to_string();
    if (!gt.ok()) return false;
    f.truth[i] = std::move(gt).value();
    const CameraCalibration& c = f.rig->camera_calibrations()[i];
    f.world_from_cam[i] = cam0_from_proj * c.cam_from_proj.inverse();
    f.k[i] = c.intrinsics;
  }
  return true;
}

// Independent single-scattering B (DN) at pixel (x, y) of camera `cam`: the
// midpoint rule with `steps` samples from the camera centre to the truth
// surface; a sample counts when it projects into the projector image and the
// segment to the projector misses the sphere (if any).
double reference_backscatter_dn(const Fixture& f, const nlohmann::json& cfg, size_t cam, uint32_t x, uint32_t y,
                                const Vec3* sphere_c, double sphere_r, size_t steps) {
  const Intrinsics& k = f.k[cam];
  const double depth = static_cast<double>(f.truth[cam].depth_mm.ptr<float>()[size_t{y} * k.width + x]);
  const Vec3 ray_cam{(x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0};
  const Vec3 dir = normalized(f.world_from_cam[cam].rotation * ray_cam);
  const Vec3 c = f.world_from_cam[cam].translation_mm;
  const double t_end = depth * norm(ray_cam);
  const Rigid3 proj_from_world = f.rig->camera_calibrations()[0].cam_from_proj.inverse();
  const Vec3 p = f.rig->camera_calibrations()[0].cam_from_proj.translation_mm;  // projector centre, world
  const Intrinsics& pk = f.rig->projector_intrinsics();
  const double i0 = cfg["projector"]["irradiance_at_1m"].get<double>() * 1e6;
  const double h = t_end / static_cast<double>(steps);
  double sum = 0;
  for (size_t s = 0; s < steps; ++s) {
    const double t = (static_cast<double>(s) + 0.5) * h;
    const Vec3 yw = c + dir * t;
    const Vec3 q = proj_from_world * yw;
    if (!(q.z > 0)) continue;
    const double px = pk.fx * q.x / q.z + pk.cx, py = pk.fy * q.y / q.z + pk.cy;
    if (px < -0.5 || px > pk.width - 0.5 || py < -0.5 || py > pk.height - 0.5) continue;
    const Vec3 v = yw - p;
    const double d = norm(v);
    if (sphere_c != nullptr) {  // segment p -> yw against the sphere
      const Vec3 oc = p - *sphere_c, u = v / d;
      const double b = dot(oc, u), cc = dot(oc, oc) - sphere_r * sphere_r, disc = b * b - cc;
      if (disc > 0 && -b - std::sqrt(disc) > 0 && -b - std::sqrt(disc) < d - 1.0) continue;
    }
    const double cos_t = -dot(v, dir) / d;  // propagation p->y against scattered y->camera
    const double hg = (1 - kG * kG) / (4 * M_PI * std::pow(1 + kG * kG - 2 * kG * cos_t, 1.5));
    sum += kBeta * hg * i0 / (d * d) * std::exp(-kSigma * (d + t)) * h;
  }
  return sum * dn_per_ru(cfg);
}

TEST(MediaStereoRig, SimBackscatterOfEitherCameraMatchesAnIndependentIntegral) {
  const nlohmann::json cfg = rig_config();
  for (const char* scene : {"media-stereo-rig-plane", "media-stereo-rig-hemisphere"}) {
    Fixture f;
    ASSERT_TRUE(open_rig(scene, f));
    const bool sphere = std::string(scene).find("hemisphere") != std::string::npos;
    const Vec3 sc{75, 0, 580};
    for (size_t cam = 0; cam < 2; ++cam) {
      ASSERT_FALSE(f.truth[cam].medium_backscatter.empty());
      double worst = 0, b_min = 1e30, b_max = 0;
      for (uint32_t y = 5; y < f.k[cam].height; y += 22)
        for (uint32_t x = 5; x < f.k[cam].width; x += 25) {
          const double sim = static_cast<double>(
              f.truth[cam].medium_backscatter.ptr<float>()[size_t{y} * f.k[cam].width + x]);
          const double ref = reference_backscatter_dn(f, cfg, cam, x, y, sphere ? &sc : nullptr, 100.0, 100000);
          ASSERT_GT(ref, 0.0);
          worst = std::max(worst, std::abs(sim - ref) / ref);
          b_min = std::min(b_min, ref);
          b_max = std::max(b_max, ref);
        }
      std::printf("%s camera %zu: B %.0f..%.0f DN, worst relative error of the sim %.2e\n", scene, cam, b_min, b_max,
                  worst);
      EXPECT_LT(worst, 2e-3) << "camera " << cam;
    }
  }
}

struct DepthStats {
  double rms = NAN, median_abs = NAN, valid = 0;
  size_t pixels = 0;
};

// Pixels of camera 0 whose truth point is lit and seen (unoccluded) by camera
// 1, at least `border` pixels from the image edge (where the 7 x 7 window is
// clipped: a corner pixel's window holds 16 samples).
std::vector<uint8_t> stereo_mask(const Fixture& f, uint32_t border = 3) {
  const Intrinsics& k0 = f.k[0];
  const size_t n = size_t{k0.width} * k0.height;
  std::vector<uint8_t> m(n, 0);
  const Rigid3 cam1_from_world = f.world_from_cam[1].inverse();
  for (uint32_t y = border; y + border < k0.height; ++y)
    for (uint32_t x = border; x + border < k0.width; ++x) {
      const size_t i = size_t{y} * k0.width + x;
      const double z = static_cast<double>(f.truth[0].depth_mm.ptr<float>()[i]);
      if (!std::isfinite(z) || f.truth[0].lit.ptr<uint8_t>()[i] == 0) continue;
      const Vec3 pw = f.world_from_cam[0] * Vec3{(x - k0.cx) / k0.fx * z, (y - k0.cy) / k0.fy * z, z};
      const Vec3 q = cam1_from_world * pw;
      const double u = f.k[1].fx * q.x / q.z + f.k[1].cx, v = f.k[1].fy * q.y / q.z + f.k[1].cy;
      if (!(u >= 0 && v >= 0 && u <= f.k[1].width - 1.0 && v <= f.k[1].height - 1.0)) continue;
      const auto j = static_cast<size_t>(std::lround(v)) * f.k[1].width + static_cast<size_t>(std::lround(u));
      const double z1 = static_cast<double>(f.truth[1].depth_mm.ptr<float>()[j]);
      if (std::abs(z1 - q.z) < 3.0) m[i] = 1;
    }
  return m;
}

DepthStats depth_stats(const std::vector<float>& depth, const Fixture& f, const std::vector<uint8_t>& mask) {
  DepthStats s;
  std::vector<double> e;
  for (size_t i = 0; i < mask.size(); ++i) {
    if (!mask[i]) continue;
    ++s.pixels;
    if (std::isfinite(depth[i]))
      e.push_back(static_cast<double>(depth[i]) - static_cast<double>(f.truth[0].depth_mm.ptr<float>()[i]));
  }
  s.rms = test::rms(e);
  for (double& v : e) v = std::abs(v);
  s.median_abs = test::percentile(e, 0.5);
  s.valid = s.pixels ? static_cast<double>(e.size()) / static_cast<double>(s.pixels) : 0;
  return s;
}

struct ScanOut {
  std::vector<float> depth, medium_image;
  uint32_t width = 0, height = 0;  // of medium_image
  std::map<std::string, double> scalars;
  nlohmann::json report;
  size_t patterns = 0;
};

// Through the plugin host and the engine's scan runner, as procamd runs a
// scan. With `record_dir` the frames are recorded there, and `offline` then
// decodes that folder instead of scanning (engine::run_offline).
// `method` and `inputs` default to a binocular scan without scan inputs.
ScanOut host_scan(hw::Rig& rig, const nlohmann::json& p, const std::string& record_dir = "", bool offline = false,
                  const std::string& method = "binocular", const std::vector<host::InputImage>& inputs = {}) {
  ScanOut r;
  host::PluginHost host(host::LoadOptions{.probe_in_child = false});
  const Status loaded = host.load_file(std::string(PROCAM_PLUGIN_DIR) + "/procam-media-stereo.so");
  EXPECT_TRUE(loaded.ok()) << loaded.to_string();
  host::IsolationOptions iso;
  iso.mode = host::Isolation::in_process;
  host.set_isolation(iso);
  auto session =
      host.create_session("media-stereo", method, p.dump(), engine::plugin_rig_json(rig, 2).dump(), inputs);
  EXPECT_TRUE(session.ok()) << session.status().to_string();
  if (!session.ok()) return r;
  std::atomic<bool> cancel{false};
  engine::CaptureOptions co;
  co.record_dir = offline ? "" : record_dir;
  auto outcome = offline ? engine::run_offline(*session, record_dir, nullptr)
                         : engine::run_scan(rig, *session, co, nullptr, cancel);
  EXPECT_TRUE(outcome.ok()) << outcome.status().to_string();
  if (!outcome.ok()) return r;
  r.patterns = outcome->patterns;
  if (method == "binocular") {
    EXPECT_EQ(outcome->patterns, 2u);
  }
  auto outs = session->outputs();
  EXPECT_TRUE(outs.ok()) << outs.status().to_string();
  if (!outs.ok()) return r;
  for (const host::Output& o : *outs) {
    if (o.name == "depth_mm") {
      const auto* d = static_cast<const float*>(o.image.data);
      r.depth.assign(d, d + size_t{o.image.width} * o.image.height);
    }
    if (o.name == "medium_image") {
      const auto* d = static_cast<const float*>(o.image.data);
      r.width = o.image.width;
      r.height = o.image.height;
      r.medium_image.assign(d, d + size_t{o.image.width} * o.image.height);
    }
    if (o.kind == PROCAM_OUTPUT_SCALAR) r.scalars[o.name] = o.scalar;
    if (o.name == "report") r.report = nlohmann::json::parse(o.json);
  }
  return r;
}

void expect_no_bad_values(const std::vector<float>& depth) {
  size_t bad = 0;
  for (float z : depth)
    if (!std::isnan(z) && !(std::isfinite(z) && static_cast<double>(z) >= kZMin && static_cast<double>(z) <= kZMax))
      ++bad;
  EXPECT_EQ(bad, 0u) << "valid depths must be finite and inside the searched range";
}

struct Claim {
  const char* scene;
  double max_rms_mm;     // media constraint
  double max_median_mm;  // media constraint
  double min_factor;     // clear-air RMS / media RMS
};

class MediaVsClearAir : public ::testing::TestWithParam<Claim> {};

TEST_P(MediaVsClearAir, MediaConstraintBeatsClearAirThroughTheRig) {
  const Claim c = GetParam();
  const nlohmann::json cfg = rig_config();
  Fixture f;
  ASSERT_TRUE(open_rig(c.scene, f));
  const auto mask = stereo_mask(f);
  const std::string rec = (std::filesystem::temp_directory_path() /
                           ("procam_media_stereo_" + std::to_string(::getpid()) + "_" + c.scene)).string();
  std::filesystem::create_directories(rec);
  const ScanOut media = host_scan(*f.rig, params(cfg, "media"), rec);
  // The recorded frames (12-bit in 16-bit PNG), decoded offline with the other constraint.
  const ScanOut clear = host_scan(*f.rig, params(cfg, "clear-air"), rec, true);
  const ScanOut media_offline = host_scan(*f.rig, params(cfg, "media"), rec, true);
  std::filesystem::remove_all(rec);
  ASSERT_EQ(media_offline.depth.size(), media.depth.size());
  for (size_t i = 0; i < media.depth.size(); ++i) {  // PNG round trip of 12-bit frames is lossless
    if (!(std::isnan(media.depth[i]) && std::isnan(media_offline.depth[i]))) {
      ASSERT_EQ(media.depth[i], media_offline.depth[i]) << "offline decode differs at pixel " << i;
    }
  }
  ASSERT_EQ(media.depth.size(), mask.size());
  ASSERT_EQ(clear.depth.size(), mask.size());
  expect_no_bad_values(media.depth);
  expect_no_bad_values(clear.depth);
  const DepthStats m = depth_stats(media.depth, f, mask), a = depth_stats(clear.depth, f, mask);
  // Backscatter over direct on the lit, stereo-visible pixels (how hard the medium is here).
  double bd = 0;
  size_t nb = 0;
  for (size_t i = 0; i < mask.size(); ++i)
    if (mask[i]) {
      bd += static_cast<double>(f.truth[0].medium_backscatter.ptr<float>()[i] /
                                f.truth[0].medium_direct.ptr<float>()[i]);
      ++nb;
    }
  std::printf("%-28s B/D %.2f | media: RMS %.2f mm, median |e| %.2f mm, valid %.1f %% | clear air: RMS %.1f mm, "
              "median |e| %.1f mm, valid %.1f %% | factor %.1f (%zu px)\n",
              c.scene, nb ? bd / static_cast<double>(nb) : std::nan(""), m.rms, m.median_abs, 100 * m.valid, a.rms,
              a.median_abs, 100 * a.valid, a.rms / m.rms, m.pixels);
  ASSERT_GT(m.pixels, mask.size() / 3) << "most of camera 0's view is stereo-visible";
  EXPECT_LT(m.rms, c.max_rms_mm);
  EXPECT_LT(m.median_abs, c.max_median_mm);
  EXPECT_GT(m.valid, 0.95);
  EXPECT_GT(a.rms, c.min_factor * m.rms);
  EXPECT_EQ(media.report["medium"]["sigma_per_mm"].get<double>(), kSigma);
  EXPECT_NE(media.report["constraint"].get<std::string>().find("media"), std::string::npos);
}

INSTANTIATE_TEST_SUITE_P(Fig514, MediaVsClearAir,
                         // Measured (2026-11, seed 13): RMS 0.35 / 1.60 / 9.1 mm, median
                         // 0.27 / 0.88 / 0.49 mm, factors 167 / 59 / 10 (docs/media-stereo.md).
                         ::testing::Values(Claim{"media-stereo-rig-plane", 0.6, 0.4, 50.0},
                                           Claim{"media-stereo-rig-inclined", 2.5, 1.2, 20.0},
                                           Claim{"media-stereo-rig-hemisphere", 14.0, 0.8, 5.0}),
                         [](const ::testing::TestParamInfo<Claim>& p) {
                           std::string s = p.param.scene;
                           std::replace(s.begin(), s.end(), '-', '_');
                           return s;
                         });

// §5.4.1 for binocular: on this rig the projector is the light, so a
// `medium` scan of the medium alone (scene media-stereo-rig-medium-only: the
// objects removed, a black wall at z 2000) floods with the projector and
// fits sigma, beta, g from camera 0's image; its medium_image, passed to a
// `binocular` scan of the plane as the input of that name, replaces the
// params (given here deliberately as clear water).
//
// What this geometry can measure: the projector sits 120 mm above camera 0,
// so most backscatter comes from near-backward angles (gamma ~ 150-177 deg),
// where beta and g trade off (beta p_HG(gamma) is nearly the same for many
// pairs). Measured 2026-11-24 (seed 13), fitting every 4th pixel: sigma
// 0.00260 (+4 %), beta 0.00146 (-34 %), g 0.349 (truth 0.5); every 7th pixel
// (the shipped stride at 160 x 120): sigma 0.00246, beta 0.00257 (+17 %),
// g 0.552; B within 0.24 % / 0.09 % both times. The Helmholtz rig's
// side-by-side units pin all three (helmholtz_rig_test.cpp). The first
// tolerances, stated before measuring and copied from that rig (sigma
// +-15 %, beta +-20 %, g +-0.08), failed for beta and g at the 4-pixel
// stride; so this test asserts what binocular
// needs and the geometry determines: sigma +-15 %; the backscatter B the
// fitted medium predicts along camera 0's rays to the plane (Eq. 5.16, the
// plugin's own integrator for both) within 10 % median of the true medium's
// (chosen after the beta/g measurement, before this B comparison ran); and
// depth with the fitted medium within the plane's claim bounds above (RMS
// < 0.6 mm, median |e| < 0.4 mm, valid > 95 %). beta and g are printed.
TEST(MediaStereoRig, MediumFromOneImageOfTheMediumAloneFeedsBinocular) {
  const nlohmann::json cfg = rig_config();
  Fixture med_rig;
  ASSERT_TRUE(open_rig("media-stereo-rig-medium-only", med_rig));
  const nlohmann::json mp = {{"light_intensity", light_fullscale(cfg)}, {"medium_wall_mm", 2000.0}};
  const ScanOut med = host_scan(*med_rig.rig, mp, "", false, "medium");
  ASSERT_EQ(med.patterns, 1u);
  ASSERT_EQ(med.medium_image.size(), size_t{med_rig.k[0].width} * med_rig.k[0].height);
  EXPECT_EQ(med.report["light"], "projector flood");
  EXPECT_TRUE(med.report.contains("identifiable")) << "the report must say beta and g are not determined here";
  ASSERT_EQ(med.scalars.count("medium_extinction_per_mm"), 1u) << med.report.dump();
  const double sigma = med.scalars.at("medium_extinction_per_mm"), beta = med.scalars.at("medium_scattering_per_mm"),
               g = med.scalars.at("medium_hg_g");
  std::printf("binocular rig, medium fit from one flood image (sim, 12-bit, shot + read noise): sigma %.5f (truth "
              "%.5f), beta %.5f (truth %.5f), g %.3f (truth %.3f), residual %.2e full scale\n",
              sigma, kSigma, beta, kBeta, g, kG, med.report["medium"]["fit_rms_residual_fullscale"].get<double>());
  EXPECT_NEAR(sigma, kSigma, 0.15 * kSigma);

  Fixture f;
  ASSERT_TRUE(open_rig("media-stereo-rig-plane", f));
  const auto mask = stereo_mask(f);
  {  // B of the fitted medium against B of the true one, every 4th stereo-visible pixel
    sdk::Rig rig;
    ASSERT_TRUE(sdk::parse_rig(engine::plugin_rig_json(*f.rig, 2), rig).ok());
    const MediumShot shot = projector_shot(rig);
    const double i0 = light_fullscale(cfg);
    const Intrinsics& k = f.k[0];
    std::vector<double> rel;
    for (uint32_t y = 0; y < k.height; y += 4)
      for (uint32_t x = 0; x < k.width; x += 4) {
        const size_t i = size_t{y} * k.width + x;
        if (!mask[i]) continue;
        const Vec3 ray{(x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0};
        const double t = static_cast<double>(f.truth[0].depth_mm.ptr<float>()[i]) * norm(ray);
        const Vec3 dir = normalized(ray);
        const double b_true = backscatter({kSigma, kBeta, kG}, i0, Vec3{0, 0, 0}, dir, shot.light, t, 4.0, &shot.cone);
        const double b_fit = backscatter({sigma, beta, g}, i0, Vec3{0, 0, 0}, dir, shot.light, t, 4.0, &shot.cone);
        if (b_true > 0) rel.push_back(std::abs(b_fit / b_true - 1));
      }
    ASSERT_GT(rel.size(), 50u);
    const double med_rel = test::percentile(rel, 0.5);
    std::printf("backscatter of the fitted medium vs the true one along camera 0's rays to the plane: median "
                "|rel| %.2f %%, p90 %.2f %% (%zu px)\n",
                100 * med_rel, 100 * test::percentile(rel, 0.9), rel.size());
    EXPECT_LT(med_rel, 0.10);
  }
  const host::InputImage in = test::medium_image_input(med.medium_image, med.width, med.height);
  const nlohmann::json bp = test::with_clear_water(params(cfg, "media"));
  const ScanOut fitted = host_scan(*f.rig, bp, "", false, "binocular", {in});
  ASSERT_EQ(fitted.depth.size(), mask.size());
  EXPECT_EQ(fitted.report["medium"]["fitted"], nlohmann::json({"sigma_per_mm", "beta_per_mm", "g"}));
  EXPECT_TRUE(fitted.report["medium"]["given"].empty());
  EXPECT_DOUBLE_EQ(fitted.report["medium"]["sigma_per_mm"].get<double>(), sigma);
  EXPECT_DOUBLE_EQ(fitted.scalars.at("medium_scattering_per_mm"), beta);
  expect_no_bad_values(fitted.depth);
  const DepthStats m = depth_stats(fitted.depth, f, mask);
  std::printf("binocular on the plane with the fitted medium: RMS %.2f mm, median |e| %.2f mm, valid %.1f %%\n",
              m.rms, m.median_abs, 100 * m.valid);
  EXPECT_LT(m.rms, 0.6);
  EXPECT_LT(m.median_abs, 0.4);
  EXPECT_GT(m.valid, 0.95);

  // Without the input the params stand, and a medium_image of the wrong size is refused by name.
  host::InputImage small = in;
  small.image.width = med.width / 2;
  small.image.stride_bytes = size_t{small.image.width} * sizeof(float);
  host::PluginHost host(host::LoadOptions{.probe_in_child = false});
  ASSERT_TRUE(host.load_file(std::string(PROCAM_PLUGIN_DIR) + "/procam-media-stereo.so").ok());
  host::IsolationOptions iso;
  iso.mode = host::Isolation::in_process;
  host.set_isolation(iso);
  auto bad = host.create_session("media-stereo", "binocular", bp.dump(), engine::plugin_rig_json(*f.rig, 2).dump(),
                                 {small});
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().to_string().find("medium_image"), std::string::npos) << bad.status().to_string();
}

// What the session refuses, and that its message says what to do.
TEST(MediaStereoRig, SessionRefusesRigsAndParamsItCannotUse) {
  Fixture f;
  ASSERT_TRUE(open_rig("media-stereo-rig-plane", f));
  const nlohmann::json good = engine::plugin_rig_json(*f.rig, 2), p = params(rig_config(), "media");
  auto refuse = [&](const nlohmann::json& rig, const nlohmann::json& prm, int code, const std::string& says) {
    std::unique_ptr<sdk::Session> s;
    const sdk::Error e = create_binocular_session({"binocular", prm, rig, {}}, s);
    EXPECT_EQ(e.code, code) << e.message;
    EXPECT_NE(e.message.find(says), std::string::npos) << e.message;
    EXPECT_FALSE(s);
  };
  {
    std::unique_ptr<sdk::Session> s;
    EXPECT_TRUE(create_binocular_session({"binocular", p, good, {}}, s).ok());
  }
  nlohmann::json one = good;
  one["cameras"].erase(1);
  refuse(one, p, PROCAM_ERR_FAILED_PRECONDITION, "two cameras");
  nlohmann::json uncal = good;
  uncal["cameras"][1].erase("calibration");
  refuse(uncal, p, PROCAM_ERR_FAILED_PRECONDITION, "calibrated");
  nlohmann::json distorted = good;
  distorted["cameras"][0]["calibration"]["intrinsics"]["distortion"] = {0.1, 0, 0, 0, 0};
  refuse(distorted, p, PROCAM_ERR_FAILED_PRECONDITION, "undistort");
  nlohmann::json bad = p;
  bad["beta_per_mm"] = 0.01;
  refuse(good, bad, PROCAM_ERR_INVALID_ARGUMENT, "beta_per_mm");
  bad = p;
  bad["window"] = 6;
  refuse(good, bad, PROCAM_ERR_INVALID_ARGUMENT, "odd");
  bad = p;
  bad["constraint"] = "fog";
  refuse(good, bad, PROCAM_ERR_INVALID_ARGUMENT, "constraint");
}

// Hard cases through the session: black frames (no signal) and
// saturated frames give no valid pixel (all NaN).
TEST(MediaStereoRig, BlackAndSaturatedFramesGiveNoDepth) {
  Fixture f;
  ASSERT_TRUE(open_rig("media-stereo-rig-plane", f));
  const sdk::CreateArgs args{"binocular", params(rig_config(), "media"), engine::plugin_rig_json(*f.rig, 2), {}};
  const uint32_t w = f.k[0].width, h = f.k[0].height;
  for (uint16_t level : {uint16_t{0}, uint16_t{4095}}) {
    std::unique_ptr<sdk::Session> s;
    ASSERT_TRUE(create_binocular_session(args, s).ok());
    sdk::Plan plan;
    bool has = false;
    ASSERT_TRUE(s->next_plan(plan, has).ok());
    const std::vector<uint16_t> img(size_t{w} * h, level);
    for (uint32_t i = 0; i < 2; ++i) ASSERT_TRUE(s->add_frame(i, sdk::gray_view(img.data(), w, h, 12)).ok());
    ASSERT_TRUE(s->end_round().ok());
    sdk::Outputs out;
    ASSERT_TRUE(s->outputs(out).ok());
    bool found = false;
    for (size_t k = 0; k < out.size(); ++k) {
      const procam_output& o = out.view()[k];
      if (std::strcmp(o.name, "depth_mm") == 0) {
        found = true;
        const auto* d = static_cast<const float*>(o.image.data);
        for (size_t i = 0; i < size_t{w} * h; ++i) {
          ASSERT_TRUE(std::isnan(d[i])) << "level " << level << " px " << i;
        }
      }
      if (std::strcmp(o.name, "valid_fraction") == 0) {
        EXPECT_EQ(o.scalar, 0.0);
      }
    }
    EXPECT_TRUE(found);
  }
  // A frame of the wrong size is refused and may be added again.
  std::unique_ptr<sdk::Session> s;
  ASSERT_TRUE(create_binocular_session(args, s).ok());
  sdk::Plan plan;
  bool has = false;
  ASSERT_TRUE(s->next_plan(plan, has).ok());
  const std::vector<uint16_t> small(size_t{w / 2} * h, 100);
  const sdk::Error e = s->add_frame(1, sdk::gray_view(small.data(), w / 2, h, 12));
  EXPECT_EQ(e.code, PROCAM_ERR_BAD_FRAME);
  EXPECT_NE(e.message.find("camera 1"), std::string::npos) << e.message;
}

// Item 4 of the brief: the sim's 12-bit frames of the plane, re-quantised to
// 8 bits (v >> 4), stretched to 16 bits (v << 4) and as float (v / 4095),
// through the session in process. Float is the 12-bit data exactly (same
// full-scale values); 16-bit is the same data scaled by 65535/65520, so the
// maps agree to a hair; 8-bit loses 4 bits of the signal.
TEST(MediaStereoRig, EightTwelveSixteenBitAndFloatFramesDecodeAlike) {
  const nlohmann::json cfg = rig_config();
  Fixture f;
  ASSERT_TRUE(open_rig("media-stereo-rig-plane", f));
  const sdk::CreateArgs args{"binocular", params(cfg, "media"), engine::plugin_rig_json(*f.rig, 2), {}};
  std::vector<Image> frames;
  {
    std::unique_ptr<sdk::Session> s;
    ASSERT_TRUE(create_binocular_session(args, s).ok());
    sdk::Plan plan;
    bool has = false;
    ASSERT_TRUE(s->next_plan(plan, has).ok());
    ASSERT_TRUE(has);
    ASSERT_EQ(plan.size(), 2u);
    plan.view();
    for (uint32_t i = 0; i < plan.size(); ++i) {
      ASSERT_EQ(plan.settings(i).camera_index, static_cast<int32_t>(i));
      ASSERT_TRUE(f.rig->projector().show(plan.pattern(i), i + 1).ok());
      auto fr = f.rig->camera(i).capture(std::chrono::milliseconds(2000));
      ASSERT_TRUE(fr.ok()) << fr.status().to_string();
      ASSERT_EQ(fr->image.bit_depth(), 12u);
      frames.push_back(std::move(fr->image));
    }
  }
  const uint32_t w = frames[0].width(), h = frames[0].height();
  const size_t n = size_t{w} * h;
  // Runs one session on frames converted by `make` (returns the view of frame
  // i), the rig describing cameras of `bits` significant bits (32: float).
  auto decode = [&](uint32_t bits, auto make) {
    sdk::CreateArgs a = args;
    for (auto& cam : a.rig["cameras"]) cam["bit_depth"] = bits;
    std::unique_ptr<sdk::Session> s;
    EXPECT_TRUE(create_binocular_session(a, s).ok());
    sdk::Plan plan;
    bool has = false;
    EXPECT_TRUE(s->next_plan(plan, has).ok());
    for (uint32_t i = 0; i < 2; ++i) {
      const sdk::Error e = s->add_frame(i, make(i));
      EXPECT_TRUE(e.ok()) << e.message;
    }
    EXPECT_TRUE(s->end_round().ok());
    sdk::Outputs out;
    EXPECT_TRUE(s->outputs(out).ok());
    for (size_t k = 0; k < out.size(); ++k)
      if (std::strcmp(out.view()[k].name, "depth_mm") == 0) {
        const auto* d = static_cast<const float*>(out.view()[k].image.data);
        return std::vector<float>(d, d + n);
      }
    ADD_FAILURE() << "no depth_mm output";
    return std::vector<float>(n, NAN);
  };
  std::vector<uint16_t> u12[2], u16[2];
  std::vector<uint8_t> u8[2];
  std::vector<float> f32[2];
  for (int i = 0; i < 2; ++i) {
    const uint16_t* p = frames[static_cast<size_t>(i)].ptr<uint16_t>();
    u12[i].assign(p, p + n);
    for (uint16_t v : u12[i]) {
      u16[i].push_back(static_cast<uint16_t>(v << 4));
      u8[i].push_back(static_cast<uint8_t>(v >> 4));
      f32[i].push_back(static_cast<float>(v) / 4095.0f);
    }
  }
  const auto d12 = decode(12, [&](uint32_t i) { return sdk::gray_view(u12[i].data(), w, h, 12); });
  const auto d16 = decode(16, [&](uint32_t i) { return sdk::gray_view(u16[i].data(), w, h, 16); });
  const auto d8 = decode(8, [&](uint32_t i) { return sdk::gray_view(u8[i].data(), w, h, 8); });
  const auto df = decode(32, [&](uint32_t i) { return sdk::gray_view(f32[i].data(), w, h); });
  // A 12-bit camera's frames handed over as U16 claiming 16 bits (as a
  // recorded PNG reads back): scaled by the rig's 12 bits, identical to d12.
  const auto d12as16 = decode(12, [&](uint32_t i) { return sdk::gray_view(u12[i].data(), w, h, 16); });
  const auto mask = stereo_mask(f);
  const DepthStats s12 = depth_stats(d12, f, mask), s16 = depth_stats(d16, f, mask), s8 = depth_stats(d8, f, mask),
                   sf = depth_stats(df, f, mask);
  double max16 = 0, maxf = 0;
  for (size_t i = 0; i < n; ++i) {  // on the interior stereo-visible pixels (border ones may flip a near-tie)
    if (!mask[i]) continue;
    if (std::isfinite(d12[i]) && std::isfinite(d16[i])) max16 = std::max(max16, std::abs(double(d12[i] - d16[i])));
    if (std::isfinite(d12[i]) && std::isfinite(df[i])) maxf = std::max(maxf, std::abs(double(d12[i] - df[i])));
  }
  std::printf("RMS (valid): 8-bit %.2f mm (%.1f %%), 12-bit %.2f mm (%.1f %%), 16-bit %.2f mm (%.1f %%), float %.2f mm "
              "(%.1f %%); max |16-bit - 12-bit| %.3g mm, max |float - 12-bit| %.3g mm\n",
              s8.rms, 100 * s8.valid, s12.rms, 100 * s12.valid, s16.rms, 100 * s16.valid, sf.rms, 100 * sf.valid, max16,
              maxf);
  for (const auto* d : {&d12, &d16, &d8, &df}) expect_no_bad_values(*d);
  for (size_t i = 0; i < n; ++i) {
    if (!(std::isnan(d12[i]) && std::isnan(d12as16[i]))) {
      ASSERT_EQ(d12[i], d12as16[i]) << i;
    }
  }
  EXPECT_LT(s12.rms, 0.6);
  EXPECT_LT(maxf, 1e-3);
  EXPECT_LT(max16, 0.05);
  EXPECT_NEAR(s16.valid, s12.valid, 0.002);
  EXPECT_LT(s8.rms, 0.6);
  EXPECT_GT(s8.valid, 0.95);
}

}  // namespace
}  // namespace procam::media_stereo
