// SPDX-License-Identifier: MIT
// Parameters of the polarized-striping methods (see params.hpp).
#include "params.hpp"

#include <algorithm>
#include <cmath>

namespace procam::polarized_striping {

using sdk::ParamSpec;
using sdk::ParamType;

Method method_of(const std::string& m) {
  if (m == "polarized-flood") return Method::polarized_flood;
  if (m == "striping") return Method::striping;
  if (m == "polarized-striping") return Method::polarized_striping;
  return Method::flood;
}
bool is_polarized(Method m) noexcept { return m == Method::polarized_flood || m == Method::polarized_striping; }
bool is_striping(Method m) noexcept { return m == Method::striping || m == Method::polarized_striping; }

std::vector<ParamSpec> specs_for(Method m) {
  std::vector<ParamSpec> p = {
      {"noise", ParamType::number, 0.004, 0.0, 0.5, {},
       "Gaussian noise sigma of one frame as a fraction of full scale (read noise + quantisation); 0.004 is ~1 DN "
       "at 8 bits. Margins, the DOP pixel selection and the SNR weight derive from it: measure yours as the std of "
       "a static scene over frames"},
      {"margin_sigma", ParamType::number, 5.0, 1.0, 100.0, {},
       "a stripe (or signal) must exceed the background by this many noise sigmas; 5: below 1e-6 false detections "
       "per pixel for Gaussian noise"},
      {"saturation", ParamType::number, 0.98, 0.5, 1.0, {},
       "values at or above this fraction of full scale are clipped: pixels whose backscatter is clipped are invalid"},
      {"w_mu", ParamType::number, -1.0, -1.0, 1.0, {},
       "shift mu of the SNR weight W (Eq. 5.10) as a fraction of full scale; -1 = 3 x noise (a signal 3 sigma above "
       "the noise floor gets W = 0.5)"},
      {"exposure_us", ParamType::number, 0.0, 0.0, 1e8, {},
       "camera exposure of every frame, microseconds; 0 = the camera's own setting. Through a dense medium the "
       "signal is a few DN at a normal exposure: the thesis lengthens the exposure for its dim light sheets (§5.2, "
       "footnote 3). Raise it until the brightest backscatter nears full scale (clipped backscatter is invalid)"},
      {"w_z", ParamType::number, -1.0, -1.0, 1.0, {},
       "steepness z of the SNR weight W (Eq. 5.10) as a fraction of full scale; -1 = noise (the thesis: z = the "
       "Gaussian noise's standard deviation)"},
      {"maps", ParamType::string, "core", 0, 0, {"core", "all"},
       "which per-pixel maps are handed over: \"core\" = image_dn, enhanced_dn, backscatter_dn (and for striping "
       "stripe_index, depth_mm, points); \"all\" adds the quality maps cqm, snr_weight (and gqm, stripe_col_px). "
       "The report's quality means (cqm_mean, gqm_mean, snr_weight_mean, ...) are there either way. \"core\" "
       "because each 1920x1200 F32 map is 9 MB written after the last frame: the end of a scan is memory-bound"}};
  if (is_polarized(m)) {
    p.push_back({"polarizer_deg", ParamType::number, 0.0, 0.0, 180.0, {},
                 "projector polariser angle, degrees; the best analyser is crossed to it (+90), the worst parallel. "
                 "Backscatter keeps the incident polarisation, the surface depolarises, so crossed removes most "
                 "backscatter. 0 suits an LCD projector whose red/green are already polarised horizontally"});
    p.push_back({"p", ParamType::number, -1.0, -1.0, 1.0, {},
                 "degree of polarization of the backscatter; -1 = estimate it from the frames (needs some pixels that "
                 "see only medium); the thesis measured ~0.8 in milk"});
    p.push_back({"p_min", ParamType::number, 0.05, 0.001, 0.5, {},
                 "below this DOP Eq. 5.6 is not applied (its 1/p amplifies noise by > sqrt(2)/p_min): the signal is "
                 "E_b + E_w and the backscatter is not separated"});
    p.push_back({"dop_percentile", ParamType::number, 0.9, 0.5, 1.0, {},
                 "quantile of (E_w - E_b) / (E_w + E_b) taken as p: that ratio is p where a pixel sees only medium "
                 "and less where it sees an object, so a high quantile; 0.9 assumes >= 10 % medium-only pixels and "
                 "stays clear of noise outliers"});
  }
  if (m == Method::flood)
    p.push_back({"backscatter_percentile", ParamType::number, 0.02, 0.0, 0.5, {},
                 "flood: backscatter is taken as uniform and equal to this quantile of the image (the darkest "
                 "pixels see medium only); 0.02 skips dead pixels"});
  if (is_striping(m)) {
    p.push_back({"stripes", ParamType::integer, 64, 3, 4096, {},
                 "number K of vertical light sheets across the projector; 64 as the speed goal; more stripes = more "
                 "depth samples, more frames"});
    p.push_back({"stripe_px", ParamType::integer, 0, 0, 65535, {},
                 "width of each sheet in projector columns; 0 = a third of the pitch W/K (gaps between sheets keep "
                 "each surface point lit by one sheet, which the background estimate assumes)"});
  }
  return p;
}

std::vector<std::string> outputs_of(Method m) {
  std::vector<std::string> o = {"image_dn", "enhanced_dn", "backscatter_dn", "cqm", "snr_weight"};
  if (is_polarized(m)) o.emplace_back("dop");
  if (is_striping(m)) {
    for (const char* s : {"stripe_index", "stripe_col_px", "depth_mm", "points"}) o.emplace_back(s);
    if (m == Method::polarized_striping) o.emplace_back("gqm");
  }
  for (const char* s : {"decode_ms", "pattern_count", "valid_fraction", "report"}) o.emplace_back(s);
  return o;
}

sdk::Error parse_config(const std::string& method, const nlohmann::json& params, uint32_t proj_width, Config& cfg) {
  cfg.method = method_of(method);
  cfg.method_name = method;
  if (sdk::Error e = sdk::parse_params(params, specs_for(cfg.method), cfg.params, method); !e.ok()) return e;
  const sdk::Params& p = cfg.params;
  cfg.noise = p.get_number("noise");
  cfg.margin_sigma = p.get_number("margin_sigma");
  cfg.saturation = p.get_number("saturation");
  cfg.w_mu = p.get_number("w_mu");
  cfg.w_z = p.get_number("w_z");
  cfg.exposure_us = p.get_number("exposure_us");
  cfg.all_maps = p.get_string("maps") == "all";
  if (is_polarized(cfg.method)) {
    cfg.polarizer_deg = p.get_number("polarizer_deg");
    cfg.p = p.get_number("p");
    cfg.p_min = p.get_number("p_min");
    cfg.dop_percentile = p.get_number("dop_percentile");
  }
  if (cfg.method == Method::flood) cfg.backscatter_percentile = p.get_number("backscatter_percentile");
  if (is_striping(cfg.method)) {
    cfg.stripes = static_cast<uint32_t>(p.get_int("stripes"));
    if (cfg.stripes > proj_width)
      return sdk::invalid_argument("stripes = " + std::to_string(cfg.stripes) + " exceeds the projector width " +
                                   std::to_string(proj_width) + ": use at most one stripe per column");
    const uint32_t pitch = proj_width / cfg.stripes;
    const auto px = static_cast<uint32_t>(p.get_int("stripe_px"));
    cfg.stripe_px = px == 0 ? std::max(1u, pitch / 3) : px;
    if (cfg.stripe_px > pitch)
      return sdk::invalid_argument("stripe_px = " + std::to_string(cfg.stripe_px) + " exceeds the stripe pitch " +
                                   std::to_string(pitch) + " (projector width / stripes): sheets would overlap; "
                                   "use fewer stripes or narrower ones");
  }
  return sdk::ok();
}

Levels levels_for(const Config& cfg, double full_scale) noexcept {
  Levels l;
  l.full_scale = full_scale;
  l.sigma = cfg.noise * full_scale;
  l.margin = cfg.margin_sigma * l.sigma;
  l.saturation = cfg.saturation * full_scale;
  l.mu = cfg.w_mu < 0 ? 3.0 * l.sigma : cfg.w_mu * full_scale;
  l.z = cfg.w_z < 0 ? l.sigma : cfg.w_z * full_scale;
  // r = (E_w - E_b) / (E_w + E_b) has noise ~ sqrt(2) sigma / (E_w + E_b):
  // at 40 sigma that is <= 0.035, small against a DOP of 0.1..1.
  l.dop_min_sum = std::max(40.0 * l.sigma, 1e-6 * full_scale);
  return l;
}

double background_dop_min_sum(const Levels& lv, uint32_t frames) noexcept {
  const double averaged = frames > 2 ? double(frames - 2) : 1.0;
  return std::max(lv.dop_min_sum / std::sqrt(averaged), 1e-6 * lv.full_scale);
}

}  // namespace procam::polarized_striping

namespace procam::polarized_striping {

StripeColumns stripe_columns(uint32_t proj_width, uint32_t stripes, uint32_t stripe_px, uint32_t k) noexcept {
  StripeColumns s;
  s.width = std::clamp(stripe_px, 1u, proj_width);
  const double centre = (double(k) + 0.5) * double(proj_width) / double(stripes) - 0.5;
  const double first = std::round(centre - 0.5 * double(s.width - 1));
  s.first = static_cast<uint32_t>(std::clamp(first, 0.0, double(proj_width - s.width)));
  s.centre = double(s.first) + 0.5 * double(s.width - 1);
  return s;
}

}  // namespace procam::polarized_striping
