// SPDX-License-Identifier: MIT
// Binocular stereo in a scattering medium (thesis §5.4.1): two calibrated
// cameras A (left, the reference) and B (right), one point light L fixed for
// both images. For each left pixel and depth hypothesis z the scene point P =
// A + ray·z is projected into the right image and the two intensities are
// compared:
//   media constraint (Eq. 5.22):  a = (I_l − B_l(z)) e^{σ d_AP},
//                                 b = (I_r − B_r(z)) e^{σ d_BP},
//   clear-air constraint (Eq. 5.20): a = I_l, b = I_r,
// with B_l, B_r the single-scattering backscatter of Eq. 5.16/5.19 up to P
// along each camera's ray (BackscatterTable lookups). Eq. 5.23 minimises
// s(d) over d; we minimise the window cost
//   C(z) = Σ_W (a − b)² / Σ_W (a² + b²)
// (the normalised squared residual of s over a window of pixels sharing the
// hypothesis z; the normalisation stops the e^{σd} gain from favouring near
// depths), with a parabola through the best three hypotheses.
//
// Samples that are saturated or project outside the right image drop out of
// the window; a window cost needs at least half its pixels valid.
// Invalid (NaN) pixels: the left sample saturated, the signal I_l − B_l (or
// I_l in clear air) at/below DepthSearch::min_signal (shadows, pure
// backscatter), no finite cost for any z, or the minimum on the first/last
// hypothesis (depth outside the searched range).
// Units: mm, depth = z in the left camera frame. Threads: single-threaded,
// pure; the inputs are read only during the call.
#pragma once

#include <optional>
#include <vector>

#include "scatter_model.hpp"
#include "stereo_common.hpp"
#include "synthetic.hpp"

namespace procam::media_stereo {

enum class Constraint { media, clear_air };

struct BinocularInput {
  PinholeCamera left, right;
  std::vector<float> left_image, right_image;  // linear intensities, w×h of each camera
  Vec3 light{};
  double light_intensity = 1;
  MediumParams medium;  // used by Constraint::media only
  std::optional<LightCone> light_cone;  // a projector as the light: B only inside its image
};

// Depth map (mm, left camera's z; NaN invalid), left-sized.
std::vector<float> binocular_depth(const BinocularInput& in, const DepthSearch& search, Constraint constraint);

}  // namespace procam::media_stereo
