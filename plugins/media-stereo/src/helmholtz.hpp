// SPDX-License-Identifier: MIT
// Helmholtz stereo in a scattering medium (thesis §5.4.2). Each reciprocal
// pair j has two calibrated positions A_j, B_j: image_a is taken by the camera
// at A_j with the point light at B_j, image_b with camera and light swapped.
// For a hypothesis P (depth z along a reference camera's ray), Eq. 5.32:
//   w_j = (I_a − B_a) â/d_AP² − (I_b − B_b) b̂/d_BP²,   w_j · n = 0   (5.33)
// â, b̂ unit vectors from P to A_j, B_j; B_a, B_b the backscatter of
// Eq. 5.26/5.29 (camera at A_j lit from B_j and vice versa). Attenuation
// cancels exactly (both images' light travels d_AP + d_BP, Eq. 5.25/5.28),
// so only the backscatter is removed. W(z) stacks the w_j; at the true depth
// rank W <= 2 (Eq. 5.34): we minimise the ratio s3/s2 of its two smallest
// singular values (Zickler et al.), summed over a window, refine by a
// parabola, and take the normal as the right null vector of W(z*), turned to
// face the reference camera. `remove_backscatter = false` is the medium-free
// Helmholtz stereo of Zickler et al. on the same images (the baseline).
//
// Needs >= 3 pairs (3 unknowns: depth and the normal's two angles).
// Invalid (NaN): any sample saturated or outside its image at every depth,
// no signal (largest singular value of W <= 0), minimum on the range ends.
// Units: mm; depth = z in the reference camera; normals in world coordinates.
// Threads: single-threaded, pure.
#pragma once

#include <optional>
#include <vector>

#include "scatter_model.hpp"
#include "stereo_common.hpp"
#include "synthetic.hpp"

namespace procam::media_stereo {

struct ReciprocalPair {
  PinholeCamera cam_a, cam_b;
  std::vector<float> image_a;  // camera at A, light at B
  std::vector<float> image_b;  // camera at B, light at A
  // Emission cones of the lights at B (lighting image_a) and at A (image_b):
  // the backscatter of (3) is integrated only inside them. Empty: isotropic
  // point lights over the whole sphere.
  std::optional<LightCone> cone_b, cone_a;
};

struct HelmholtzInput {
  PinholeCamera reference;  // defines the output grid and depth (needs no image)
  std::vector<ReciprocalPair> pairs;
  double light_intensity = 1;
  MediumParams medium;
};

struct HelmholtzResult {
  std::vector<float> depth_mm;  // NaN invalid
  std::vector<Vec3> normal;     // world, unit; {NaN..} where invalid
  std::vector<float> rank_ratio;  // s3/s2 at the chosen depth (window-averaged), NaN invalid
};

HelmholtzResult helmholtz_stereo(const HelmholtzInput& in, const DepthSearch& search, bool remove_backscatter);

}  // namespace procam::media_stereo
