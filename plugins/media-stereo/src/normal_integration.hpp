// SPDX-License-Identifier: MIT
// Depth from surface normals for Helmholtz stereo (thesis §5.4.2, Fig. 5.18:
// the recovered normals are integrated into the surface; the rank-minimum
// depth of Eq. 5.34 is coarse on untextured surfaces).
//
// Perspective camera: the point of pixel (u, v) is P = z·r, r = ((u−cx)/fx,
// (v−cy)/fy, 1) in the camera frame. A tangent ∂P/∂u is normal to n, so
//   ∂ ln z/∂u = −n_x / (fx · n·r),   ∂ ln z/∂v = −n_y / (fy · n·r)
// (n in the camera frame; exact, no orthographic approximation). With q = ln z
// we minimise over the valid pixels
//   Σ_{4-neighbour edges ij} (q_j − q_i − ½(g_i + g_j))² + λ Σ_i (q_i − ln z0_i)²
// — a least-squares Poisson solve whose weak data term takes the seed z0
// (the rank-minimum depth) for the integration constant and for regions the
// gradients do not connect. Conjugate gradient on the normal equations
// (graph Laplacian + λI: symmetric positive definite for λ > 0).
// Edges are dropped where either gradient is steeper than max_log_slope per
// pixel (grazing normals, silhouettes: depth may jump there).
// Invalid (NaN out): pixels whose normal or seed is not finite, or whose
// normal is grazing (|n·r| ~ 0), or that no kept edge links to a neighbour.
// Units: mm. Threads: single-threaded, pure.
#pragma once

#include <vector>

#include "synthetic.hpp"

namespace procam::media_stereo {

struct IntegrationOptions {
  double lambda = 1e-3;          // weight of the seed term against one gradient edge
  double max_log_slope = 0.02;   // |∂ ln z| per pixel above which an edge is dropped (2 %/px)
  int max_iterations = 4000;
  double tolerance = 1e-10;      // on the residual norm relative to the right-hand side's
};

// depth (mm, camera z, NaN invalid) for `cam`'s pixel grid from world-frame
// unit normals and a seed depth of the same size.
std::vector<float> integrate_normals(const PinholeCamera& cam, const std::vector<Vec3>& normal_world,
                                     const std::vector<float>& seed_depth_mm, const IntegrationOptions& opt = {});

}  // namespace procam::media_stereo
