// SPDX-License-Identifier: MIT
// Source–camera placement in a scattering medium (thesis §5.3, P4): the
// single-scattering components D, A, B (Eq. 5.11–5.13) at the image centre for
// a point source L beside a pinhole camera C, a Lambertian plane at distance d
// and a homogeneous medium, over source–camera separations d_LC; the quality
// measures CQM·W (flood, Eq. 5.8 + 5.10) and GQM·W (one light sheet through
// the observed point, Eq. 5.9 + 5.10); the separation that maximises each.
//
// Geometry (mm): camera at the origin looking along +z; the plane z = d with
// albedo R; source at (d_LC, 0, 0); O = (0, 0, d) is the observed point; the
// medium fills 0 < z < d. Radiance units: I0 = 1.
//   D = I0 / d_LO^2 e^{-sigma (d_LO + d_CO)} (R / pi) cos(phi)                     (5.11)
//   A = (R / pi) e^{-sigma d_CO} ∫ I0 / d_LX^2 e^{-sigma (d_LX + d_XO)} beta F(alpha) cos(gamma) / d_XO^2 dV   (5.12)
//   B = ∫_C^O I0 / d_LY^2 e^{-sigma (d_LY + d_YC)} beta F(theta) dY               (5.13)
// F is the Henyey–Greenstein phase function with parameter g; beta (the
// scattering coefficient) and 1/d_XO^2 are written out where the thesis
// absorbs them in F and dV. A is integrated in spherical coordinates about O
// (dV = r^2 dr dw cancels 1/d_XO^2); B by the midpoint rule along the ray.
// Light sheet: the slab of thickness `sheet_mm` through L, O and the y axis;
// A and B are restricted to it (A as an integral over the sheet's plane).
// Polarisation: B(1 - p) in the measures with the given DOP p (0: none).
// Sensor: W = sigmoid((S - mu) / z) with mu = 3 noise, z = noise, the noise in
// units of the clear-air direct signal D_clear = I0 R / (pi d^2) (noise 0:
// W = 1 wherever S > 0).
// Pure functions; no exceptions but std::bad_alloc; reentrant.
#pragma once

#include <string>
#include <vector>

namespace procam::polarized_striping {

struct PlacementParams {
  double distance_mm = 500;     // camera to plane, d
  double albedo = 0.6;          // Lambertian R (the thesis's value)
  double sigma_per_mm = 0.005;  // extinction
  double beta_per_mm = 0.004;   // scattering (<= sigma)
  double g = 0.8;               // Henyey–Greenstein (the thesis's Fig. 5.5 value)
  double p = 0.8;               // DOP of the backscatter (thesis: ~0.8 measured in milk); 0: no polariser
  double noise = 5e-4;          // sensor noise, fraction of D_clear
  double sheet_mm = 5;          // light-sheet thickness
  double min_separation_mm = 0, max_separation_mm = 800;
  int steps = 41;               // separations sampled (>= 3)
  int quality = 1;              // integration grid multiplier (1: ~50k samples per separation)
};

struct PlacementSample {
  double separation_mm = 0;
  double d = 0, a = 0, b = 0;              // flood, units of D_clear
  double cqm = 0, w = 0, cqm_w = 0;        // flood (Eq. 5.8, 5.10)
  double sheet_a = 0, sheet_b = 0;         // light sheet
  double gqm = 0, sheet_w = 0, gqm_w = 0;  // light sheet (Eq. 5.9, 5.10)
};

struct PlacementResult {
  std::vector<PlacementSample> curve;
  double best_flood_mm = 0, best_sheet_mm = 0;  // argmax CQM·W, GQM·W (parabolic refinement)
  size_t best_flood_index = 0, best_sheet_index = 0;
};

// Empty string when the parameters are usable, else what is wrong.
std::string check(const PlacementParams& p);

// The curve and its optima; p must pass check().
PlacementResult evaluate_placement(const PlacementParams& p);

// The curve as CSV (header + one row per separation).
std::string placement_csv(const PlacementResult& r);

// A PNG plot (RGB, `width` x `height`): CQM·W (blue) and GQM·W (red) against
// the separation, each scaled to its maximum, the optima as vertical lines.
std::vector<unsigned char> placement_png(const PlacementResult& r, int width = 640, int height = 400);

}  // namespace procam::polarized_striping
