// SPDX-License-Identifier: MIT
#include "binocular_session.hpp"

#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "binocular.hpp"

namespace procam::media_stereo {
namespace {

using sdk::ParamSpec;
using sdk::ParamType;

const std::vector<ParamSpec>& binocular_params() {
  static const std::vector<ParamSpec> specs = stereo_params(
      7,
      "matching constraint: 'media' removes the backscatter and undoes the camera-leg attenuation (Eq. 5.22); "
      "'clear-air' compares raw intensities (Eq. 5.20), the baseline",
      "I0 of the flood in full-scale units x mm^2: a white Lambertian surface facing the projector at d mm in "
      "clear water reads I0 / (pi d^2) of full scale in camera 0 (a photometric calibration of light and camera)");
  return specs;
}

class BinocularSession final : public sdk::Session {
 public:
  BinocularSession(const sdk::Rig& rig, const sdk::Params& p, const MediumShot& shot,
                   const std::optional<MediumFit>& fit)
      : params_(p.json()), fit_(fit), search_(search_from(p)) {
    // World = camera 0's frame: world_from_cam_i = cam0_from_proj · proj_from_cam_i.
    const Rigid3 cam0_from_proj = rig.cameras[0].calibration.cam_from_proj;
    for (int i = 0; i < 2; ++i) {
      const auto& c = rig.cameras[static_cast<size_t>(i)].calibration;
      cams_[i] = pinhole_of(c.intrinsics, cam0_from_proj * c.cam_from_proj.inverse());
      images_[i].assign(size_t{c.intrinsics.width} * c.intrinsics.height, 0.f);
      rig_bits_[i] = rig.cameras[static_cast<size_t>(i)].bit_depth;
    }
    in_.light = shot.light;
    in_.light_cone = shot.cone;
    in_.light_intensity = p.get_number("light_intensity");
    in_.medium = medium_of(p, fit);
    media_ = p.get_string("constraint") == "media";
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
        {"medium", medium_report(in_.medium, fit_,
                                 "fit_medium() on the input medium_image (thesis 5.4.1; camera 0 lit by the "
                                 "projector's flood)")},
        {"light", {{"centre_mm_camera0", {in_.light.x, in_.light.y, in_.light.z}},
                   {"intensity_fullscale_mm2", in_.light_intensity}}},
        {"baseline_mm", norm(cams_[1].centre() - cams_[0].centre())},
        {"params", params_}};
    sdk::add_standard_outputs(out, s);
    if (fit_) add_medium_scalars(out, in_.medium, "fitted from the input medium_image (thesis 5.4.1)");
    return sdk::ok();
  }

 private:
  nlohmann::json params_;
  std::optional<MediumFit> fit_;
  PinholeCamera cams_[2];
  std::vector<float> images_[2];
  uint32_t rig_bits_[2] = {8, 8};  // significant bits of each camera's integer frames (rig description)
  DepthSearch search_;
  BinocularInput in_;
  bool media_ = true, planned_ = false;
  uint32_t proj_w_ = 0, proj_h_ = 0;
  std::vector<float> depth_;
  size_t valid_ = 0;
  double decode_ms_ = 0;
};

}  // namespace

sdk::MethodDescription binocular_description() {
  sdk::MethodDescription d;
  d.name = "binocular";
  d.summary =
      "binocular stereo in a scattering medium (thesis Eq. 5.22-5.23): a projector flood seen by cameras 0 and 1, "
      "backscatter removed and attenuation undone per depth hypothesis; medium from params or fitted from the "
      "input medium_image (a `medium` scan of the medium alone)";
  d.patterns = 2;
  d.outputs = {"depth_mm", "decode_ms", "pattern_count", "valid_fraction", "report"};
  d.params = binocular_params();
  d.inputs = {medium_image_input()};
  return d;
}

sdk::Error create_binocular_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Params p;
  if (sdk::Error e = sdk::parse_params(args.params, binocular_params(), p, args.method); !e.ok()) return e;
  if (sdk::Error e = check_stereo_params(p); !e.ok()) return e;
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
  const MediumShot shot = projector_shot(rig);
  std::optional<MediumFit> fit;
  if (sdk::Error e = medium_from_input(args, p, shot, fit); !e.ok()) return e;
  out = std::make_unique<BinocularSession>(rig, p, shot, fit);
  return sdk::ok();
}

}  // namespace procam::media_stereo
