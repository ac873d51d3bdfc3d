// SPDX-License-Identifier: MIT
// Single-scattering rendering of a non-homogeneous density (thesis ch. 6
// §6.5, Eq. 6.4-6.5 and 6.22-6.24): a distant source lights the box along
// one axis, an orthographic camera looks along an axis, and the image is
// the scattered intensity E^s on the camera-side face (air-light) plus the
// transmittance exp(-sigma int r) that attenuates whatever lies behind.
//
// Geometry (first model, stated): light and view directions are box axes
// (either sign, same or different axes). General directions need boundary
// conditions on up to three inflow faces and are not done here.
// Units: density r is dimensionless (a concentration), sigma and beta are
// per box length unit at r = 1, phase in 1/sr, irradiance in the caller's
// radiometric unit; images are in irradiance * (beta * phase * length).
// Limits: optically thin media (single scattering only: multiple
// scattering is ignored, so results are valid while sigma int r << 1-ish).
// Threads: renderers are immutable after construction and thread-safe.
#pragma once

#include <vector>

#include "procam/legendre/field.hpp"
#include "procam/legendre/linalg.hpp"

namespace procam::legendre {

struct Lighting {
  size_t light_axis = 1;   // light travels along this axis
  int light_sign = +1;     // +1: towards hi (enters at the lo face)
  size_t view_axis = 0;    // scattered light reaches the camera along this axis
  int view_sign = +1;      // +1: towards hi (camera on the hi face, looking at -axis)
  double irradiance = 1.0; // E0 of the source at the entry face
  double sigma = 1.0;      // extinction coefficient at r = 1
  double beta = 0.9;       // scattering coefficient at r = 1 (albedo beta/sigma)
  double g = 0.0;          // Henyey-Greenstein anisotropy of Omega(theta)
  // Omega(theta) for the scattering angle between the two directions.
  double phase() const;
};

struct RenderResult {
  bool ok = true;
  std::string error;
  Shape image{1, 1, 1};               // cells; the view axis has 1
  std::vector<double> airlight;       // E^s on the camera face, per image cell
  std::vector<double> transmittance;  // exp(-sigma int r) along the view ray
};

// Legendre-domain renderer: solves Eq. 6.22 for [I^d] and 6.23 for [I^s]
// with n_render polynomials per axis (the thesis uses more for intensity
// than for density), each as one K x K linear system whose top-degree rows
// along the ray axis are replaced by the inflow boundary condition (the tau
// method), then evaluates Eq. 6.24 at the image cell centres. O(K^3).
class LegendreRenderer {
 public:
  // Throws std::invalid_argument for bad axes/signs/sizes.
  LegendreRenderer(size_t dims, size_t n_render, const Box& box, const Lighting& light);
  // image_cells: cells per axis over the box (the view axis is ignored).
  RenderResult render(const Field& density, const Shape& image_cells) const;

 private:
  Matrix tau_system(const Matrix& m, size_t axis, int sign) const;
  size_t dims_, n_;
  Box box_;
  Lighting light_;
  std::array<Matrix, 3> d_;  // K x K derivative operators per used axis
};

// Grid baseline: the same quantities by marching the cell-centred density
// along the light and view axes (midpoint rule), O(N).
RenderResult render_grid(const std::vector<double>& density, size_t dims, const Shape& cells, const Box& box,
                         const Lighting& light);

}  // namespace procam::legendre
