// SPDX-License-Identifier: MIT
// Methods, parameters and the parsed configuration of the medium plugin (one
// place, shared by describe() and the factory). Units: mm, 1/mm, px
// (camera pixels, centres at integers), us, DN; the radiance map is DN/us.
#pragma once

#include <string>
#include <vector>

#include "fit.hpp"
#include "hdr_merge.hpp"
#include "procam/plugin_sdk.hpp"

namespace procam::medium {

enum class Method { measure, concentration };

std::vector<sdk::ParamSpec> specs_for(Method m);
std::vector<std::string> outputs_of(Method m);

struct Config {
  Method method = Method::measure;
  std::string method_name;
  sdk::Params params;
  HdrSettings hdr;
  FitSettings fit;
  std::vector<double> exposures_us;     // the bracket, one frame each (per dilution)
  double min_signal = 0.05;             // measure: fit bins reaching this fraction of full scale at the longest exposure
  bool spot = false;                    // projector pattern: a spot (else white)
  double spot_x_px = -1, spot_y_px = -1, spot_radius_px = 20;
  std::vector<double> volumes_ml;       // concentration: one HDR bracket per volume, increasing
  uint32_t linear_points = 3;           // concentration: volumes the line through the origin is fit on
  double linearity_tolerance = 0.1;     // concentration: sigma-hat below the line by more than this: nonlinear
  double max_sigma_per_mm = 0.04;       // concentration: single-scattering bound (thesis §4.2.3)
  double max_multiple_scattering = 0.10;  // measure: warn above this share of energy missed (Monte Carlo regime)
  double min_bulb_radiance = 0;         // concentration: SNR floor for the best volume (DN/us); 0 = 1 % of water
  uint32_t threads = 1;
};

// Validates params against the rig's camera 0 (width, height) and reads the
// LUT file if response = lut. Errors name the parameter and what to do.
sdk::Error parse_config(const std::string& method, const nlohmann::json& params, uint32_t cam_w, uint32_t cam_h,
                        Config& cfg);

}  // namespace procam::medium
