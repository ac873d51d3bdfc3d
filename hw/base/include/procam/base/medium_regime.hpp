// SPDX-License-Identifier: MIT
// Where single scattering describes the dilution tank (thesis §4.2.3,
// Fig. 4.5), as measured in the sim: docs/media.md "Regime of validity".
// Header-only plain data and functions in the bottom layer, so a decoder
// plugin (the `medium` plugin's concentration stop and measure warning) uses
// the same numbers as the sim without linking it. The table is data measured
// with the sim's Monte Carlo reference (procam_medium_regime); the sim's
// tank_mc_test checks it against a fresh run.
//
// The error is the share of the tank image's energy that single scattering
// misses: (E_all − E_single)/E_all over the tank's face without the bulb,
// E_all by Monte Carlo with every order of scattering (procam_medium_regime;
// TankEnergy::relative_excess in hw/sim/src/tank.hpp) — the thesis's
// "differences between energies". Shipped tank: 300 mm deep, bulb (r 10 mm)
// at mid depth, H-G g = 0.9, the face sampled on 36 × 30 points with 2500
// paths each (standard errors 0.001-0.04, docs/report/ch4). It depends on
// the scattering β almost alone (forward-scattered light keeps travelling
// with the bulb's light; absorption thins both alike): over κ = σ − β from
// 0 to 0.03 /mm the columns differ by about their noise, so the table keeps,
// per β, the largest value over κ (conservative). Other tank depths D scale
// β by D/300 (same optical depth; an approximation).
//
// Threads: constexpr data and pure functions.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>

namespace procam {

// β grid (1/mm) and the energy share missed there (max over κ in [0, 0.03]).
inline constexpr std::array<double, 9> kRegimeBetaPerMm = {0.0,   0.00025, 0.0005, 0.001, 0.002,
                                                           0.004, 0.01,    0.02,   0.04};
inline constexpr std::array<double, 9> kRegimeMissedEnergy = {0.0,    0.0252, 0.0519, 0.1062, 0.2013,
                                                              0.3518, 0.6652, 0.8934, 0.9902};
inline constexpr double kRegimeTankDepthMm = 300.0;

// Share of the energy single scattering misses for scattering β (1/mm) in a tank
// `depth_mm` deep (linear in β between the grid points; 1 beyond the last,
// where single scattering holds nothing). NaN/negative β: 1 (not valid).
inline double single_scattering_error(double beta_per_mm, double depth_mm = kRegimeTankDepthMm) {
  if (!(beta_per_mm >= 0) || !(depth_mm > 0)) return 1.0;
  const double b = beta_per_mm * depth_mm / kRegimeTankDepthMm;
  for (std::size_t i = 1; i < kRegimeBetaPerMm.size(); ++i)
    if (b <= kRegimeBetaPerMm[i]) {
      const double w = (b - kRegimeBetaPerMm[i - 1]) / (kRegimeBetaPerMm[i] - kRegimeBetaPerMm[i - 1]);
      return kRegimeMissedEnergy[i - 1] + w * (kRegimeMissedEnergy[i] - kRegimeMissedEnergy[i - 1]);
    }
  return 1.0;
}

// The largest β (1/mm) at which single scattering misses at most `tolerance`
// of the energy in a tank `depth_mm` deep: the inverse of
// single_scattering_error() (linear between grid points). tolerance >= the
// table's last value: the last grid β; <= 0: 0.
inline double max_beta_for_error(double tolerance, double depth_mm = kRegimeTankDepthMm) {
  if (!(tolerance > 0) || !(depth_mm > 0)) return 0.0;
  const double scale = kRegimeTankDepthMm / depth_mm;
  for (std::size_t i = 1; i < kRegimeBetaPerMm.size(); ++i)
    if (tolerance <= kRegimeMissedEnergy[i]) {
      const double w = (tolerance - kRegimeMissedEnergy[i - 1]) / (kRegimeMissedEnergy[i] - kRegimeMissedEnergy[i - 1]);
      return (kRegimeBetaPerMm[i - 1] + w * (kRegimeBetaPerMm[i] - kRegimeBetaPerMm[i - 1])) * scale;
    }
  return kRegimeBetaPerMm.back() * scale;
}

// Whether single scattering misses less than `tolerance` of the energy
// (default the thesis's 5 %) for extinction σ and absorption κ = σ − β
// (1/mm). With the shipped tank: β < 0.00048 /mm (β·300 mm < 0.15) at 5 %.
inline bool single_scattering_valid(double sigma_per_mm, double kappa_per_mm, double depth_mm = kRegimeTankDepthMm,
                                    double tolerance = 0.05) {
  if (!(sigma_per_mm >= 0) || !(kappa_per_mm >= 0) || kappa_per_mm > sigma_per_mm) return false;
  return single_scattering_error(sigma_per_mm - kappa_per_mm, depth_mm) < tolerance;
}

}  // namespace procam
