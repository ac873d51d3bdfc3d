// SPDX-License-Identifier: MIT
#include "binocular_session.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "binocular.hpp"

namespace procam::media_stereo {
namespace {

using sdk::ParamSpec;
using sdk::ParamType;

const std::vector<ParamSpec>& binocular_params() {
  static const std::vector<ParamSpec> specs = {
      {"constraint", ParamType::string, "media", 0, 0, {"media", "clear-air"},
       "matching constraint: 'media' removes the backscatter and undoes the camera-leg attenuation (Eq. 5.22); "
       "'clear-air' compares raw intensities (Eq. 5.20), the baseline"},
      {"sigma_per_mm", ParamType::number, 0.0, 0, 10, {}, "medium extinction sigma (1/mm); 0: clear water"},
      {"beta_per_mm", ParamType::number, 0.0, 0, 10, {}, "medium scattering coefficient beta (1/mm), <= sigma"},
      {"g", ParamType::number, 0.0, -0.99, 0.99, {}, "Henyey-Greenstein asymmetry of the medium"},
      {"light_intensity", ParamType::number, 1.0e6, 1e-12, 1e30, {},
       "I0 of the flood in full-scale units x mm^2: a white Lambertian surface facing the projector at d mm in "
       "clear water reads I0 / (pi d^2) of full scale in camera 0 (a photometric calibration of light and camera)"},
      {"z_min_mm", ParamType::number, 380.0, 1, 1e5, {}, "nearest depth hypothesis (camera 0's z)"},
      {"z_max_mm", ParamType::number, 700.0, 1, 1e5, {}, "farthest depth hypothesis"},
      {"z_step_mm", ParamType::number, 2.0, 0.01, 1e4, {}, "hypothesis spacing (a parabola refines between)"},
      {"window", ParamType::integer, 7, 1, 31, {}, "odd window side (px) the cost is summed over"},
      {"min_signal", ParamType::number, 0.002, 0, 1, {},
       "a pixel whose signal I - B is at/below this (full scale) is invalid: shadow or black surface"},
      {"saturation", ParamType::number, 0.999, 0.01, 1e30, {}, "samples at/above this (full scale) drop out"},
  };
  return specs;
}

class BinocularSession final : public sdk::Session {
 public:
  BinocularSession(const sdk::Rig& rig, const sdk::Params& p) : params_(p.json()) {
    // World = camera 0's frame: world_from_cam_i = cam0_from_proj · proj_from_cam_i.
    const Rigid3 cam0_from_proj = rig.cameras[0].calibration.cam_from_proj;
    for (int i = 0; i < 2; ++i) {
      const auto& c = rig.cameras[static_cast<size_t>(i)].calibration;
      cams_[i] = pinhole_of(c.intrinsics, cam0_from_proj * c.cam_from_proj.inverse());
      images_[i].assign(size_t{c.intrinsics.width} * c.intrinsics.height, 0.f);
      rig_bits_[i] = rig.cameras[static_cast<size_t>(i)].bit_depth;
    }
    in_.light = cam0_from_proj.translation_mm;
    LightCone cone;
    cone.light_from_world = cam0_from_proj.inverse();
    cone.width = rig.projector.width;
    cone.height = rig.projector.height;
    cone.fx = rig.projector.fx;
    cone.fy = rig.projector.fy;
    cone.cx = rig.projector.cx;
    cone.cy = rig.projector.cy;
    in_.light_cone = cone;
    in_.light_intensity = p.get_number("light_intensity");
    in_.medium = {p.get_number("sigma_per_mm"), p.get_number("beta_per_mm"), p.get_number("g")};
    media_ = p.get_string("constraint") == "media";
    search_.z_min_mm = p.get_number("z_min_mm");
    search_.z_max_mm = p.get_number("z_max_mm");
    search_.z_step_mm = p.get_number("z_step_mm");
    search_.window = static_cast<int>(p.get_int("window"));
    search_.min_signal = p.get_number("min_signal");
    search_.saturation = p.get_number("saturation");
    proj_w_ = rig.projector_width;
    proj_h_ = rig.projector_height;
  }

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (planned_) return sdk::ok();
    planned_ = true;
    for (int i = 0; i < 2; ++i) {
      const uint32_t f = plan.add_frame("flood-camera-" + std::to_string(i), proj_w_, proj_h_);
      for (uint8_t& v : plan.pattern_u8(f)) v = 255;
      plan.settings(f).camera_index = i;
    }
    has_round = true;
    return sdk::ok();
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    sdk::ScopedMs t(decode_ms_);
    const PinholeCamera& c = cams_[index];
    if (sdk::Error e = sdk::check_frame(&frame, c.width, c.height, 1, "frame " + std::to_string(index) +
                                                                          " (camera " + std::to_string(index) + ")");
        !e.ok())
      return e;
    frame_to_full_scale(frame, rig_bits_[index], images_[index]);
    return sdk::ok();
  }

  sdk::Error end_round() override {
    sdk::ScopedMs t(decode_ms_);
    in_.left = cams_[0];
    in_.right = cams_[1];
    in_.left_image = images_[0];
    in_.right_image = images_[1];
    depth_ = binocular_depth(in_, search_, media_ ? Constraint::media : Constraint::clear_air);
    valid_ = 0;
    for (float z : depth_) valid_ += std::isfinite(z) ? 1u : 0u;
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    const PinholeCamera& c = cams_[0];
    out.add_image("depth_mm", "mm", "depth (z in camera 0's frame) from binocular stereo in the medium; NaN invalid",
                  c.width, c.height, depth_);
    sdk::StandardOutputs s;
    s.decode_ms = decode_ms_;
    s.pattern_count = 2;
    s.valid_pixels = valid_;
    s.total_pixels = depth_.size();
    s.report = {
        {"method", "binocular"},
        {"constraint", media_ ? "media (Eq. 5.22-5.23)" : "clear-air (Eq. 5.20, 5.23)"},
        {"model", "single scattering (Eq. 5.14-5.16), isotropic point light at the projector centre clipped to its "
                  "image, no forward-scattered signal, fronto-parallel window"},
        {"medium", {{"sigma_per_mm", in_.medium.sigma_per_mm},
                    {"beta_per_mm", in_.medium.beta_per_mm},
                    {"g", in_.medium.g},
                    {"source", "params (a scan has no image of the medium alone)"}}},
        {"light", {{"centre_mm_camera0", {in_.light.x, in_.light.y, in_.light.z}},
                   {"intensity_fullscale_mm2", in_.light_intensity}}},
        {"baseline_mm", norm(cams_[1].centre() - cams_[0].centre())},
        {"params", params_}};
    sdk::add_standard_outputs(out, s);
    return sdk::ok();
  }

 private:
  nlohmann::json params_;
  PinholeCamera cams_[2];
  std::vector<float> images_[2];
  uint32_t rig_bits_[2] = {8, 8};  // significant bits of each camera's integer frames (rig description)
  BinocularInput in_;
  DepthSearch search_;
  bool media_ = true, planned_ = false;
  uint32_t proj_w_ = 0, proj_h_ = 0;
  std::vector<float> depth_;
  size_t valid_ = 0;
  double decode_ms_ = 0;
};

}  // namespace

PinholeCamera pinhole_of(const Intrinsics& k, const Rigid3& world_from_cam) {
  PinholeCamera c;
  c.width = k.width;
  c.height = k.height;
  c.fx = k.fx;
  c.fy = k.fy;
  c.cx = k.cx;
  c.cy = k.cy;
  c.world_from_cam = world_from_cam;
  return c;
}

void frame_to_full_scale(const procam_image& frame, uint32_t rig_bits, std::vector<float>& img) {
  // Normalise to full scale (8-, 12-, 16-bit and float frames alike). An
  // integer frame claiming more significant bits than the rig's camera has
  // went through a file that does not keep them (a recorded 12-bit frame
  // reads back from 16-bit PNG as bit_depth 16, values unchanged): the
  // camera's bit depth wins.
  double full = sdk::full_scale(frame);
  if (frame.pixel_type != PROCAM_PIXEL_F32 && rig_bits < frame.bit_depth && rig_bits <= 16)
    full = std::ldexp(1.0, static_cast<int>(rig_bits)) - 1.0;
  const double inv = 1.0 / full;
  img.resize(size_t{frame.width} * frame.height);
  for (uint32_t y = 0; y < frame.height; ++y) {
    float* row = img.data() + size_t{y} * frame.width;
    sdk::read_row(frame, y, row);
    for (uint32_t x = 0; x < frame.width; ++x) row[x] = static_cast<float>(static_cast<double>(row[x]) * inv);
  }
}

sdk::MethodDescription binocular_description() {
  sdk::MethodDescription d;
  d.name = "binocular";
  d.summary =
      "binocular stereo in a scattering medium (thesis Eq. 5.22-5.23): a projector flood seen by cameras 0 and 1, "
      "backscatter removed and attenuation undone per depth hypothesis; medium from params";
  d.patterns = 2;
  d.outputs = {"depth_mm", "decode_ms", "pattern_count", "valid_fraction", "report"};
  d.params = binocular_params();
  return d;
}

sdk::Error create_binocular_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Params p;
  if (sdk::Error e = sdk::parse_params(args.params, binocular_params(), p, args.method); !e.ok()) return e;
  if (!(p.get_number("beta_per_mm") <= p.get_number("sigma_per_mm")))
    return sdk::invalid_argument("parameter 'beta_per_mm' must be <= sigma_per_mm (scattering is part of extinction)");
  if (!(p.get_number("z_max_mm") > p.get_number("z_min_mm") + 2 * p.get_number("z_step_mm")))
    return sdk::invalid_argument("z_max_mm must exceed z_min_mm by at least two z_step_mm (three hypotheses)");
  if (p.get_int("window") % 2 == 0) return sdk::invalid_argument("parameter 'window' must be odd");
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  if (rig.cameras.size() < 2)
    return sdk::failed_precondition("media-stereo 'binocular' needs a rig with two cameras (cameras 0 and 1), got " +
                                    std::to_string(rig.cameras.size()) + "; e.g. configs/rigs/sim-tank-stereo.json");
  if (!rig.can_triangulate(0) || !rig.can_triangulate(1))
    return sdk::failed_precondition(
        "media-stereo 'binocular' needs calibrated cameras 0 and 1 and a calibrated projector (intrinsics and "
        "cam_from_proj in the rig description): the projector is the light, camera 0 the reference");
  for (size_t i = 0; i < 2; ++i)
    if (rig.cameras[i].calibration.intrinsics.distorted())
      return sdk::failed_precondition("media-stereo 'binocular': camera " + std::to_string(i) +
                                      " has lens distortion, which the matcher does not model; undistort its frames "
                                      "and pass a pinhole calibration");
  out = std::make_unique<BinocularSession>(rig, p);
  return sdk::ok();
}

}  // namespace procam::media_stereo
