// SPDX-License-Identifier: MIT
// `helmholtz` end to end through the rig (issue 13 item 4, thesis §5.4.2,
// Fig. 5.17): configs/rigs/sim-helmholtz.json (five camera+light units, the
// lights co-located with the cameras, plugin ABI 3 light_index) and the
// media-stereo-rig-* scenes (whole-scene medium σ 0.0025, β 0.0022 /mm,
// g 0.5). The plugin is loaded by the plugin host in process and driven by
// engine::run_scan, which lights each frame with the light its settings name;
// the sim renders each (camera, light) pair with that pair's medium taps.
// Normals are compared with the scenes' analytic normals (planes: their
// normal; half-sphere: (P − centre)/r at the sim's truth point of camera 0),
// the media constraint against the medium-free one (Zickler) on the same
// frames (the recorded scan decoded again by engine::run_offline).
//
// The medium and the lights' photometric scale are params, as for
// `binocular` (I0 = irradiance_at_1m·10⁶ · exposure · sensitivity / full_well,
// the sim's sensor model at 0 dB).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <unistd.h>

#include "procam/core/image_io.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"
#include "host_input_util.hpp"
#include "scatter_model.hpp"
#include "stereo_common.hpp"
#include "stereo_session.hpp"
#include "synthetic.hpp"
#include "test_rig.hpp"

namespace procam::media_stereo {
namespace {

const std::string kConfigs = std::string(PROCAM_SOURCE_DIR) + "/configs";
constexpr double kSigma = 0.0025, kBeta = 0.0022, kG = 0.5;  // the media-stereo-rig-* scenes
constexpr double kZMin = 380, kZMax = 700;

nlohmann::json rig_config() {
  std::ifstream f(kConfigs + "/rigs/sim-helmholtz.json");
  return nlohmann::json::parse(f);
}

double light_fullscale(const nlohmann::json& cfg) {
  const nlohmann::json& c = cfg["cameras"][0];
  return c["light"]["irradiance_at_1m"].get<double>() * 1e6 * c["exposure_us"].get<double>() *
         c["sensitivity"].get<double>() / c["full_well_e"].get<double>();
}

nlohmann::json params(const nlohmann::json& cfg, const std::string& constraint, int frames_per_pair = 1) {
  return {{"constraint", constraint},
          {"sigma_per_mm", kSigma},
          {"beta_per_mm", kBeta},
          {"g", kG},
          {"light_intensity", light_fullscale(cfg)},
          {"z_min_mm", kZMin},
          {"z_max_mm", kZMax},
          {"z_step_mm", 2.0},
          {"window", 5},
          {"frames_per_pair", frames_per_pair}};
}

std::unique_ptr<hw::Rig> open_rig(const std::string& scene) {
  auto rig = hw::create_rig(rig_config(), {kConfigs + "/rigs", {kConfigs + "/scenes"}});
  EXPECT_TRUE(rig.ok()) << rig.status().to_string();
  if (!rig.ok()) return nullptr;
  const Status st = (*rig)->apply_scan_options({{"scene", scene}});
  EXPECT_TRUE(st.ok()) << st.to_string();
  return std::move(*rig);
}

struct ScanOut {
  std::vector<float> depth, integrated, medium_image;
  std::vector<Vec3> normal;
  nlohmann::json report;
  std::map<std::string, double> scalars;
  size_t patterns = 0;
  uint32_t width = 0, height = 0;
};

// One scan of media-stereo `method` through the plugin host (in process) and
// engine::run_scan, or with `offline` engine::run_offline on `record_dir`.
ScanOut host_scan(hw::Rig& rig, const nlohmann::json& p, const std::string& record_dir, bool offline,
                  const std::string& method = "helmholtz", const std::vector<host::InputImage>& inputs = {}) {
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
  auto outs = session->outputs();
  EXPECT_TRUE(outs.ok()) << outs.status().to_string();
  if (!outs.ok()) return r;
  std::vector<float> comp[3];
  for (const host::Output& o : *outs) {
    const auto* d = static_cast<const float*>(o.image.data);
    const size_t n = size_t{o.image.width} * o.image.height;
    if (o.name == "depth_mm") r.depth.assign(d, d + n);
    if (o.name == "depth_integrated_mm") r.integrated.assign(d, d + n);
    if (o.name == "normal_x") comp[0].assign(d, d + n);
    if (o.name == "normal_y") comp[1].assign(d, d + n);
    if (o.name == "normal_z") comp[2].assign(d, d + n);
    if (o.name == "medium_image") {
      r.medium_image.assign(d, d + n);
      r.width = o.image.width;
      r.height = o.image.height;
    }
    if (o.kind == PROCAM_OUTPUT_SCALAR) r.scalars[o.name] = o.scalar;
    if (o.name == "report") r.report = nlohmann::json::parse(o.json);
  }
  EXPECT_EQ(comp[0].size(), r.depth.size());
  EXPECT_EQ(comp[2].size(), r.depth.size());
  for (size_t i = 0; i < comp[0].size() && i < comp[1].size() && i < comp[2].size(); ++i)
    r.normal.push_back({comp[0][i], comp[1][i], comp[2][i]});
  return r;
}

// The scene's analytic unit normal at camera 0's pixel i (facing camera 0),
// or NaN where no surface.
std::vector<Vec3> truth_normals(const std::string& scene, const hw::GroundTruth& t, const Intrinsics& k) {
  const double nan = std::nan("");
  std::vector<Vec3> n(size_t{k.width} * k.height, Vec3{nan, nan, nan});
  const float* depth = t.depth_mm.ptr<float>();
  const uint8_t* obj = t.object.empty() ? nullptr : t.object.ptr<uint8_t>();
  for (uint32_t y = 0; y < k.height; ++y)
    for (uint32_t x = 0; x < k.width; ++x) {
      const size_t i = size_t{y} * k.width + x;
      const double z = depth[i];
      if (!std::isfinite(z)) continue;
      if (scene.starts_with("media-stereo-rig-plane")) {
        n[i] = {0, 0, -1};
      } else if (scene.starts_with("media-stereo-rig-inclined")) {
        n[i] = {0.5, 0, -std::sqrt(3.0) / 2};
      } else {  // half-sphere (object 1) at (75, 0, 580) r 100 on the board z 580 (object 2)
        if (obj != nullptr && obj[i] == 1) {
          const Vec3 p{(x - k.cx) / k.fx * z, (y - k.cy) / k.fy * z, z};
          n[i] = (p - Vec3{75, 0, 580}) / 100.0;
          n[i] = n[i] / norm(n[i]);
        } else {
          n[i] = {0, 0, -1};
        }
      }
    }
  return n;
}

struct Stats {
  double median_deg = 0, p90_deg = 0, depth_rms_mm = 0, integrated_rms_mm = 0, valid = 0;
};

Stats stats(const ScanOut& s, const std::vector<Vec3>& truth_n, const hw::GroundTruth& t, uint32_t w, uint32_t h) {
  std::vector<double> ang, dz, dzi;
  size_t total = 0;
  const float* depth = t.depth_mm.ptr<float>();
  for (uint32_t y = 3; y + 3 < h; ++y)
    for (uint32_t x = 3; x + 3 < w; ++x) {
      const size_t i = size_t{y} * w + x;
      if (!std::isfinite(truth_n[i].x)) continue;
      ++total;
      if (!std::isfinite(s.depth[i])) continue;
      ang.push_back(std::acos(std::clamp(dot(s.normal[i], truth_n[i]), -1.0, 1.0)) * 180 / std::numbers::pi);
      dz.push_back(static_cast<double>(s.depth[i]) - static_cast<double>(depth[i]));
      if (std::isfinite(s.integrated[i])) dzi.push_back(static_cast<double>(s.integrated[i]) - static_cast<double>(depth[i]));
    }
  return {test::percentile(ang, 0.5), test::percentile(ang, 0.9), test::rms(dz), test::rms(dzi),
          total ? static_cast<double>(ang.size()) / static_cast<double>(total) : 0.0};
}

struct Claim {
  const char* scene;
  double max_median_deg;  // media constraint, normal angle
  double min_factor;      // Zickler median / media median
  int frames_per_pair = 1;
};

class HelmholtzThroughTheRig : public ::testing::TestWithParam<Claim> {};

TEST_P(HelmholtzThroughTheRig, NormalsAgainstTruthAndZickler) {
  const Claim c = GetParam();
  const nlohmann::json cfg = rig_config();
  auto rig = open_rig(c.scene);
  ASSERT_TRUE(rig);
  auto truth = rig->ground_truth(0);
  ASSERT_TRUE(truth.ok()) << truth.status().to_string();
  const Intrinsics k = rig->camera_calibrations()[0].intrinsics;
  const auto tn = truth_normals(c.scene, *truth, k);
  const std::string rec = (std::filesystem::temp_directory_path() /
                           ("procam_helmholtz_" + std::to_string(::getpid()) + "_" + c.scene)).string();
  std::filesystem::create_directories(rec);
  const ScanOut media = host_scan(*rig, params(cfg, "media", c.frames_per_pair), rec, false);
  const ScanOut zickler = host_scan(*rig, params(cfg, "clear-air", c.frames_per_pair), rec, true);
  std::filesystem::remove_all(rec);
  ASSERT_EQ(media.patterns, 8u * static_cast<size_t>(c.frames_per_pair));  // 4 pairs x 2 images x frames_per_pair
  ASSERT_EQ(media.depth.size(), tn.size());
  ASSERT_EQ(zickler.depth.size(), tn.size());
  const Stats m = stats(media, tn, *truth, k.width, k.height), z = stats(zickler, tn, *truth, k.width, k.height);
  std::printf("%s, %d frame(s) per pair image: media normal median %.2f p90 %.2f deg, depth RMS %.1f mm (integrated %.1f), valid %.3f | "
              "zickler median %.2f p90 %.2f deg, depth RMS %.1f mm, valid %.3f | factor %.1f\n",
              c.scene, c.frames_per_pair, m.median_deg, m.p90_deg, m.depth_rms_mm, m.integrated_rms_mm, m.valid, z.median_deg,
              z.p90_deg, z.depth_rms_mm, z.valid, z.median_deg / m.median_deg);
  EXPECT_LT(m.median_deg, c.max_median_deg);
  EXPECT_GE(m.valid, 0.9);
  EXPECT_GE(z.median_deg, c.min_factor * m.median_deg);
  EXPECT_EQ(media.report["medium"]["source"], "params");
}

INSTANTIATE_TEST_SUITE_P(Objects, HelmholtzThroughTheRig,
                         // Measured (2026-11-24, rig seed 13, the sim's A on both legs, reciprocal):
                         // media median 6.03 / 6.00 / 9.92 deg, Zickler 35.4 / 40.7 / 38.3 deg
                         // (factor 5.9 / 6.8 / 3.9). Noise-free 0.29 / 0.62 / 1.63 deg (a local
                         // experiment), so sensor noise is what is left: B is 2-5 x D. Averaging
                         // 4 frames per pair image (param frames_per_pair) halves the error:
                         // 2.98 / 2.93 / 5.51 deg (factor 11.8 / 14.1 / 7.0); 16 frames gave
                         // 1.54 / 1.62 / 3.05 deg. The bounds leave ~25 % margin over the measured
                         // values. Before (A along the light's leg only, not reciprocal):
                         // 14.3 / 15.0 / 22.1 deg.
                         ::testing::Values(Claim{"media-stereo-rig-plane-matte", 7.5, 4.5},
                                           Claim{"media-stereo-rig-inclined-matte", 7.5, 5.0},
                                           Claim{"media-stereo-rig-hemisphere-matte", 12.5, 3.0},
                                           Claim{"media-stereo-rig-plane-matte", 3.7, 9.0, 4},
                                           Claim{"media-stereo-rig-inclined-matte", 3.7, 11.0, 4},
                                           Claim{"media-stereo-rig-hemisphere-matte", 6.9, 5.5, 4}),
                         [](const auto& param_info) {
                           std::string n = param_info.param.scene;
                           std::replace(n.begin(), n.end(), '-', '_');
                           if (param_info.param.frames_per_pair > 1)
                             n += "_averaged_" + std::to_string(param_info.param.frames_per_pair);
                           return n;
                         });

// frames_per_pair n > 1: each pair image is the mean of n frames, and a
// sample clipped in ANY of them stays clipped (the mean of a clipped and an
// unclipped sample looks like a valid, wrong signal). Scanned once with n = 2
// and recorded; then the first of camera 0's two frames of every pair is
// clipped on its left half (x < w/2) and the recording decoded offline.
// Camera 0's image enters every pair, so its left half must give no depth at
// all, while the right half decodes as the untouched recording does.
TEST(HelmholtzRig, FramesPerPairKeepsASampleClippedInAnyFrameClipped) {
  const nlohmann::json cfg = rig_config();
  auto rig = open_rig("media-stereo-rig-plane-matte");
  ASSERT_TRUE(rig);
  const std::string rec = (std::filesystem::temp_directory_path() /
                           ("procam_helmholtz_fpp_" + std::to_string(::getpid()))).string();
  std::filesystem::create_directories(rec);
  const ScanOut live = host_scan(*rig, params(cfg, "media", 2), rec, false);
  ASSERT_EQ(live.patterns, 16u);  // 4 pairs x 2 images x 2 frames
  const ScanOut again = host_scan(*rig, params(cfg, "media", 2), rec, true);
  uint32_t w = 0, h = 0;
  // Frame index (2(j-1) + side)·n + k; side 0 is camera 0, k = 0 the first repeat.
  for (size_t j = 1; j <= 4; ++j) {
    const std::string path = rec + "/" + engine::recorded_frame_name(1, (2 * (j - 1)) * 2);
    auto img = read_image(path);
    ASSERT_TRUE(img.ok()) << img.status().to_string();
    w = img->width(), h = img->height();
    ASSERT_EQ(img->channels(), 1u);
    const auto top = static_cast<uint16_t>(img->max_value());
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w / 2; ++x) img->row<uint16_t>(y)[x] = top;
    ASSERT_TRUE(write_image(path, *img).ok());
  }
  const ScanOut clipped = host_scan(*rig, params(cfg, "media", 2), rec, true);
  std::filesystem::remove_all(rec);
  ASSERT_EQ(again.depth.size(), size_t{w} * h);
  ASSERT_EQ(clipped.depth.size(), size_t{w} * h);
  size_t left_before = 0, left_after = 0, right_before = 0, right_same = 0;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t i = size_t{y} * w + x;
      if (x < w / 2) {
        left_before += std::isfinite(again.depth[i]);
        left_after += std::isfinite(clipped.depth[i]);
      } else if (x >= w / 2 + 8 && std::isfinite(again.depth[i])) {  // beyond the 5x5 window's reach
        ++right_before;
        right_same += clipped.depth[i] == again.depth[i];
      }
    }
  std::printf("frames_per_pair 2, left half clipped in one frame: valid left %zu -> %zu, right unchanged %zu of %zu\n",
              left_before, left_after, right_same, right_before);
  EXPECT_GT(left_before, size_t{w} * h / 8) << "the untouched recording should decode the left half";
  EXPECT_EQ(left_after, 0u) << "a sample clipped in one of the n frames must stay clipped in their mean";
  EXPECT_GT(right_before, size_t{w} * h / 8);
  EXPECT_EQ(right_same, right_before) << "pixels away from the clipped half should not change";
}

// ---- issue 13: where the error came from, and reciprocity ----------------
// The lead measured, on the matte plane: 14.3 deg with noise, 7.76 deg and an
// 85 mm rank-minimum depth bias without noise, 0.20 deg in clear water. The
// test below splits each pair image into the terms the plugin models (Eq.
// 5.24: I = D + B) with noise off. Measured:
//  - B: the sim's frame of the medium alone (black wall at 2 m) against the
//    plugin's backscatter() for the same camera ray, light centre and field,
//    all 8 pair images: ratio 0.991-1.008 (median 1.000). The light-k path
//    (poses, field, irradiance scale) is right.
//  - the surface signal (I - B) / D on the plane: the sim adds its indirect
//    signal A (forward-scattered light, thesis Eq. 5.12,
//    hw/sim/src/medium_indirect.cpp), which the plugin does not model. Until
//    2026-11-24 A was taken along the light's leg only and was not
//    reciprocal: camera 0 lit by unit j read 1.73-1.75, camera j lit by unit
//    0 1.65-1.66 (5 % apart at the same points), and the noiseless scan gave
//    7.76 deg. Now A is forward scattering on both legs with normalised
//    blurs: (I - B) / D = (1 + R_L)(1 + R_C) = 2.97-3.01 (median), the two
//    images of a pair agree at the same surface points to 0.05 % (pairs 1,
//    3) and 0.7 % (pairs 2, 4; p90 1.7 %, max 2.4 %: 12-bit quantisation of
//    a D of a few % of full scale), and the noiseless scan gives 0.29 deg.
nlohmann::json noiseless(nlohmann::json cfg) {
  for (auto& c : cfg["cameras"]) {
    c["shot_noise"] = false;
    c["read_noise_e"] = 0.0;
  }
  return cfg;
}

// Camera `camera`'s frame lit by rig light `light` alone, full scale.
std::vector<float> capture_lit(hw::Rig& rig, size_t camera, size_t light) {
  EXPECT_TRUE(rig.select_light(light).ok());
  auto f = rig.camera(camera).capture(std::chrono::milliseconds(1000));
  EXPECT_TRUE(f.ok()) << f.status().to_string();
  std::vector<float> out;
  if (!f.ok()) return out;
  const Image& im = f->image;
  const double full = static_cast<double>((1u << im.bit_depth()) - 1u);
  out.resize(size_t{im.width()} * im.height());
  for (uint32_t y = 0; y < im.height(); ++y)
    for (uint32_t x = 0; x < im.width(); ++x)
      out[size_t{y} * im.width() + x] = static_cast<float>(static_cast<double>(im.row<uint16_t>(y)[x]) / full);
  return out;
}

TEST(HelmholtzRigTerms, PairBackscatterMatchesThePluginAndSurfaceSignalCarriesTheSimsA) {
  const nlohmann::json cfg = noiseless(rig_config());
  const double i0 = light_fullscale(cfg);
  const MediumParams med{kSigma, kBeta, kG};
  for (const char* scene : {"media-stereo-rig-medium-only", "media-stereo-rig-plane-matte"}) {
    auto rig = hw::create_rig(cfg, {kConfigs + "/rigs", {kConfigs + "/scenes"}});
    ASSERT_TRUE(rig.ok()) << rig.status().to_string();
    ASSERT_TRUE((*rig)->apply_scan_options({{"scene", scene}}).ok());
    const auto& cal = (*rig)->camera_calibrations();
    const auto lights = (*rig)->lights();
    ASSERT_EQ(lights.size(), 5u);
    // The plugin's composition (helmholtz_session.cpp units_from_rig): world = camera 0's frame.
    std::vector<Rigid3> world_from_cam;
    for (const auto& c : cal) world_from_cam.push_back(cal[0].cam_from_proj * c.cam_from_proj.inverse());
    const bool medium_only = std::string(scene).find("medium-only") != std::string::npos;
    for (size_t j = 1; j < 5; ++j) {
      // Per side: the surface points (world) of camera 0's sample pixels and
      // (I - B) / D there (side 1: at the nearest pixel of camera j).
      std::vector<Vec3> points;
      std::vector<double> side_ratio[2];
      for (int side = 0; side < 2; ++side) {
        // pair-j-a: camera 0 lit by unit j's light; pair-j-b: camera j lit by unit 0's.
        const size_t cam = side == 0 ? 0 : j, lcam = side == 0 ? j : 0;
        ASSERT_EQ(lights[lcam].camera, lcam);
        const std::vector<float> img = capture_lit(**rig, cam, lcam + 1);
        ASSERT_FALSE(img.empty());
        auto truth = (*rig)->ground_truth(cam);
        ASSERT_TRUE(truth.ok());
        const Intrinsics& k = cal[cam].intrinsics;
        const PinholeCamera pc = pinhole_of(k, world_from_cam[cam]);
        const hw::LightInfo& li = lights[lcam];
        const Rigid3 world_from_light = world_from_cam[lcam] * li.cam_from_light;
        const LightCone cone = cone_of(world_from_light.inverse(), li.field.width, li.field.height, li.field.fx,
                                       li.field.fy, li.field.cx, li.field.cy);
        const Vec3 c = pc.centre(), l = world_from_light.translation_mm;
        // B from the plugin's model, and the medium-only ratio or (I - B) / D at pixel (x, y).
        auto ratio_at = [&](uint32_t x, uint32_t y) {
          const size_t i = size_t{y} * k.width + x;
          Vec3 dir = pc.ray_world(x, y);
          const double per_depth = norm(dir);
          dir = dir / per_depth;
          const double z = static_cast<double>(truth->depth_mm.ptr<float>()[i]);
          if (!medium_only && !std::isfinite(z)) return std::nan("");
          const double t = medium_only ? (2000.0 - c.z) / dir.z : z * per_depth;  // the wall is z = 2000
          const double b = backscatter(med, i0, c, dir, l, t, 1.0, &cone);
          EXPECT_GT(b, 0.0);
          if (medium_only) return static_cast<double>(img[i]) / b;
          // D of Eq. 5.25 for the plane (normal (0, 0, -1), albedo 0.5).
          const Vec3 p = c + dir * t, to_light = l - p;
          if (side == 0) points.push_back(p);
          const double dl = norm(to_light);
          const double d = i0 * 0.5 / std::numbers::pi * std::max(0.0, -to_light.z / dl) / (dl * dl) *
                           std::exp(-kSigma * (dl + t));
          return (static_cast<double>(img[i]) - b) / d;
        };
        std::vector<double> ratio;
        if (side == 0 || medium_only) {
          for (uint32_t y = 4; y < k.height; y += 8)
            for (uint32_t x = 4; x < k.width; x += 8) {
              const size_t before = points.size();
              const double r = ratio_at(x, y);
              if (points.size() > before) side_ratio[0].push_back(r);  // aligned with points
              if (std::isfinite(r)) ratio.push_back(r);
            }
        } else {
          // Camera j at the same surface points as camera 0 (nearest pixel).
          for (const Vec3& p : points) {
            double u = 0, v = 0, zz = 0;
            const bool in = pc.project(p, u, v, zz) && u >= 0 && v >= 0 && u <= k.width - 1.0 && v <= k.height - 1.0;
            const double r = in ? ratio_at(static_cast<uint32_t>(std::lround(u)), static_cast<uint32_t>(std::lround(v)))
                                : std::nan("");
            side_ratio[1].push_back(r);
            if (std::isfinite(r)) ratio.push_back(r);
          }
        }
        ASSERT_GT(ratio.size(), 50u);
        std::sort(ratio.begin(), ratio.end());
        const double med_r = ratio[ratio.size() / 2];
        std::printf("%s camera %zu lit by unit %zu's light: %s median %.3f (%.3f..%.3f)\n", scene, cam, lcam,
                    medium_only ? "sim / plugin B" : "(I - B) / D", med_r, ratio.front(), ratio.back());
        if (medium_only) {
          // Measured 0.991..1.008; the plugin integrates at 1 mm steps, the sim's taps to < 1e-3.
          EXPECT_GT(ratio.front(), 0.985);
          EXPECT_LT(ratio.back(), 1.015);
        } else {
          // The sim's A (forward scattering on both legs, hw/sim/src/medium_indirect.cpp):
          // (I - B) / D = (1 + R_L)(1 + R_C), R ~ 0.7 on this rig's legs (measured
          // medians 2.97-3.01). If this fails with a median near 1, the sim no longer
          // renders A and HelmholtzThroughTheRig should be re-measured (issue 13).
          EXPECT_GT(med_r, 2.6);
          EXPECT_LT(med_r, 3.4);
        }
      }
      if (medium_only) continue;
      // Reciprocity (Eq. 5.32 needs I - B of the two images of a pair to
      // differ only by the geometric factors that D carries): (I - B) / D of
      // camera 0 lit by unit j against camera j lit by unit 0 at the same
      // surface points. The light-leg-only A of session 11 gave 1.73-1.75
      // against 1.65-1.66 here (5 % apart). Measured now: median 0.05-0.7 %,
      // p90 0.12-1.7 % (12-bit quantisation; noise is off).
      std::vector<double> rel;
      for (size_t q = 0; q < points.size() && q < side_ratio[1].size(); ++q)
        if (std::isfinite(side_ratio[0][q]) && std::isfinite(side_ratio[1][q]))
          rel.push_back(std::abs(side_ratio[0][q] / side_ratio[1][q] - 1.0));
      ASSERT_GT(rel.size(), 50u);
      std::sort(rel.begin(), rel.end());
      const double rel_med = rel[rel.size() / 2], rel_p90 = rel[rel.size() * 9 / 10];
      std::printf("pair %zu reciprocity: |a / b - 1| median %.4f p90 %.4f max %.4f (%zu points)\n", j, rel_med, rel_p90,
                  rel.back(), rel.size());
      EXPECT_LT(rel_med, 0.01);
      EXPECT_LT(rel_p90, 0.03);
    }
  }
}

// §5.4.1 inside the scan: a `medium` scan of the medium alone (scene
// media-stereo-rig-medium-only: the objects removed, a black wall at z 2000)
// fits σ, β, g (measured: σ 0.00235, β 0.00237, g 0.545 against 0.0025,
// 0.0022, 0.5); its medium_image, passed to a `helmholtz` scan of the matte
// plane as the input of that name, replaces the params (given here
// deliberately wrong: clear water), and the normals are as good as with the
// true medium.
TEST(MediumThroughTheRig, FitFromOneImageOfTheMediumAloneFeedsHelmholtz) {
  const nlohmann::json cfg = rig_config();
  auto medium_rig = open_rig("media-stereo-rig-medium-only");
  ASSERT_TRUE(medium_rig);
  const nlohmann::json mp = {{"light_intensity", light_fullscale(cfg)}, {"medium_wall_mm", 2000.0}};
  const ScanOut med = host_scan(*medium_rig, mp, "", false, "medium");
  ASSERT_EQ(med.patterns, 1u);
  ASSERT_EQ(med.medium_image.size(), size_t{96} * 72);
  ASSERT_EQ(med.scalars.count("medium_extinction_per_mm"), 1u) << med.report.dump();
  const double sigma = med.scalars.at("medium_extinction_per_mm"), beta = med.scalars.at("medium_scattering_per_mm"),
               g = med.scalars.at("medium_hg_g");
  std::printf("medium fit from one image (sim, 12-bit, shot + read noise): sigma %.5f (truth %.5f), beta %.5f "
              "(truth %.5f), g %.3f (truth %.3f), residual %.2e full scale\n",
              sigma, kSigma, beta, kBeta, g, kG, med.report["medium"]["fit_rms_residual_fullscale"].get<double>());
  // Tolerances: the library fit (docs/media-stereo.md) recovers σ to ±10 %,
  // β to ±20 % and g to ±0.05 at 3 % noise; here the noise is the sim
  // sensor's (12-bit, shot and read noise, backscatter of a few % of full
  // scale), the light is clipped to its field, and the wall ends the rays at
  // 2 m. Stated: σ ±15 %, β ±20 %, g ±0.08.
  EXPECT_NEAR(sigma, kSigma, 0.15 * kSigma);
  EXPECT_NEAR(beta, kBeta, 0.20 * kBeta);
  EXPECT_NEAR(g, kG, 0.08);

  auto rig = open_rig("media-stereo-rig-plane-matte");
  ASSERT_TRUE(rig);
  auto truth = rig->ground_truth(0);
  ASSERT_TRUE(truth.ok()) << truth.status().to_string();
  const Intrinsics k = rig->camera_calibrations()[0].intrinsics;
  const auto tn = truth_normals("media-stereo-rig-plane-matte", *truth, k);
  const host::InputImage in = test::medium_image_input(med.medium_image, med.width, med.height);
  const nlohmann::json hp = test::with_clear_water(params(cfg, "media"));
  const ScanOut fitted = host_scan(*rig, hp, "", false, "helmholtz", {in});
  ASSERT_EQ(fitted.depth.size(), tn.size());
  EXPECT_EQ(fitted.report["medium"]["fitted"], nlohmann::json({"sigma_per_mm", "beta_per_mm", "g"}));
  EXPECT_TRUE(fitted.report["medium"]["given"].empty());
  EXPECT_DOUBLE_EQ(fitted.report["medium"]["sigma_per_mm"].get<double>(), sigma);
  const Stats st = stats(fitted, tn, *truth, k.width, k.height);
  std::printf("helmholtz on the plane with the fitted medium: normal median %.2f p90 %.2f deg, valid %.3f\n",
              st.median_deg, st.p90_deg, st.valid);
  // Measured 6.56 deg with the fit, 6.03 with the true medium as params
  // (HelmholtzThroughTheRig); until 2026-11-24 (the sim's A not reciprocal)
  // 13.9 and 14.3. Bound: ~25 % over 6.56.
  EXPECT_LT(st.median_deg, 8.2);
  EXPECT_GE(st.valid, 0.9);
}

}  // namespace
}  // namespace procam::media_stereo
