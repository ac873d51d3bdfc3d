// SPDX-License-Identifier: MIT
#include "helmholtz_session.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "binocular_session.hpp"
#include "helmholtz.hpp"
#include "medium_fit.hpp"
#include "normal_integration.hpp"

namespace procam::media_stereo {
namespace {

using sdk::ParamSpec;
using sdk::ParamType;

// A light farther than this from its camera's centre breaks reciprocity
// beyond what the matcher tolerates: the pair's two paths differ by the
// offset (mm).
constexpr double kMaxLightOffsetMm = 1.0;

const std::vector<ParamSpec>& helmholtz_params() {
  static const std::vector<ParamSpec> specs = [] {
    std::vector<ParamSpec> s = stereo_params(
        5,
        "'media' removes each image's backscatter before the reciprocity constraint (Eq. 5.32); 'clear-air' is "
        "the medium-free Helmholtz stereo of Zickler et al. on the same frames (the baseline)",
        "I0 of every light in full-scale units x mm^2: a white Lambertian surface facing a light at d mm in clear "
        "water reads I0 / (pi d^2) of full scale (a photometric calibration of lights and cameras)");
    s.push_back({"frames_per_pair", ParamType::integer, 1, 1, 64, {},
                 "frames captured and averaged per pair image (sensor noise falls as 1/sqrt(n); a sample saturated "
                 "in any of them stays saturated)"});
    return s;
  }();
  return specs;
}

// Params of the `medium` method (the §5.4.1 image of the medium alone).
const std::vector<ParamSpec>& medium_params() {
  static const std::vector<ParamSpec> specs = {
      {"light_intensity", ParamType::number, 1.0e6, 1e-12, 1e30, {},
       "I0 of the light in full-scale units x mm^2 (as for helmholtz or binocular)"},
      {"medium_wall_mm", ParamType::number, 2000.0, 1, 1e6, {},
       "z (camera 0's frame) of the black wall that ends every ray (the tank's far wall, blackened)"},
      {"saturation", ParamType::number, 0.999, 0.01, 1e30, {}, "samples at/above this (full scale) drop out"},
  };
  return specs;
}

struct Unit {
  size_t camera = 0;
  int32_t light_index = 0;  // settings.light_index of its light
  PinholeCamera cam;
  LightCone cone;           // its light's field
  uint32_t bits = 8;
};

// §5.4.1's shot on a rig of units: camera 0 lit by unit 1's light (the other
// unit nearest in the plan order: side by side, so the scattering angles vary
// over the image and g is observable; a co-located light sees γ = π
// everywhere), its field the light's cone.
MediumShot unit_shot(const std::vector<Unit>& units) {
  return {units[0].cam, units[1].cam.centre(), units[1].cone, "unit 1's light"};
}

class HelmholtzSession final : public sdk::Session {
 public:
  HelmholtzSession(std::vector<Unit> units, const sdk::Rig& rig, const sdk::Params& p,
                   const std::optional<MediumFit>& fit)
      : params_(p.json()), units_(std::move(units)), fit_(fit), search_(search_from(p)) {
    in_.light_intensity = p.get_number("light_intensity");
    in_.medium = medium_of(p, fit);
    media_ = p.get_string("constraint") == "media";
    proj_w_ = rig.projector_width;
    proj_h_ = rig.projector_height;
    repeats_ = static_cast<uint32_t>(p.get_int("frames_per_pair"));
    images_.resize(2 * (units_.size() - 1));
    peak_.resize(images_.size());
    seen_.assign(images_.size(), 0);
  }

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (planned_) return sdk::ok();
    planned_ = true;
    // Pair j: frame 2(j-1) camera 0 lit by unit j's light, frame 2(j-1)+1
    // camera j lit by unit 0's light. The projector stays dark.
    // With frames_per_pair n > 1 each of them n times in a row (frame
    // index (2(j-1) + side)·n + k, named pair-j-a-k), averaged in add_frame.
    for (size_t j = 1; j < units_.size(); ++j)
      for (int side = 0; side < 2; ++side)
        for (uint32_t k = 0; k < repeats_; ++k) {
          const std::string name = "pair-" + std::to_string(j) + (side == 0 ? "-a" : "-b") +
                                   (repeats_ > 1 ? "-" + std::to_string(k) : "");
          const uint32_t f = plan.add_frame(name, proj_w_, proj_h_);
          plan.settings(f).camera_index = static_cast<int32_t>(units_[side == 0 ? 0 : j].camera);
          plan.settings(f).light_index = units_[side == 0 ? j : 0].light_index;
        }
    has_round = true;
    return sdk::ok();
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    sdk::ScopedMs t(decode_ms_);
    const uint32_t slot = index / repeats_;  // 2(j-1) + side
    if (slot >= images_.size()) return sdk::invalid_argument("frame " + std::to_string(index) + " is not in the plan");
    const Unit& u = slot % 2 == 0 ? units_[0] : units_[slot / 2 + 1];
    if (sdk::Error e = sdk::check_frame(&frame, u.cam.width, u.cam.height, 1,
                                        "frame " + std::to_string(index) + " (camera " + std::to_string(u.camera) + ")");
        !e.ok())
      return e;
    if (repeats_ == 1) {
      frame_to_full_scale(frame, u.bits, images_[slot]);
      return sdk::ok();
    }
    // Running sum and per-sample peak; the n-th frame of the slot turns them
    // into the mean, saturated wherever one of the frames was.
    frame_to_full_scale(frame, u.bits, one_);
    std::vector<float>& sum = images_[slot];
    std::vector<float>& peak = peak_[slot];
    if (seen_[slot] == 0) {
      sum = one_;
      peak = one_;
    } else {
      for (size_t i = 0; i < sum.size(); ++i) {
        sum[i] += one_[i];
        peak[i] = std::max(peak[i], one_[i]);
      }
    }
    if (++seen_[slot] == repeats_) {
      const float inv = 1.0f / static_cast<float>(repeats_), sat = static_cast<float>(search_.saturation);
      for (size_t i = 0; i < sum.size(); ++i) sum[i] = peak[i] >= sat ? peak[i] : sum[i] * inv;
      std::vector<float>().swap(peak);
    }
    return sdk::ok();
  }

  sdk::Error end_round() override {
    sdk::ScopedMs t(decode_ms_);
    for (size_t k = 0; repeats_ > 1 && k < seen_.size(); ++k)
      if (seen_[k] != repeats_)
        return sdk::failed_precondition("pair image " + std::to_string(k) + " got " + std::to_string(seen_[k]) +
                                        " of its " + std::to_string(repeats_) + " frames (frames_per_pair)");
    in_.reference = units_[0].cam;
    in_.pairs.clear();
    for (size_t j = 1; j < units_.size(); ++j) {
      ReciprocalPair pr;
      pr.cam_a = units_[0].cam;
      pr.cam_b = units_[j].cam;
      pr.image_a = images_[2 * (j - 1)];      // camera 0, light at unit j
      pr.image_b = images_[2 * (j - 1) + 1];  // camera j, light at unit 0
      pr.cone_b = units_[j].cone;
      pr.cone_a = units_[0].cone;
      in_.pairs.push_back(std::move(pr));
    }
    result_ = helmholtz_stereo(in_, search_, media_);
    integrated_ = integrate_normals(units_[0].cam, result_.normal, result_.depth_mm);
    valid_ = 0;
    for (float z : result_.depth_mm) valid_ += std::isfinite(z) ? 1u : 0u;
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    const PinholeCamera& c = units_[0].cam;
    out.add_image("depth_mm", "mm",
                  "depth (z in camera 0's frame) at the minimum of the rank measure s3/s2 of W(z) (Eq. 5.34); NaN "
                  "invalid",
                  c.width, c.height, result_.depth_mm);
    out.add_image("depth_integrated_mm", "mm",
                  "depth from integrating the normals (perspective log-depth Poisson solve) seeded with depth_mm; "
                  "NaN where no gradient edge reaches",
                  c.width, c.height, integrated_);
    // World = camera 0's frame, so the world normals are camera 0's.
    const char* axes[3] = {"normal_x", "normal_y", "normal_z"};
    for (int k = 0; k < 3; ++k) {
      std::vector<float> comp(result_.normal.size());
      for (size_t i = 0; i < comp.size(); ++i) comp[i] = static_cast<float>(result_.normal[i][k]);
      out.add_image(axes[k], "",
                    std::string("component ") + "xyz"[k] +
                        " of the unit surface normal in camera 0's frame (right null vector of W, facing the "
                        "camera); NaN invalid",
                    c.width, c.height, std::move(comp));
    }
    out.add_image("rank_ratio", "", "s3/s2 of W at the chosen depth, window-averaged (0: rank 2 exactly)", c.width,
                  c.height, result_.rank_ratio);
    sdk::StandardOutputs s;
    s.decode_ms = decode_ms_;
    s.pattern_count = static_cast<uint32_t>(images_.size() * repeats_);
    s.valid_pixels = valid_;
    s.total_pixels = result_.depth_mm.size();
    nlohmann::json pairs = nlohmann::json::array();
    for (size_t j = 1; j < units_.size(); ++j)
      pairs.push_back({{"camera_a", units_[0].camera},
                       {"camera_b", units_[j].camera},
                       {"light_a", units_[0].light_index},
                       {"light_b", units_[j].light_index},
                       {"baseline_mm", norm(units_[j].cam.centre() - units_[0].cam.centre())}});
    s.report = {
        {"method", "helmholtz"},
        {"constraint", media_ ? "media: backscatter removed (Eq. 5.32-5.34)"
                              : "clear-air: Zickler et al., no backscatter removal (Eq. 5.34 on raw intensities)"},
        {"model", "single scattering (Eq. 5.24-5.29), isotropic lights at the camera centres clipped to their "
                  "fields, Lambertian or reciprocal BRDF, rank-2 W at the true depth"},
        {"medium", medium_report(in_.medium, fit_,
                                 "fit_medium() on the input medium_image (thesis 5.4.1; camera 0 lit by unit 1's "
                                 "light)")},
        {"light_intensity_fullscale_mm2", in_.light_intensity},
        {"pairs", pairs},
        {"params", params_}};
    sdk::add_standard_outputs(out, s);
    if (fit_) add_medium_scalars(out, in_.medium, "fitted from the input medium_image (thesis 5.4.1)");
    return sdk::ok();
  }

 private:
  nlohmann::json params_;
  std::vector<Unit> units_;  // [0] the reference unit
  std::optional<MediumFit> fit_;
  DepthSearch search_;
  std::vector<std::vector<float>> images_;
  // frames_per_pair > 1: per slot the peak sample and the frames seen so far; one_ scratch.
  std::vector<std::vector<float>> peak_;
  std::vector<uint32_t> seen_;
  std::vector<float> one_;
  uint32_t repeats_ = 1;
  HelmholtzInput in_;
  bool media_ = true, planned_ = false;
  uint32_t proj_w_ = 0, proj_h_ = 0;
  HelmholtzResult result_;
  std::vector<float> integrated_;
  size_t valid_ = 0;
  double decode_ms_ = 0;
};

// The rig description's "lights" (ABI 3) as units: camera 0's light first,
// then every other camera with a light, in camera order.
sdk::Error units_from_rig(const nlohmann::json& rig_json, const sdk::Rig& rig, std::vector<Unit>& units,
                          size_t min_others) {
  const auto* lights = rig_json.is_object() && rig_json.contains("lights") ? &rig_json.at("lights") : nullptr;
  if (lights == nullptr || !lights->is_array())
    return sdk::failed_precondition(
        "media-stereo 'helmholtz' needs camera+light units (rig description \"lights\", plugin ABI 3: a light at "
        "each camera's centre, e.g. a ring light or a beam splitter) and this rig has none; e.g. "
        "configs/rigs/sim-helmholtz.json");
  const Rigid3 cam0_from_proj = rig.cameras[0].calibration.cam_from_proj;
  std::vector<Unit> found;
  double irradiance0 = -1;
  for (size_t k = 0; k < lights->size(); ++k) {
    const nlohmann::json& l = (*lights)[k];
    const std::string at = "rig: lights[" + std::to_string(k) + "]";
    Unit u;
    Rigid3 cam_from_light;
    Intrinsics field;
    double irradiance = 0;
    try {
      u.camera = l.at("camera").get<size_t>();
      cam_from_light = l.at("cam_from_light").get<Rigid3>();
      field = l.at("field").get<Intrinsics>();
      irradiance = l.at("irradiance_at_1m").get<double>();
    } catch (const std::exception& e) {
      return sdk::invalid_argument(at + " is malformed (" + e.what() + ")");
    }
    if (u.camera >= rig.cameras.size()) return sdk::invalid_argument(at + ".camera names no camera of the rig");
    if (!rig.cameras[u.camera].calibrated || rig.cameras[u.camera].calibration.intrinsics.distorted() ||
        !field.valid())
      return sdk::failed_precondition(
          "media-stereo 'helmholtz': camera " + std::to_string(u.camera) +
          " needs a pinhole calibration (intrinsics and cam_from_proj, no distortion) and its light a valid field");
    if (norm(cam_from_light.translation_mm) > kMaxLightOffsetMm)
      return sdk::failed_precondition("media-stereo 'helmholtz': the light of camera " + std::to_string(u.camera) +
                                      " is " + std::to_string(norm(cam_from_light.translation_mm)) +
                                      " mm off the camera's centre; reciprocal pairs need it within 1 mm (a ring "
                                      "light around the lens or a beam splitter)");
    if (irradiance0 < 0) irradiance0 = irradiance;
    if (std::abs(irradiance - irradiance0) > 0.01 * irradiance0)
      return sdk::failed_precondition(
          "media-stereo 'helmholtz': the rig's lights differ in irradiance_at_1m; Eq. 5.32 needs equal light "
          "intensities within 1 %");
    u.light_index = static_cast<int32_t>(k + 1);
    const Rigid3 world_from_cam = cam0_from_proj * rig.cameras[u.camera].calibration.cam_from_proj.inverse();
    u.cam = pinhole_of(rig.cameras[u.camera].calibration.intrinsics, world_from_cam);
    u.cone = cone_of((world_from_cam * cam_from_light).inverse(), field.width, field.height, field.fx, field.fy,
                     field.cx, field.cy);
    u.bits = rig.cameras[u.camera].bit_depth;
    found.push_back(u);
  }
  units.clear();
  for (const Unit& u : found)
    if (u.camera == 0) units.push_back(u);
  if (units.empty())
    return sdk::failed_precondition(
        "media-stereo 'helmholtz' needs a light on camera 0 (the reference unit of every reciprocal pair)");
  for (const Unit& u : found)
    if (u.camera != 0) units.push_back(u);
  if (units.size() < 1 + min_others)
    return sdk::failed_precondition(
        "media-stereo needs camera 0 and >= " + std::to_string(min_others) +
        " other cameras each with a light at its centre (helmholtz: >= 3 reciprocal pairs; medium: a light beside "
        "camera 0); the rig has " + std::to_string(units.size() - 1) + " other camera+light units");
  return sdk::ok();
}

// `medium`: one frame of the medium alone, returned as medium_image (the
// input `helmholtz` and `binocular` fit) with its fit. On a rig of
// camera+light units camera 0 is lit by unit 1's light and the projector
// stays dark; on a rig without units the projector floods (binocular's light).
class MediumSession final : public sdk::Session {
 public:
  MediumSession(const MediumShot& shot, size_t camera, uint32_t bits, int32_t light_index, bool flood,
                const sdk::Rig& rig, const sdk::Params& p)
      : params_(p.json()), shot_(shot), camera_(camera), bits_(bits), light_index_(light_index), flood_(flood),
        i0_(p.get_number("light_intensity")), wall_mm_(p.get_number("medium_wall_mm")),
        saturation_(p.get_number("saturation")), proj_w_(rig.projector_width), proj_h_(rig.projector_height) {}

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (planned_) return sdk::ok();
    planned_ = true;
    const uint32_t f = plan.add_frame("medium-alone", proj_w_, proj_h_);
    plan.settings(f).camera_index = static_cast<int32_t>(camera_);
    if (flood_)
      for (uint8_t& v : plan.pattern_u8(f)) v = 255;
    else
      plan.settings(f).light_index = light_index_;
    has_round = true;
    return sdk::ok();
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    sdk::ScopedMs t(decode_ms_);
    if (sdk::Error e = sdk::check_frame(&frame, shot_.cam.width, shot_.cam.height, 1,
                                        "frame " + std::to_string(index) + " (camera " + std::to_string(camera_) + ")");
        !e.ok())
      return e;
    frame_to_full_scale(frame, bits_, image_);
    return sdk::ok();
  }

  sdk::Error end_round() override {
    sdk::ScopedMs t(decode_ms_);
    fit_ = fit_medium_shot(shot_, image_, i0_, wall_mm_, saturation_);
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    out.add_image("medium_image", "",
                  "camera 0's image of the medium alone lit by " + shot_.light_name +
                      ", full scale (input medium_image of helmholtz or binocular on this rig)",
                  shot_.cam.width, shot_.cam.height, image_);
    size_t valid = 0;
    for (float v : image_) valid += std::isfinite(v) && static_cast<double>(v) < saturation_ ? 1u : 0u;
    if (fit_.ok) add_medium_scalars(out, fit_.medium, "fitted from this image (thesis 5.4.1)");
    sdk::StandardOutputs s;
    s.decode_ms = decode_ms_;
    s.pattern_count = 1;
    s.valid_pixels = valid;
    s.total_pixels = image_.size();
    nlohmann::json m = {{"sigma_per_mm", fit_.medium.sigma_per_mm},
                        {"beta_per_mm", fit_.medium.beta_per_mm},
                        {"g", fit_.medium.g}};
    m["fitted"] = fit_.ok ? nlohmann::json{"sigma_per_mm", "beta_per_mm", "g"} : nlohmann::json::array();
    m["fit_ok"] = fit_.ok;
    m["fit_rms_residual_fullscale"] = fit_.rms_residual;
    s.report = {{"method", "medium"},
                {"medium", m},
                {"model", "pure single-scattered backscatter B = beta F(sigma, g) (Eq. 5.16), rays ending at a black "
                          "wall at medium_wall_mm, light clipped to its field"},
                {"fit_pixel_stride", medium_fit_stride(shot_.cam.width, shot_.cam.height)},
                {"camera", camera_},
                {"light", flood_ ? nlohmann::json("projector flood") : nlohmann::json(light_index_)},
                {"params", params_}};
    if (flood_)
      s.report["identifiable"] =
          "sigma and the backscatter B the fit predicts, not beta and g one by one: a projector beside camera 0 "
          "lights the medium mostly at near-backward scattering angles, where beta and g trade off (sim, "
          "projector 120 mm off, two pixel samplings: beta -34 % / +17 %, g 0.35 / 0.55 for 0.5, B within "
          "0.3 % both). Enough for binocular; to measure "
          "beta and g, light the medium from beside the camera (a helmholtz rig's units)";
    sdk::add_standard_outputs(out, s);
    return sdk::ok();
  }

 private:
  nlohmann::json params_;
  MediumShot shot_;
  size_t camera_;
  uint32_t bits_;
  int32_t light_index_;
  bool flood_;
  double i0_, wall_mm_, saturation_;
  uint32_t proj_w_, proj_h_;
  bool planned_ = false;
  std::vector<float> image_;
  MediumFit fit_;
  double decode_ms_ = 0;
};

}  // namespace

sdk::MethodDescription medium_description() {
  sdk::MethodDescription d;
  d.name = "medium";
  d.summary =
      "one image of the medium alone (thesis 5.4.1; the scene removed, a black far wall): camera 0 lit by the "
      "light of the next camera+light unit, or by the projector's flood on a rig without units; fits sigma, beta, "
      "g and outputs the image as the input medium_image of helmholtz or binocular";
  d.patterns = 1;
  d.outputs = {"medium_image", "medium_extinction_per_mm", "medium_scattering_per_mm", "medium_hg_g", "decode_ms",
               "pattern_count", "valid_fraction", "report"};
  d.params = medium_params();
  return d;
}

sdk::Error create_medium_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Params p;
  if (sdk::Error e = sdk::parse_params(args.params, medium_params(), p, args.method); !e.ok()) return e;
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  const bool has_units = args.rig.is_object() && args.rig.contains("lights");
  if (!has_units) {
    // binocular's rig: the projector floods as the light.
    if (rig.cameras.empty() || !rig.can_triangulate(0))
      return sdk::failed_precondition(
          "media-stereo 'medium' needs a calibrated camera 0 and either camera+light units (rig \"lights\", e.g. "
          "configs/rigs/sim-helmholtz.json) or a calibrated projector as the light (e.g. "
          "configs/rigs/sim-tank-stereo.json)");
    if (rig.cameras[0].calibration.intrinsics.distorted())
      return sdk::failed_precondition("media-stereo 'medium': camera 0 has lens distortion, which the fit does not "
                                      "model; undistort its frames and pass a pinhole calibration");
    out = std::make_unique<MediumSession>(projector_shot(rig), 0, rig.cameras[0].bit_depth, 0, true, rig, p);
    return sdk::ok();
  }
  std::vector<Unit> units;
  if (sdk::Error e = units_from_rig(args.rig, rig, units, 1); !e.ok()) return e;
  out = std::make_unique<MediumSession>(unit_shot(units), units[0].camera, units[0].bits, units[1].light_index, false,
                                        rig, p);
  return sdk::ok();
}

sdk::MethodDescription helmholtz_description() {
  sdk::MethodDescription d;
  d.name = "helmholtz";
  d.summary =
      "Helmholtz stereo in a scattering medium (thesis Eq. 5.32-5.34): reciprocal pairs of camera+light units "
      "(camera 0 with each other unit), backscatter removed, depth and normals from the rank-2 condition, then "
      "integrated depth; medium from params or fitted from the input medium_image";
  d.patterns_formula = "2 x frames_per_pair per reciprocal pair (camera 0 and each other camera with a light)";
  d.outputs = {"depth_mm", "depth_integrated_mm", "normal_x", "normal_y", "normal_z", "rank_ratio",
               "decode_ms", "pattern_count", "valid_fraction", "report"};
  d.params = helmholtz_params();
  d.inputs = {medium_image_input()};
  return d;
}

sdk::Error create_helmholtz_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Params p;
  if (sdk::Error e = sdk::parse_params(args.params, helmholtz_params(), p, args.method); !e.ok()) return e;
  if (sdk::Error e = check_stereo_params(p); !e.ok()) return e;
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  std::vector<Unit> units;
  if (sdk::Error e = units_from_rig(args.rig, rig, units, 3); !e.ok()) return e;
  std::optional<MediumFit> fit;
  if (sdk::Error e = medium_from_input(args, p, unit_shot(units), fit); !e.ok()) return e;
  out = std::make_unique<HelmholtzSession>(std::move(units), rig, p, fit);
  return sdk::ok();
}

}  // namespace procam::media_stereo
