// SPDX-License-Identifier: MIT
// Medium parameters from one image of the medium alone (thesis §5.4.1,
// "Recovering the medium parameters"): camera and point light side by side,
// no scene, the rays ending at a black wall. The image is pure backscatter,
// B = β · F(σ, g) per pixel (Eq. 5.16 with the wall as the ray's end), so β
// follows in closed form (linear least squares) for each (σ, g), and (σ, g)
// minimise the squared residual: a log-σ × g grid, then Nelder-Mead.
// Units: mm⁻¹. Threads: single-threaded, pure.
#pragma once

#include <cstdint>
#include <vector>

#include "scatter_model.hpp"
#include "synthetic.hpp"

namespace procam::media_stereo {

struct MediumFit {
  MediumParams medium;
  double rms_residual = 0;  // image units, over the pixels used
  bool ok = false;          // false: no usable pixel or no backscatter
};

// `stride`: use every stride-th pixel in x and y. Pixels NaN or >= saturation
// are skipped. `cone`: the light's emission cone (B integrated only inside
// it, as scatter_model.hpp's backscatter()); nullptr: isotropic everywhere.
MediumFit fit_medium(const PinholeCamera& cam, const std::vector<float>& image, const Vec3& light,
                     double light_intensity, double wall_z_mm, uint32_t stride = 8, double saturation = 1e30,
                     const LightCone* cone = nullptr);

}  // namespace procam::media_stereo
