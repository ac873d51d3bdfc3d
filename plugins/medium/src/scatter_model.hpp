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
// The bulb as an area source (thesis §4.3.3, bulb_radius_mm > 0): a
// Lambertian sphere of radius R and radiance L = I0 / (pi R^2) (so it is a
// point source of intensity I0 from afar). A scattering point at distance d
// from its centre receives light from the sphere's visible cap, the cone of
// half-angle alpha = asin(R / d) about the direction to the centre:
//   exp(-sigma (z + d)) P(g, cos a) / d^2   (point source)
//   -> (1 / (pi R^2)) ∫_cap exp(-sigma (z + l(w))) P(g, w.z) dw,
// l(w) = d cos psi - sqrt(R^2 - d^2 sin^2 psi) the distance to the sphere's
// surface along w (psi its angle from the centre direction). The cap is
// sampled with 3 Gauss–Legendre rings in cos psi, each with 8 azimuths over
// a half circle (the integrand is symmetric about the plane through the
// centre direction and the camera axis), for every node whose phase may vary
// across the cap: a < 1.2 rad (the forward lobe of H-G with g up to 0.99) or
// d < 4 R. Elsewhere the node keeps one direction, the centre's, with the
// cap's exact solid angle 2 pi (1 - cos alpha) and its mean path l (and the
// path's variance, for the second-order correction of the exponential),
// and the phase function's mean over the cap to second order,
// p + <sin^2 psi> / 4 * Lap p (Lap the Laplacian on the sphere; H-G's is
// analytic, the Legendre table's by central differences): the curvature
// term is ~0.1 % at 90 deg for g = 0.93 and 50-250 mm off a 10 mm bulb,
// which is enough to move kappa = sigma - beta of a high-albedo medium by
// >100 % (issue 14).
// Near the forward lobe a point-source model is wrong even far from the
// bulb: a 10 mm bulb 150 mm away subtends 0.067 rad, as wide as the lobe of
// g = 0.9, and the point model then fits g ~0.03-0.06 too high.
//
// Units: mm, 1/mm, phase functions in 1/sr (normalised over the sphere).
// Threads: const methods are safe to call concurrently.
#pragma once

#include <cstddef>
#include <cstdint>
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
  double bulb_radius_mm = 0;   // R: 0 = point source; else every rho must be > R
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
    double weight;     // Gauss–Legendre weight / rho (x the cap's solid angle / (pi R^2) x d^2 for a sphere)
    double path_mm;    // z + d (or z + the cap's mean l): the ray's length in the medium
    double cos_angle;  // cos a, a the scattering angle
    double angle;      // a (rad)
    double path_var;   // variance of the path over the cap (mm^2); 0 for a point source
    double cap_m2;     // <sin^2 psi> / 4 over the cap (psi off its centre): the phase's curvature term; 0 for a point
  };
  // One ring of a sampled cap: kAzimuths directions sharing the path length.
  struct Ring {
    double weight;   // per direction
    double path_mm;  // z + l(psi)
    uint32_t first;  // index of its kAzimuths directions in ring_cos_ / ring_angle_
  };
  static constexpr size_t kAzimuths = 8;
  std::vector<double> rho_;
  std::vector<Node> nodes_;      // single-direction nodes of every rho, contiguous
  std::vector<size_t> node_end_; // nodes of rho i: [node_end_[i-1], node_end_[i])
  std::vector<Ring> rings_;      // cap rings of every rho, contiguous
  std::vector<size_t> ring_end_;
  std::vector<double> ring_cos_, ring_angle_;
};

}  // namespace procam::medium
