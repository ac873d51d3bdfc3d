// SPDX-License-Identifier: MIT
// Device models of the simulated rig: the projector (emission curve, thin-lens
// defocus) and the camera sensor (electrons, noise, gain, quantisation).
//
// Units (hw/sim/SCENES.md "Units"):
//   iu  irradiance unit: what a projector with irradiance_at_1m = 1 delivers,
//       for emitted value 1, to a surface 1000 mm away facing it.
//   ru  radiance unit = iu / sr: a Lambertian surface of albedo a under
//       irradiance E iu has radiance a·E/π ru.
//   Projector coordinates in projector pixels, pixel centres at integers.
// Plain data; all functions are pure and thread-safe.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "procam/base/calibration.hpp"

namespace procam::sim {

struct ProjectorModel {
  std::string name = "sim projector";
  Intrinsics intrinsics;          // projector pixels
  double refresh_hz = 60;         // reported in ProjectorInfo only (no pacing)
  double irradiance_at_1m = 1.0;  // iu at 1000 mm, normal incidence, emitted = 1
  double black_level = 0.01;      // emitted fraction for pattern value 0
  double gamma = 2.2;             // emitted = black + (1 - black) * p^gamma
  double aperture_mm = 2.0;       // thin-lens aperture diameter (0: pinhole, no defocus)
  double focus_mm = 800;          // default focal-plane distance along the projector axis

  // Linear emitted light for a pattern value p in [0, 1] (clamped).
  double emitted(double p) const {
    p = std::clamp(p, 0.0, 1.0);
    return black_level + (1.0 - black_level) * std::pow(p, gamma);
  }
  // Blur-circle diameter in projector pixels of a point at projector-axis
  // depth z_p_mm with the lens focused at focus_mm (thin lens):
  //   b = aperture_mm · fx_p · |1/focus_mm − 1/z_p_mm|.
  double blur_diameter_px(double z_p_mm, double focus) const {
    return aperture_mm * intrinsics.fx * std::abs(1.0 / focus - 1.0 / z_p_mm);
  }
  // Gaussian σ standing in for the uniform blur disc: per-axis standard
  // deviation of a disc of radius b/2 is b/4.
  double blur_sigma_px(double z_p_mm, double focus) const { return 0.25 * blur_diameter_px(z_p_mm, focus); }
};

// Camera sensor. electrons = exposure_us · sensitivity · radiance (ru), then
// shot noise (Gaussian with variance = mean electrons), read noise (Gaussian,
// read_noise_e RMS), clamp at full well, DN = electrons · dn_per_e(gain), round,
// clamp to [0, 2^bit_depth − 1].
struct SensorModel {
  uint32_t bit_depth = 8;       // 8 → U8 frames; 9..16 → U16 right-aligned
  double exposure_us = 10000;   // default exposure
  double gain_db = 0;           // default analog gain
  double sensitivity = 2.0;     // electrons per (ru · µs)
  double full_well_e = 10000;   // saturation charge
  double read_noise_e = 10;     // RMS electrons per read
  bool shot_noise = true;       // Poisson shot noise (Gaussian approximation)

  double max_dn() const { return static_cast<double>((uint64_t{1} << bit_depth) - 1); }
  // At 0 dB a full well maps to the largest DN.
  double dn_per_e(double gain) const { return max_dn() / full_well_e * std::pow(10.0, gain / 20.0); }
};

}  // namespace procam::sim
