// SPDX-License-Identifier: MIT
// Single-scattering image formation for a camera at C and a point light at L
// in a homogeneous medium (thesis §5.4, Eq. 5.14-5.19 binocular with a fixed
// light, Eq. 5.24-5.29 for a reciprocal Helmholtz pair; the same two terms):
//
//   I = D + B                                                    (5.14/5.24)
//   D = I0 e^{-σ d_LP} / d_LP² · cos θ_i · f_r · e^{-σ d_CP}     (5.15/5.25)
//   B(t) = ∫_0^t β Ω(g, γ(x)) I0 e^{-σ a(x)} / a(x)² · e^{-σ x} dx (5.16/5.26)
//
// x the distance from C along the viewing ray, a(x) the distance of that
// point from L, γ(x) the angle between the light's propagation direction
// (L → point) and the scattered direction (point → C), Ω the Henyey-Greenstein
// phase function (1/sr). The thesis prints Eq. 5.16 without the scattering
// coefficient β; it belongs there (B is proportional to the scatterer density,
// §5.1 Eq. 5.13), so we carry it.
//
// Units: mm, mm⁻¹, intensities in arbitrary linear units (I0 in units·mm²).
// Threads: everything here is pure functions and immutable data.
#pragma once

#include <cstdint>
#include <vector>

#include "procam/base/geometry.hpp"

namespace procam::media_stereo {

// Homogeneous medium: extinction σ, scattering β (β <= σ), HG parameter g.
struct MediumParams {
  double sigma_per_mm = 0;
  double beta_per_mm = 0;
  double g = 0;
};

// Henyey-Greenstein phase function, 1/sr, ∫ over the sphere = 1; cos_theta is
// the cosine between the incident and the scattered propagation directions
// (−1: straight back).
double hg_phase(double g, double cos_theta);

// Integrand of Eq. 5.16 at distance x along the unit ray `dir` from `cam`:
// β Ω(g, γ) I0 e^{-σ(a + x)} / a².  0 where the point coincides with the light.
double backscatter_integrand(const MediumParams& m, double light_intensity, const Vec3& cam, const Vec3& dir,
                             const Vec3& light, double x);

// The emission cone of a projector used as the light: it lights only the
// points that project inside its image (pixel centres at integers, the image
// spanning [-0.5, width-0.5] x [-0.5, height-0.5], as the sim's flood), and
// isotropically (I0 / d^2) inside it. Without a cone the light is an isotropic
// point source over the whole sphere.
struct LightCone {
  Rigid3 light_from_world{};
  uint32_t width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
};

// [t0, t1] (t0 >= 0) of the ray cam + dir·x inside the cone (a convex set, so
// one interval); false when the ray misses it.
bool cone_interval(const LightCone& cone, const Vec3& cam, const Vec3& dir, double& t0, double& t1);

// B(t) of Eq. 5.16 by composite 3-point Gauss-Legendre on segments of at most
// `segment_mm`, over the part of [0, t] inside `cone` (nullptr: all of it).
// dir must be unit length. t <= 0 gives 0.
double backscatter(const MediumParams& m, double light_intensity, const Vec3& cam, const Vec3& dir,
                   const Vec3& light, double t, double segment_mm = 4.0, const LightCone* cone = nullptr);

// Cumulative backscatter along many rays: B at distances k·step_mm,
// k = 0..samples-1, per ray (row-major: ray r's samples at [r·samples,
// (r+1)·samples)). Built once per (camera, light, medium); lookups interpolate
// linearly in distance. Beyond the last sample: NaN (the caller's depth range
// must lie inside the table).
struct BackscatterTable {
  double step_mm = 0;
  uint32_t samples = 0;
  std::vector<float> b;
  double at(size_t ray, double t) const;
};

// Builds the table for `rays` (unit directions from `cam`) out to max_mm,
// integrating only inside `cone` when given.
BackscatterTable backscatter_table(const MediumParams& m, double light_intensity, const Vec3& cam,
                                   const std::vector<Vec3>& rays, const Vec3& light, double max_mm, double step_mm,
                                   const LightCone* cone = nullptr);

}  // namespace procam::media_stereo
