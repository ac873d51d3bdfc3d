// SPDX-License-Identifier: MIT
// Choosing the concentration (thesis §4.2.4, Fig. 4.7; TECHNIQUES M3): from
// the extinction estimates sigma-hat of several dilutions (Eq. 4.3, from the
// attenuation of the bulb's direct image), test linearity in the volume,
// pick the best volume and stop the user beyond single scattering.
//
// Linearity: sigma-hat = c V through the origin, c by least squares on the
// `linear_points` smallest non-zero volumes; a volume whose sigma-hat falls
// below c V by more than `tolerance` (fraction) is nonlinear: multiple
// scattering makes sigma-hat the smaller "reduced" attenuation (§4.2.4).
// Bound: sigma-hat > max_sigma_per_mm (default 0.04 /mm, §4.2.3) is beyond
// single scattering whatever the line says.
// Best: the largest volume before the first nonlinear or out-of-bound one
// whose bulb radiance is at least `min_bulb_radiance` (the SNR floor): the
// most scattering signal still inside the single-scattering regime.
// Units: ml, 1/mm, DN/us. Threads: pure function.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace procam::medium {

struct DilutionPoint {
  double volume_ml = 0;
  double sigma_hat = 0, sigma_hat_ci95 = 0;  // 1/mm; NaN when it could not be measured
  double bulb_radiance = 0;                  // DN/us, mean of the bulb's central pixels
  std::string note;                          // why sigma_hat is missing
};

struct ConcentrationSettings {
  unsigned linear_points = 3;
  double tolerance = 0.1, max_sigma_per_mm = 0.04, min_bulb_radiance = 0;
};

struct ConcentrationResult {
  std::vector<DilutionPoint> points;
  double slope_per_ml = 0;   // c: sigma-hat per ml on the linear part
  int first_nonlinear = -1;  // index into points, -1 = none
  int first_over_bound = -1;
  int best = -1;             // -1 = no usable volume
  std::vector<std::string> warnings;
  nlohmann::json to_json() const;
};

ConcentrationResult analyse_dilutions(std::vector<DilutionPoint> points, const ConcentrationSettings& s);

}  // namespace procam::medium
