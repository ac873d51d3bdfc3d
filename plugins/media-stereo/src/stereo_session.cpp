// SPDX-License-Identifier: MIT
#include "stereo_session.hpp"

#include <algorithm>
#include <cmath>

namespace procam::media_stereo {

using sdk::ParamSpec;
using sdk::ParamType;

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

std::vector<ParamSpec> stereo_params(int window, const std::string& constraint_doc, const std::string& light_doc) {
  return {
      {"constraint", ParamType::string, "media", 0, 0, {"media", "clear-air"}, constraint_doc},
      {"sigma_per_mm", ParamType::number, 0.0, 0, 10, {},
       "medium extinction sigma (1/mm); 0: clear water; replaced by the fit when the input medium_image is given"},
      {"beta_per_mm", ParamType::number, 0.0, 0, 10, {}, "medium scattering coefficient beta (1/mm), <= sigma"},
      {"g", ParamType::number, 0.0, -0.99, 0.99, {}, "Henyey-Greenstein asymmetry of the medium"},
      {"light_intensity", ParamType::number, 1.0e6, 1e-12, 1e30, {}, light_doc},
      {"z_min_mm", ParamType::number, 380.0, 1, 1e5, {}, "nearest depth hypothesis (camera 0's z)"},
      {"z_max_mm", ParamType::number, 700.0, 1, 1e5, {}, "farthest depth hypothesis"},
      {"z_step_mm", ParamType::number, 2.0, 0.01, 1e4, {}, "hypothesis spacing (a parabola refines between)"},
      {"window", ParamType::integer, window, 1, 31, {}, "odd window side (px) the cost is summed over"},
      {"min_signal", ParamType::number, 0.002, 0, 1, {},
       "a pixel whose signal I - B is at/below this (full scale) is invalid: shadow or black surface"},
      {"saturation", ParamType::number, 0.999, 0.01, 1e30, {}, "samples at/above this (full scale) drop out"},
      {"medium_wall_mm", ParamType::number, 2000.0, 1, 1e6, {},
       "input medium_image only: z (camera 0's frame) of the black wall that ends every ray in the image of the "
       "medium alone"},
  };
}

sdk::Error check_stereo_params(const sdk::Params& p) {
  if (!(p.get_number("beta_per_mm") <= p.get_number("sigma_per_mm")))
    return sdk::invalid_argument("parameter 'beta_per_mm' must be <= sigma_per_mm (scattering is part of extinction)");
  if (!(p.get_number("z_max_mm") > p.get_number("z_min_mm") + 2 * p.get_number("z_step_mm")))
    return sdk::invalid_argument("z_max_mm must exceed z_min_mm by at least two z_step_mm (three hypotheses)");
  if (p.get_int("window") % 2 == 0) return sdk::invalid_argument("parameter 'window' must be odd");
  return sdk::ok();
}

DepthSearch search_from(const sdk::Params& p) {
  DepthSearch s;
  s.z_min_mm = p.get_number("z_min_mm");
  s.z_max_mm = p.get_number("z_max_mm");
  s.z_step_mm = p.get_number("z_step_mm");
  s.window = static_cast<int>(p.get_int("window"));
  s.min_signal = p.get_number("min_signal");
  s.saturation = p.get_number("saturation");
  return s;
}

LightCone cone_of(const Rigid3& light_from_world, uint32_t width, uint32_t height, double fx, double fy, double cx,
                  double cy) {
  LightCone c;
  c.light_from_world = light_from_world;
  c.width = width;
  c.height = height;
  c.fx = fx;
  c.fy = fy;
  c.cx = cx;
  c.cy = cy;
  return c;
}

MediumShot projector_shot(const sdk::Rig& rig) {
  const Rigid3 cam0_from_proj = rig.cameras[0].calibration.cam_from_proj;
  MediumShot s;
  // The same product binocular places camera 0 with (identity up to rounding).
  s.cam = pinhole_of(rig.cameras[0].calibration.intrinsics, cam0_from_proj * cam0_from_proj.inverse());
  s.light = cam0_from_proj.translation_mm;
  s.cone = cone_of(cam0_from_proj.inverse(), rig.projector.width, rig.projector.height, rig.projector.fx,
                   rig.projector.fy, rig.projector.cx, rig.projector.cy);
  s.light_name = "the projector's flood";
  return s;
}

uint32_t medium_fit_stride(uint32_t width, uint32_t height) {
  constexpr double kMaxSamples = 500;
  const double s = std::ceil(std::sqrt(static_cast<double>(width) * height / kMaxSamples));
  return std::max<uint32_t>(4, static_cast<uint32_t>(s));
}

MediumFit fit_medium_shot(const MediumShot& shot, const std::vector<float>& image, double i0, double wall_mm,
                          double saturation) {
  return fit_medium(shot.cam, image, shot.light, i0, wall_mm, medium_fit_stride(shot.cam.width, shot.cam.height),
                    saturation, &shot.cone);
}

sdk::InputSpec medium_image_input() {
  sdk::InputSpec in;
  in.name = "medium_image";
  in.unit = "";
  in.required = false;
  in.description =
      "camera 0's image of the medium alone (output medium_image of a `medium` scan on the same rig, full scale): "
      "sigma, beta and g are then fitted from it (thesis 5.4.1) instead of taken from the params";
  return in;
}

sdk::Error medium_from_input(const sdk::CreateArgs& args, const sdk::Params& p, const MediumShot& shot,
                             std::optional<MediumFit>& fit) {
  fit.reset();
  if (!args.inputs.has("medium_image")) return sdk::ok();
  std::vector<float> image;
  if (sdk::Error e = args.inputs.image_f32("medium_image", shot.cam.width, shot.cam.height, image); !e.ok()) return e;
  fit = fit_medium_shot(shot, image, p.get_number("light_intensity"), p.get_number("medium_wall_mm"),
                        p.get_number("saturation"));
  if (!fit->ok)
    return sdk::invalid_argument("input medium_image: no usable backscatter to fit sigma, beta, g (all pixels "
                                 "invalid, saturated or zero); take it with a `medium` scan, the scene removed and "
                                 "the light on");
  return sdk::ok();
}

MediumParams medium_of(const sdk::Params& p, const std::optional<MediumFit>& fit) {
  return fit ? fit->medium
             : MediumParams{p.get_number("sigma_per_mm"), p.get_number("beta_per_mm"), p.get_number("g")};
}

nlohmann::json medium_report(const MediumParams& m, const std::optional<MediumFit>& fit,
                             const std::string& fit_source) {
  nlohmann::json r = {{"sigma_per_mm", m.sigma_per_mm}, {"beta_per_mm", m.beta_per_mm}, {"g", m.g}};
  if (fit) {
    r["fitted"] = {"sigma_per_mm", "beta_per_mm", "g"};
    r["given"] = nlohmann::json::array();
    r["source"] = fit_source;
    r["fit_rms_residual_fullscale"] = fit->rms_residual;
  } else {
    r["fitted"] = nlohmann::json::array();
    r["given"] = {"sigma_per_mm", "beta_per_mm", "g"};
    r["source"] = "params";
  }
  return r;
}

void add_medium_scalars(sdk::Outputs& out, const MediumParams& m, const std::string& how) {
  out.add_scalar("medium_extinction_per_mm", "1/mm", "extinction coefficient sigma " + how, m.sigma_per_mm);
  out.add_scalar("medium_scattering_per_mm", "1/mm", "scattering coefficient beta " + how, m.beta_per_mm);
  out.add_scalar("medium_hg_g", "", "Henyey-Greenstein asymmetry g " + how, m.g);
}

}  // namespace procam::media_stereo
