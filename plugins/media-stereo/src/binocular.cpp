// SPDX-License-Identifier: MIT
#include "binocular.hpp"

#include <cmath>
#include <limits>

namespace procam::media_stereo {


std::vector<float> binocular_depth(const BinocularInput& in, const DepthSearch& search, Constraint constraint) {
  const uint32_t w = in.left.width, h = in.left.height, kc = search.count();
  const size_t n = size_t{w} * h;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> depth(n, nan);
  if (kc < 3 || in.left_image.size() != n || in.right_image.size() != size_t{in.right.width} * in.right.height)
    return depth;
  const bool media = constraint == Constraint::media;
  const MediumParams m = media ? in.medium : MediumParams{};
  const Vec3 ca = in.left.centre(), cb = in.right.centre();

  std::vector<double> len_l;
  const auto rays_l = unit_rays(in.left, &len_l);
  const auto rays_r = unit_rays(in.right, nullptr);
  double max_len = 0;
  for (double l : len_l) max_len = std::max(max_len, l);
  const double reach = search.z_max_mm * max_len + norm(cb - ca) + 4.0;
  const double step = 2.0;
  BackscatterTable tl, tr;
  if (media && m.beta_per_mm > 0) {
    const LightCone* cone = in.light_cone ? &*in.light_cone : nullptr;
    tl = backscatter_table(m, in.light_intensity, ca, rays_l, in.light, reach, step, cone);
    tr = backscatter_table(m, in.light_intensity, cb, rays_r, in.light, reach, step, cone);
  }
  auto b_left = [&](size_t p, double t) { return tl.b.empty() ? 0.0 : tl.at(p, t); };
  auto b_right = [&](double u, double v, double t) {
    if (tr.b.empty()) return 0.0;
    size_t idx[4];
    double wt[4];
    if (!bilinear_taps(in.right.width, in.right.height, u, v, idx, wt)) return std::numeric_limits<double>::quiet_NaN();
    double s = 0;
    for (int i = 0; i < 4; ++i) s += wt[i] * tr.at(idx[i], t);
    return s;
  };

  // Per-pixel residual volumes (slice k = hypothesis k), then window sums.
  // Invalid samples count 0 in num/den and 0 in cnt: a window's cost uses its
  // valid pixels, if at least half of it is valid (so hypotheses near the
  // image border or beside a saturated blob are not lost).
  std::vector<float> num(n * kc), den(n * kc), cnt(n * kc);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t p = size_t{y} * w + x;
      const double il = in.left_image[p];
      const bool bad_left = !(il < search.saturation) || !std::isfinite(il);
      if (bad_left) continue;  // saturated: no sample, and never valid itself (below)
      for (uint32_t k = 0; k < kc; ++k) {
        float& nk = num[size_t{k} * n + p];
        float& dk = den[size_t{k} * n + p];
        float& ck = cnt[size_t{k} * n + p];
        const double z = search.z_min_mm + k * search.z_step_mm;
        const double d_ap = z * len_l[p];
        const Vec3 pt = ca + rays_l[p] * d_ap;
        double u = 0, v = 0, zr = 0;
        if (!in.right.project(pt, u, v, zr)) continue;
        const double ir = sample_bilinear(in.right_image, in.right.width, in.right.height, u, v, search.saturation);
        if (!std::isfinite(ir)) continue;
        double a = il, b = ir;
        if (media) {
          const double d_bp = norm(pt - cb);
          // Eq. 5.22: remove the backscatter, undo the attenuation of the camera leg.
          a = (il - b_left(p, d_ap)) * std::exp(m.sigma_per_mm * d_ap);
          b = (ir - b_right(u, v, d_bp)) * std::exp(m.sigma_per_mm * d_bp);
        }
        if (!std::isfinite(a) || !std::isfinite(b)) continue;
        nk = static_cast<float>((a - b) * (a - b));
        dk = static_cast<float>(a * a + b * b);
        ck = 1.0f;
      }
    }
  const int r = std::max(0, search.window / 2);
  box_sum(num, w, h, kc, r);
  box_sum(den, w, h, kc, r);
  box_sum(cnt, w, h, kc, r);
  std::vector<float> cost(size_t{kc});
  const auto min_count = static_cast<float>((2 * r + 1) * (2 * r + 1) / 2 + 1);
  for (size_t p = 0; p < n; ++p) {
    for (uint32_t k = 0; k < kc; ++k) {
      const float d = den[size_t{k} * n + p];
      const float c = cnt[size_t{k} * n + p];
      cost[k] = d > 0 && c >= min_count ? num[size_t{k} * n + p] / d : nan;
    }
    const double kk = refined_argmin(cost.data(), 1, kc);
    if (!std::isfinite(kk)) continue;
    const double z = search.z_min_mm + kk * search.z_step_mm;
    // Zero signal: nothing but backscatter (or black) at the chosen depth.
    const double signal = static_cast<double>(in.left_image[p]) - (media ? b_left(p, z * len_l[p]) : 0.0);
    if (!(signal > search.min_signal) || !(static_cast<double>(in.left_image[p]) < search.saturation)) continue;
    depth[p] = static_cast<float>(z);
  }
  return depth;
}

}  // namespace procam::media_stereo
