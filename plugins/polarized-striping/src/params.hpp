// SPDX-License-Identifier: MIT
// Methods, parameters and the parsed configuration of the polarized-striping
// plugin (one place, shared by describe() and the factory).
// Noise model of every method: each frame carries Gaussian noise of standard
// deviation `noise` x full scale (read noise and quantisation together; the
// default 0.004 is ~1 DN at 8 bits, 16 DN at 12 bits). Margins, the DOP
// estimate's pixel selection and the SNR weight's defaults derive from it.
#pragma once

#include <string>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace procam::polarized_striping {

enum class Method { flood, polarized_flood, striping, polarized_striping };

Method method_of(const std::string& name);
bool is_polarized(Method m) noexcept;
bool is_striping(Method m) noexcept;

std::vector<sdk::ParamSpec> specs_for(Method m);
std::vector<std::string> outputs_of(Method m);

// Parsed parameters; fractions of full scale stay fractions until the first
// frame tells the full scale (Levels).
struct Config {
  Method method = Method::flood;
  std::string method_name;
  sdk::Params params;
  double noise = 0.004, margin_sigma = 5, saturation = 0.98;
  double w_mu = -1, w_z = -1;           // SNR weight (Eq. 5.10); < 0: tied to noise
  double exposure_us = 0;               // every frame's camera exposure; 0 = the camera's own
  double polarizer_deg = 0;             // projector polariser angle
  double p = -1, p_min = 0.05, dop_percentile = 0.9;
  double backscatter_percentile = 0.02; // flood
  uint32_t stripes = 64, stripe_px = 0; // striping; stripe_px 0 = pitch / 3
  uint32_t threads = 1;                 // the rig's suggestion, for end-of-scan work
  // Param `maps`: "core" (default) hands over image_dn, enhanced_dn,
  // backscatter_dn and stripe_index (+ depth); "all" adds the per-pixel
  // quality maps cqm, snr_weight, gqm and stripe_col_px. The report's quality
  // summaries are computed in the same pass either way.
  bool all_maps = false;
};

sdk::Error parse_config(const std::string& method, const nlohmann::json& params, uint32_t proj_width, Config& cfg);

// Levels in DN once the full scale is known.
struct Levels {
  double full_scale = 255, sigma = 1, margin = 5, saturation = 250, mu = 3, z = 1;
  double dop_min_sum = 40;  // pixels used for the DOP estimate: E_w + E_b above this
};
Levels levels_for(const Config& cfg, double full_scale) noexcept;

// The DOP estimate's floor for a striping scan's backgrounds. Each background
// is the mean of K - 2 frames (docs/polarized-striping.md "striping"), so its
// noise is sigma / sqrt(K - 2) and the same 40-sigma rule on r's noise
// (<= 0.035) sits sqrt(K - 2) lower than for one frame. Without it, the
// medium-only pixels, whose background is only the backscatter of the other
// sheets, were all below the one-frame floor and p came out below p_min.
// `frames` = K >= 3.
double background_dop_min_sum(const Levels& lv, uint32_t frames) noexcept;

// Projector columns lit by stripe k of `stripes` on a projector `proj_width`
// wide: `width` columns from `first`, centred on (k + 0.5) W / K - 0.5 rounded
// to whole columns; `centre` = first + (width - 1) / 2 is the column the
// stripe map reports for it.
struct StripeColumns {
  uint32_t first = 0, width = 1;
  double centre = 0;
};
StripeColumns stripe_columns(uint32_t proj_width, uint32_t stripes, uint32_t stripe_px, uint32_t k) noexcept;

}  // namespace procam::polarized_striping
