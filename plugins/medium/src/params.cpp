// SPDX-License-Identifier: MIT
// Parameters of the medium methods (see params.hpp).
#include "params.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace procam::medium {

using sdk::ParamSpec;
using sdk::ParamType;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::vector<ParamSpec> common_specs() {
  return {
      {"tank_depth_mm", ParamType::number, 300.0, 1.0, 1e5, {},
       "inner depth D of the tank along the camera axis, mm; the thesis's tank is 300 mm deep (25 x 30 x 30 cm)"},
      {"bulb_depth_mm", ParamType::number, 0.0, 0.0, 1e5, {},
       "depth B of the bulb centre behind the front face, mm; 0 = tank_depth_mm / 2 (the thesis: bulb mid-way on a "
       "side wall)"},
      {"bulb_x_px", ParamType::number, 0.0, -1e5, 1e5, {},
       "camera column of the bulb centre's image, px (may lie outside the image); 0 = the left edge, where a bulb on "
       "the left side wall appears"},
      {"bulb_y_px", ParamType::number, -1.0, -1e5, 1e5, {},
       "camera row of the bulb centre's image, px; -1 = the middle row"},
      {"bulb_radius_mm", ParamType::number, 0.0, 0.0, 1e3, {},
       "radius R of the (spherical, diffuse) bulb, mm; 0 = point source (the bulb image's centre pixel, path B, is then used for attenuation). Needed with water_radiance for beta's "
       "absolute scale (I0 = W pi R^2) and for sigma by attenuation (pure absorbers, concentration)"},
      {"mm_per_px", ParamType::number, 1.0, 1e-6, 1e4, {},
       "size of one camera pixel at the tank, mm (orthographic view: measure a ruler on the front glass)"},
      {"black_dn", ParamType::number, 0.0, 0.0, 65535.0, {},
       "camera black level in linear DN, subtracted before the HDR merge (take a frame with the lens capped)"},
      {"saturation", ParamType::number, 0.98, 0.5, 1.0, {},
       "DN at or above this fraction of full scale are clipped: excluded from the HDR merge"},
      {"floor", ParamType::number, 0.02, 0.0, 0.5, {},
       "linear values below this fraction of full scale are noise-dominated: weight 1e-6 in the merge (used only if "
       "a pixel has nothing better); 0.02 = 5 DN at 8 bit"},
      {"min_signal", ParamType::number, 0.05, 0.0, 0.5, {},
       "fit only radial bins whose mean radiance reaches this fraction of full scale in the longest exposure; "
       "darker ones are biased up by the camera's clip at black and the floor (docs/medium.md, the fit step 1); 0 = fit all"},
      {"response", ParamType::string, "linear", -kInf, kInf, {"linear", "gamma", "lut"},
       "camera response: linear (raw or linear-mode frames), gamma (DN_lin = FS (DN / FS)^gamma), or lut "
       "(response_lut: one linear value per DN code)"},
      {"gamma", ParamType::number, 2.2, 0.1, 10.0, {}, "exponent of the gamma response (response = gamma)"},
      {"response_lut", ParamType::string, "", -kInf, kInf, {},
       "response = lut: text file of 2^bits numbers (whitespace-separated), the linear value of each DN code"},
      {"exposures", ParamType::integer, 25, 1, 64, {},
       "frames in the exposure bracket (per dilution); the thesis took ~25 from 1/500 s to 10 s; 1 = one exposure "
       "only (exposure_min_us)"},
      {"exposure_min_us", ParamType::number, 2000.0, 1.0, 1e9, {},
       "shortest exposure, us (thesis: 1/500 s); must leave the brightest pixels you fit unsaturated"},
      {"exposure_max_us", ParamType::number, 1e7, 1.0, 1e9, {},
       "longest exposure, us (thesis: 10 s); the bracket is geometric between the two"},
      {"pattern", ParamType::string, "white", -kInf, kInf, {"white", "spot"},
       "projector frame: white (the sim's bulb is the source), or spot: a small bright disc that a real rig sends "
       "through a diffuser as the source"},
      {"spot_x_px", ParamType::number, -1.0, -1.0, 1e5, {}, "spot centre, projector column; -1 = the middle"},
      {"spot_y_px", ParamType::number, -1.0, -1.0, 1e5, {}, "spot centre, projector row; -1 = the middle"},
      {"spot_radius_px", ParamType::number, 20.0, 0.5, 1e5, {}, "spot radius in projector pixels"},
      {"water_radiance", ParamType::number, 0.0, 0.0, 1e12, {},
       "W: radiance of the bulb's direct image through pure water, DN/us (measure once, tank filled with water, "
       "mean over the bulb's central pixels); 0 = unknown"},
  };
}

std::vector<ParamSpec> measure_specs() {
  std::vector<ParamSpec> p = common_specs();
  const std::vector<ParamSpec> more = {
      {"mask_radius_px", ParamType::number, 10.0, 0.0, 1e5, {},
       "pixels closer than this to the bulb centre are not fitted: the bulb's own image and its glare; at least the "
       "bulb's image radius R / mm_per_px plus a few pixels"},
      {"max_multiple_scattering", ParamType::number, 0.10, 0.0, 1.0, {},
       "warn when single scattering misses more than this fraction of the tank image's energy at the fitted beta "
       "(the sim's Monte Carlo regime map, scaled to tank_depth_mm; 0.10 = beta ~ 0.001 /mm in a 300 mm tank): "
       "the fit is then biased, and the report says to which volume to dilute"},
      {"source_model", ParamType::string, "sphere", -kInf, kInf, {"sphere", "point"},
       "the bulb in the fit (thesis §4.3.3): sphere = a Lambertian sphere of radius bulb_radius_mm, its visible cap "
       "sampled near the forward lobe (needed: a 10 mm bulb 150 mm away is as wide as the lobe of g = 0.9); point = "
       "an isotropic point source at its centre (also used when bulb_radius_mm = 0)"},
      {"roi_x0", ParamType::integer, 0, 0, 1e6, {}, "fitted region, first column (exclude the tank's edges)"},
      {"roi_y0", ParamType::integer, 0, 0, 1e6, {}, "fitted region, first row"},
      {"roi_x1", ParamType::integer, -1, -1, 1e6, {}, "fitted region, last column (inclusive); -1 = the last"},
      {"roi_y1", ParamType::integer, -1, -1, 1e6, {}, "fitted region, last row (inclusive); -1 = the last"},
      {"objective", ParamType::string, "normalized", -kInf, kInf, {"normalized", "profiled"},
       "normalized: Eq. 4.6-4.7 as the thesis (E / max E - RHS / max RHS); profiled: beta I0 eliminated exactly by "
       "least squares (not sensitive to the noise on max E)"},
      {"weights", ParamType::string, "uniform", -kInf, kInf, {"uniform", "noise"},
       "pixel weights of the objective: uniform = the thesis's least squares; noise = divided by the pixel noise "
       "variance (noise_relative E)^2 + noise_shot E + noise_read^2, so the bright pixels near the bulb stop "
       "dominating under shot or multiplicative noise (the reported errors stay Eq. 4.6-4.7, unweighted)"},
      {"noise_relative", ParamType::number, 0.03, 0.0, 10.0, {},
       "weights = noise: multiplicative noise of the radiance map (fraction; an HDR merge of a geometric bracket has "
       "about constant relative noise where its longer exposures saturate)"},
      {"noise_shot", ParamType::number, 0.0, 0.0, 1e12, {},
       "weights = noise: shot-noise variance per unit radiance (DN/us)"},
      {"noise_read", ParamType::number, 0.0, 0.0, 1e12, {},
       "weights = noise: noise floor in DN/us (read noise / Sum t); 0 = 1e-3 of the brightest radial bin"},
      {"sigma_min", ParamType::number, 1e-4, 1e-8, 1.0, {}, "lower end of the sigma search, 1/mm"},
      {"sigma_max", ParamType::number, 0.2, 1e-6, 10.0, {},
       "upper end of the sigma search, 1/mm (the single-scattering regime ends near 0.04, thesis §4.2.3)"},
      {"legendre_above_g", ParamType::number, 0.95, 0.0, 1.0, {},
       "if the H-G fit gives g above this, refit with the truncated Legendre expansion (thesis §4.3.3: 0.95)"},
      {"legendre_terms", ParamType::integer, 99, 2, 99, {},
       "terms of the truncated Legendre expansion of H-G (the thesis: fewer than 100)"},
      {"absorber_albedo", ParamType::number, 0.01, 0.0, 1.0, {},
       "beta / sigma below this (or beta not significant) = pure absorber: g undefined, kappa = sigma from the "
       "bulb's attenuation (needs water_radiance, bulb_radius_mm)"},
      {"source_intensity", ParamType::number, 0.0, 0.0, 1e15, {},
       "I0 of Eq. 4.2 in (DN/us) mm^2 for beta's absolute scale; 0 = W pi R^2 from water_radiance and "
       "bulb_radius_mm, or beta relative (I0 = 1) if those are unknown"},
  };
  p.insert(p.end(), more.begin(), more.end());
  return p;
}

std::vector<ParamSpec> concentration_specs() {
  std::vector<ParamSpec> p = common_specs();
  const std::vector<ParamSpec> more = {
      {"volumes_ml", ParamType::string, "0,2,4,8,16,32", -kInf, kInf, {},
       "comma-separated medium volumes, increasing, one HDR bracket (round) each in this order; 0 = pure water "
       "(gives water_radiance when that is 0)"},
      {"linear_points", ParamType::integer, 3, 1, 64, {},
       "the line sigma-hat = c V through the origin is fit on this many smallest non-zero volumes"},
      {"linearity_tolerance", ParamType::number, 0.1, 0.001, 1.0, {},
       "a volume whose sigma-hat falls below the line by more than this fraction is outside the linear "
       "(single-scattering) regime"},
      {"max_sigma_per_mm", ParamType::number, 0.04, 1e-6, 10.0, {},
       "sigma-hat above this is beyond single scattering: the thesis's bound sigma < 0.04 /mm (§4.2.3); the report "
       "stops the user there"},
      {"min_bulb_radiance", ParamType::number, 0.0, 0.0, 1e12, {},
       "SNR floor: a volume whose bulb radiance is below this (DN/us) is too dark to choose; 0 = 1 % of W"},
  };
  p.insert(p.end(), more.begin(), more.end());
  return p;
}

sdk::Error read_lut(const std::string& path, std::vector<double>& lut) {
  if (path.empty()) return sdk::invalid_argument("response = lut needs response_lut: a text file with one linear value per DN code");
  std::ifstream in(path);
  if (!in) return sdk::invalid_argument("response_lut '" + path + "' cannot be opened: give a readable text file");
  double v = 0;
  while (in >> v) {
    if (!std::isfinite(v)) return sdk::invalid_argument("response_lut '" + path + "' holds a non-finite value");
    lut.push_back(v);
  }
  if (!in.eof() || lut.size() < 2)
    return sdk::invalid_argument("response_lut '" + path + "': expected whitespace-separated numbers, one per DN code");
  return sdk::ok();
}

}  // namespace

std::vector<ParamSpec> specs_for(Method m) { return m == Method::measure ? measure_specs() : concentration_specs(); }

std::vector<std::string> outputs_of(Method m) {
  std::vector<std::string> o;
  if (m == Method::measure)
    o = {"radiance", "fit_residual", "profile_plot", "medium_extinction_per_mm", "medium_scattering_per_mm", "medium_hg_g"};
  else
    o = {"sigma_hat_plot", "best_volume_ml"};
  for (const char* s : {"decode_ms", "pattern_count", "valid_fraction", "report"}) o.emplace_back(s);
  return o;
}

sdk::Error parse_config(const std::string& method, const nlohmann::json& params, uint32_t cam_w, uint32_t cam_h,
                        Config& cfg) {
  cfg.method = method == "concentration" ? Method::concentration : Method::measure;
  cfg.method_name = method;
  if (sdk::Error e = sdk::parse_params(params, specs_for(cfg.method), cfg.params, method); !e.ok()) return e;
  const sdk::Params& p = cfg.params;
  FitSettings& f = cfg.fit;
  f.tank.depth_mm = p.get_number("tank_depth_mm");
  f.tank.bulb_depth_mm = p.get_number("bulb_depth_mm") > 0 ? p.get_number("bulb_depth_mm") : 0.5 * f.tank.depth_mm;
  if (!(f.tank.bulb_depth_mm < f.tank.depth_mm))
    return sdk::invalid_argument("bulb_depth_mm = " + std::to_string(f.tank.bulb_depth_mm) +
                                 " is not inside the tank (tank_depth_mm = " + std::to_string(f.tank.depth_mm) +
                                 "): give 0 < bulb_depth_mm < tank_depth_mm");
  f.bulb_x_px = p.get_number("bulb_x_px");
  f.bulb_y_px = p.get_number("bulb_y_px") < 0 ? 0.5 * (double(cam_h) - 1) : p.get_number("bulb_y_px");
  f.bulb_radius_mm = p.get_number("bulb_radius_mm");
  if (!(f.bulb_radius_mm < f.tank.bulb_depth_mm))
    return sdk::invalid_argument("bulb_radius_mm must be smaller than the bulb depth " +
                                 std::to_string(f.tank.bulb_depth_mm) + " mm");
  f.mm_per_px = p.get_number("mm_per_px");
  f.water_radiance = p.get_number("water_radiance");
  cfg.hdr.black_dn = p.get_number("black_dn");
  cfg.hdr.saturation = p.get_number("saturation");
  cfg.hdr.floor = p.get_number("floor");
  cfg.min_signal = p.get_number("min_signal");
  const std::string response = p.get_string("response");
  if (response == "gamma") cfg.hdr.gamma = p.get_number("gamma");
  if (response == "lut")
    if (sdk::Error e = read_lut(p.get_string("response_lut"), cfg.hdr.lut); !e.ok()) return e;
  const auto n = static_cast<uint32_t>(p.get_int("exposures"));
  const double t0 = p.get_number("exposure_min_us"), t1 = p.get_number("exposure_max_us");
  if (!(t1 >= t0))
    return sdk::invalid_argument("exposure_max_us (" + std::to_string(t1) + ") is below exposure_min_us (" +
                                 std::to_string(t0) + ")");
  cfg.exposures_us = sdk::exposure_bracket(t0, t1, n);
  cfg.spot = p.get_string("pattern") == "spot";
  cfg.spot_x_px = p.get_number("spot_x_px");
  cfg.spot_y_px = p.get_number("spot_y_px");
  cfg.spot_radius_px = p.get_number("spot_radius_px");
  if (cfg.method == Method::measure) {
    f.mask_radius_px = p.get_number("mask_radius_px");
    cfg.max_multiple_scattering = p.get_number("max_multiple_scattering");
    if (p.get_string("source_model") == "sphere") f.tank.bulb_radius_mm = f.bulb_radius_mm;
    if (f.tank.bulb_radius_mm > 0 && !(f.mask_radius_px * f.mm_per_px > f.bulb_radius_mm))
      return sdk::invalid_argument("mask_radius_px = " + std::to_string(f.mask_radius_px) + " px (" +
                                   std::to_string(f.mask_radius_px * f.mm_per_px) +
                                   " mm) does not clear the bulb (bulb_radius_mm = " + std::to_string(f.bulb_radius_mm) +
                                   "): lines of sight inside it hit the bulb; give mask_radius_px > bulb_radius_mm / mm_per_px");
    f.roi_x0 = static_cast<int32_t>(p.get_int("roi_x0"));
    f.roi_y0 = static_cast<int32_t>(p.get_int("roi_y0"));
    f.roi_x1 = static_cast<int32_t>(p.get_int("roi_x1"));
    f.roi_y1 = static_cast<int32_t>(p.get_int("roi_y1"));
    if ((f.roi_x1 >= 0 && f.roi_x1 < f.roi_x0) || (f.roi_y1 >= 0 && f.roi_y1 < f.roi_y0) ||
        f.roi_x0 >= int32_t(cam_w) || f.roi_y0 >= int32_t(cam_h))
      return sdk::invalid_argument("the ROI (roi_x0..roi_x1, roi_y0..roi_y1) is empty or outside the " +
                                   std::to_string(cam_w) + " x " + std::to_string(cam_h) + " image");
    f.objective = p.get_string("objective") == "profiled" ? Objective::profiled : Objective::normalized;
    f.weights = p.get_string("weights") == "noise" ? Weights::noise : Weights::uniform;
    f.noise_relative = p.get_number("noise_relative");
    f.noise_shot = p.get_number("noise_shot");
    f.noise_read = p.get_number("noise_read");
    if (f.weights == Weights::noise && !(f.noise_relative > 0 || f.noise_shot > 0 || f.noise_read > 0))
      return sdk::invalid_argument("weights = noise needs a noise model: give noise_relative, noise_shot or noise_read > 0");
    f.sigma_min = p.get_number("sigma_min");
    f.sigma_max = p.get_number("sigma_max");
    if (!(f.sigma_max > f.sigma_min)) return sdk::invalid_argument("sigma_max must exceed sigma_min");
    f.legendre_above_g = p.get_number("legendre_above_g");
    f.legendre_terms = static_cast<int>(p.get_int("legendre_terms"));
    f.absorber_albedo = p.get_number("absorber_albedo");
    f.source_intensity = p.get_number("source_intensity");
  } else {
    std::stringstream ss(p.get_string("volumes_ml"));
    std::string item;
    while (std::getline(ss, item, ',')) {
      char* end = nullptr;
      const double v = std::strtod(item.c_str(), &end);
      if (end == item.c_str() || !std::isfinite(v) || v < 0 || (!cfg.volumes_ml.empty() && v <= cfg.volumes_ml.back()))
        return sdk::invalid_argument("volumes_ml '" + p.get_string("volumes_ml") +
                                     "': give comma-separated volumes >= 0 in increasing order, e.g. 0,2,4,8,16");
      cfg.volumes_ml.push_back(v);
    }
    if (cfg.volumes_ml.size() < 2) return sdk::invalid_argument("volumes_ml: give at least two volumes");
    if (cfg.volumes_ml.front() > 0 && !(f.water_radiance > 0))
      return sdk::invalid_argument("concentration needs the bulb's pure-water radiance: start volumes_ml with 0 (a "
                                   "pure-water bracket) or give water_radiance");
    cfg.linear_points = static_cast<uint32_t>(p.get_int("linear_points"));
    cfg.linearity_tolerance = p.get_number("linearity_tolerance");
    cfg.max_sigma_per_mm = p.get_number("max_sigma_per_mm");
    cfg.min_bulb_radiance = p.get_number("min_bulb_radiance");
  }
  return sdk::ok();
}

}  // namespace procam::medium
