// SPDX-License-Identifier: MIT
// Multiple scattering in the projector-lit medium renderer (orders >= 2 of
// the backscatter B; docs/media.md "Multiple scattering"). Model:
//
//   B_ms(i) = r · (G_w ∗ S)(i)      for pixels whose ray crosses the medium
//
// S the frame's single-scattered intensity (Eq. 5.13, the chunk sums), G_w a
// Gaussian of w camera pixels, r one ratio per view. Linear in the pattern. Why this form: in a forward-peaked medium (milk, g ≈ 0.9) the
// light of orders >= 2 that comes back to the camera is mostly light that was
// scattered forward a few times (so it stayed near the beam) and then once
// backwards; it comes from where single backscatter comes from, spread
// sideways by the forward-scatter cone, and its amount relative to single
// backscatter depends on the medium and the tank, not on the pattern.
//  - r: the Monte Carlo reference (backscatter_monte_carlo_orders) under
//    flood light at up to 9 pixels of a 3×3 grid (same paths for both
//    orders): r = Σ multiple / Σ single. Under flood G_w ∗ S ≈ S, so B_ms
//    matches the Monte Carlo there by construction; the pattern dependence
//    (the kernel) is what medium_multiple_test checks against it.
//  - w: the RMS lateral offset of forward-scattered light after half the
//    median in-medium camera-ray length (forward_scatter()), for both legs
//    (×√2), in camera pixels at the median mid-depth of those rays.
//  - Polarization: the Monte Carlo is scalar. Its paths that turned only by
//    small angles (< 30°) before the vertex that sends light back keep the
//    single-scattering polarization (share ms_keep, 10-45 % in the chart
//    tanks); the rest (at least two large-angle scatterings) is taken as
//    depolarized: an assumption, stated in docs/media.md.
#include <algorithm>
#include <cmath>

#include "medium.hpp"
#include "parallel.hpp"

namespace procam::sim {

void prepare_multiple(const Scene& scene, const ProjectorModel& projector, const Rigid3& world_from_cam,
                      const Rigid3& world_from_proj, const PreparedView& v, MediumTaps& taps, int threads) {
  if (!scene.medium || scene.medium->multiple_scattering != Medium::MultipleScattering::diffuse) return;
  const Medium& m = *scene.medium;
  const size_t n = v.pixel_count();
  const Vec3 cam_c = world_from_cam.translation_mm;
  const Intrinsics& k = v.camera.intrinsics;
  // Per pixel: does its ray cross the medium before its surface; the length
  // inside and the camera z of the midpoint (for the kernel).
  std::vector<float> gain_mask(n, 0.f);
  std::vector<double> len, zmid;
  for (uint32_t r = 0; r < v.height; ++r)
    for (uint32_t c = 0; c < v.width; ++c) {
      const size_t i = size_t{r} * v.width + c;
      const Vec3 ray_cam = k.ray(static_cast<double>(c), static_cast<double>(r));
      const Vec3 u = normalized(world_from_cam.rotation * ray_cam);
      double t0 = 0, t1 = 0;
      if (!medium_interval(m, cam_c, u, t0, t1)) continue;
      const double depth = static_cast<double>(v.depth_mm[i]);  // camera z of the surface (inf: none)
      const double uz = normalized(ray_cam).z;
      if (std::isfinite(depth) && uz > 0) t1 = std::min(t1, depth / uz);
      if (!(t1 > t0)) continue;
      gain_mask[i] = 1.f;
      if (!std::isfinite(t1)) t1 = t0 + 40.0 / m.sigma_t_per_mm;
      len.push_back(t1 - t0);
      zmid.push_back(0.5 * (t0 + t1) * uz);
    }
  if (len.empty()) return;
  auto median = [](std::vector<double>& x) {
    std::nth_element(x.begin(), x.begin() + static_cast<ptrdiff_t>(x.size() / 2), x.end());
    return x[x.size() / 2];
  };
  const double len_med = median(len), z_med = median(zmid);
  const double spread_mm = std::sqrt(2.0) * forward_scatter(m, 0.5 * len_med).sigma_lat_mm;
  taps.ms_sigma_px = z_med > 0 ? spread_mm * k.fx / z_med : 0.0;

  // The ratio from the Monte Carlo at a 3×3 grid of pixels with backscatter.
  constexpr size_t kPaths = 20000;  // ratio standard error ~6 % (heavy chart tank), ~0.5 s on 2 threads
  constexpr int kMaxVertices = 1000;  // paths end long before (they leave the tank)
  const std::vector<float> flood(size_t{projector.intrinsics.width} * projector.intrinsics.height, 1.f);
  std::vector<BackscatterOrders> mc(9);
  detail::parallel_rows(9, threads, [&](uint32_t b, uint32_t e) {
    for (uint32_t s = b; s < e; ++s) {
      const double col = std::floor((0.25 + 0.25 * (s % 3)) * v.width), row = std::floor((0.25 + 0.25 * (s / 3)) * v.height);
      const size_t i = static_cast<size_t>(row) * v.width + static_cast<size_t>(col);
      if (taps.offset[i] == taps.offset[i + 1]) continue;
      mc[s] = backscatter_monte_carlo_orders(scene, projector, world_from_cam, world_from_proj, k, col, row, flood,
                                             kPaths, 1000 + s, kMaxVertices);
    }
  });
  double single = 0, multiple = 0, keep = 0, var_s = 0, var_m = 0;
  for (const BackscatterOrders& o : mc) {
    single += o.single;
    multiple += o.multiple;
    keep += o.multiple_small_turns;
    var_s += o.se_single * o.se_single;
    var_m += o.se_multiple * o.se_multiple;
  }
  if (!(single > 0)) return;
  taps.ms_ratio = multiple / single;
  taps.ms_keep = multiple > 0 ? keep / multiple : 0.0;
  taps.ms_ratio_se = taps.ms_ratio * std::sqrt(var_s / (single * single) + (multiple > 0 ? var_m / (multiple * multiple) : 0.0));
  taps.ms_gain.resize(n);
  for (size_t i = 0; i < n; ++i) taps.ms_gain[i] = gain_mask[i] * static_cast<float>(taps.ms_ratio);
}

}  // namespace procam::sim
