// SPDX-License-Identifier: MIT
// The single-scattering image of a tank lit by a small bulb (thesis §4.2.2,
// Eq. 4.1–4.2) as a radial profile, fast enough to sit inside a fit.
//
// Geometry (thesis Fig. 4.4): the camera looks orthographically along +z at
// the tank's front face z = 0; the tank is `depth_mm` deep; the bulb (an
// isotropic point source of intensity I0) sits at depth z = B. A pixel whose
// line of sight passes at lateral distance rho from the bulb sees
//   E(rho) = beta I0 ∫_0^D exp(-sigma (z + d)) / d^2 P(g, cos a) dz,        (Eq. 4.2)
//   d = sqrt(rho^2 + (z - B)^2), cos a = (B - z) / d (a = pi - theta, Eq. 4.1).
// With the orthographic view E depends on (x, y) only through rho, so the
// image is a 1-D profile. ProfileModel returns the unit profile
// K(rho; sigma, g) = E / (beta I0); beta I0 is a linear scale (Eq. 4.4–4.5).
//
// Quadrature: substituting z = B - rho cot a (a = the scattering angle)
// gives dz / d^2 = da / rho and z + d = B + rho tan(a / 2), so
//   K = (1 / rho) ∫_{a0}^{a1} exp(-sigma (B + rho tan(a/2))) P(g, cos a) da,
//   a0 = atan(rho / B), a1 = pi - atan(rho / (D - B)),
// a smooth integrand without the 1/d^2 spike. Gauss–Legendre on panels
// graded towards both ends (the H-G forward peak of width ~ 1 - g sits at a0;
// tan(a/2) steepens near a1). The geometric part of every node (weight,
// path length, cos a) depends on the geometry only and is computed once;
// evaluate() then costs one exp and one phase evaluation per node.
//
// Units: mm, 1/mm, phase functions in 1/sr (normalised over the sphere).
// Threads: const methods are safe to call concurrently.
#pragma once

#include <cstddef>
#include <vector>

namespace procam::medium {

// Henyey–Greenstein phase function (1 - g^2) / (4 pi (1 + g^2 - 2 g cos a)^1.5), |g| < 1.
double hg_phase(double g, double cos_angle) noexcept;

// The truncated Legendre expansion of H-G used for g > 0.95 (thesis §4.3.3):
// (1 / 4 pi) sum_{i < terms} (2 i + 1) g^i P_i(cos a). `terms` < 100 as the
// thesis; it rings (may go negative) in the tail.
double legendre_phase(double g, double cos_angle, int terms) noexcept;

enum class Phase { henyey_greenstein, truncated_legendre };

struct TankGeometry {
  double depth_mm = 300;       // D: tank depth along the camera axis
  double bulb_depth_mm = 150;  // B: depth of the bulb centre, 0 < B < D
};

class ProfileModel {
 public:
  ProfileModel() = default;
  // rho_mm: the lateral distances to evaluate, each > 0. max_panel_rad > 0
  // splits the panels until none is wider (in scattering angle) than that:
  // the truncated Legendre series oscillates with period ~ 2 pi / terms
  // (0.06 rad at 99 terms) and needs ~ 0.02 rad; H-G needs no split.
  ProfileModel(const TankGeometry& geo, std::vector<double> rho_mm, double max_panel_rad = 0);

  size_t size() const noexcept { return rho_.size(); }
  const std::vector<double>& rho_mm() const noexcept { return rho_; }

  // out[i] = K(rho_i; sigma, g) (Eq. 4.2 with beta = I0 = 1), units 1/mm^2/sr·mm.
  void evaluate(double sigma, double g, Phase phase, int legendre_terms, std::vector<double>& out) const;

 private:
  struct Node {
    double weight;     // Gauss–Legendre weight / rho
    double path_mm;    // z + d: the ray's length in the medium (source -> point -> front face)
    double cos_angle;  // cos a, a the scattering angle
    double angle;      // a (rad)
  };
  std::vector<double> rho_;
  std::vector<Node> nodes_;  // nodes_per_rho_ per rho, contiguous
  size_t nodes_per_rho_ = 0;
};

}  // namespace procam::medium
