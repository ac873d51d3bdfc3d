// SPDX-License-Identifier: MIT
#include "helmholtz.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace procam::media_stereo {

namespace {

struct PairTables {
  BackscatterTable a, b;  // camera A lit from B; camera B lit from A
};

// (I − B) at the projection of pt into cam; NaN when outside or saturated.
double signal_at(const PinholeCamera& cam, const std::vector<float>& img, const BackscatterTable* table,
                 const Vec3& pt, double saturation) {
  double u = 0, v = 0, z = 0;
  if (!cam.project(pt, u, v, z)) return std::numeric_limits<double>::quiet_NaN();
  const double i = sample_bilinear(img, cam.width, cam.height, u, v, saturation);
  if (!table || table->b.empty() || !std::isfinite(i)) return i;
  size_t idx[4];
  double wt[4];
  bilinear_taps(cam.width, cam.height, u, v, idx, wt);
  const double t = norm(pt - cam.centre());
  double b = 0;
  for (int k = 0; k < 4; ++k) b += wt[k] * table->at(idx[k], t);
  return i - b;
}

// M = WᵀW for the hypothesis pt (Eq. 5.32-5.33); false if any sample invalid.
bool build_wtw(const HelmholtzInput& in, const std::vector<PairTables>& tables, bool remove, const Vec3& pt,
               double saturation, double m[3][3], double* max_signal = nullptr) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m[r][c] = 0;
  if (max_signal) *max_signal = 0;
  for (size_t j = 0; j < in.pairs.size(); ++j) {
    const auto& pr = in.pairs[j];
    const double sa = signal_at(pr.cam_a, pr.image_a, remove ? &tables[j].a : nullptr, pt, saturation);
    const double sb = signal_at(pr.cam_b, pr.image_b, remove ? &tables[j].b : nullptr, pt, saturation);
    if (!std::isfinite(sa) || !std::isfinite(sb)) return false;
    if (max_signal) *max_signal = std::max({*max_signal, sa, sb});
    const Vec3 va = pr.cam_a.centre() - pt, vb = pr.cam_b.centre() - pt;
    const double da = norm(va), db = norm(vb);
    const Vec3 w = va * (sa / (da * da * da)) - vb * (sb / (db * db * db));  // Eq. 5.32
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m[r][c] += w[r] * w[c];
  }
  return true;
}

}  // namespace

HelmholtzResult helmholtz_stereo(const HelmholtzInput& in, const DepthSearch& search, bool remove_backscatter) {
  const PinholeCamera& ref = in.reference;
  const uint32_t w = ref.width, h = ref.height, kc = search.count();
  const size_t n = size_t{w} * h;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  HelmholtzResult out;
  out.depth_mm.assign(n, nan);
  out.rank_ratio.assign(n, nan);
  out.normal.assign(n, Vec3{nan, nan, nan});
  if (kc < 3 || in.pairs.size() < 3) return out;
  for (const auto& pr : in.pairs) {
    if (pr.image_a.size() != size_t{pr.cam_a.width} * pr.cam_a.height ||
        pr.image_b.size() != size_t{pr.cam_b.width} * pr.cam_b.height)
      return out;
  }
  const bool remove = remove_backscatter && in.medium.beta_per_mm > 0;
  std::vector<PairTables> tables(in.pairs.size());
  if (remove) {
    for (size_t j = 0; j < in.pairs.size(); ++j) {
      const auto& pr = in.pairs[j];
      const double reach = (search.z_max_mm * 2.0) + norm(pr.cam_a.centre() - ref.centre()) +
                           norm(pr.cam_b.centre() - ref.centre());
      tables[j].a = backscatter_table(in.medium, in.light_intensity, pr.cam_a.centre(), unit_rays(pr.cam_a),
                                      pr.cam_b.centre(), reach, 2.0, pr.cone_b ? &*pr.cone_b : nullptr);
      tables[j].b = backscatter_table(in.medium, in.light_intensity, pr.cam_b.centre(), unit_rays(pr.cam_b),
                                      pr.cam_a.centre(), reach, 2.0, pr.cone_a ? &*pr.cone_a : nullptr);
    }
  }
  // Cost volume: s3/s2 of W(z) per pixel and hypothesis (Eq. 5.34).
  std::vector<float> vol(n * kc, nan);
  const Vec3 c = ref.centre();
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t p = size_t{y} * w + x;
      const Vec3 ray = ref.ray_world(x, y);
      for (uint32_t k = 0; k < kc; ++k) {
        double m[3][3], ev[3];
        Vec3 vec[3];
        if (!build_wtw(in, tables, remove, c + ray * (search.z_min_mm + k * search.z_step_mm), search.saturation, m))
          continue;
        symmetric_eigen3(m, ev, vec);
        if (!(ev[1] > 0)) continue;  // no signal: W has rank <= 1
        vol[size_t{k} * n + p] = static_cast<float>(std::sqrt(std::max(ev[0], 0.0) / ev[1]));
      }
    }
  box_sum(vol, w, h, kc, std::max(0, search.window / 2));
  std::vector<float> cost(kc);
  const double area = static_cast<double>(search.window) * search.window;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t p = size_t{y} * w + x;
      for (uint32_t k = 0; k < kc; ++k) cost[k] = vol[size_t{k} * n + p];
      const double kk = refined_argmin(cost.data(), 1, kc);
      if (!std::isfinite(kk)) continue;
      const double z = search.z_min_mm + kk * search.z_step_mm;
      const Vec3 pt = c + ref.ray_world(x, y) * z;
      double m[3][3], ev[3];
      Vec3 vec[3];
      double max_signal = 0;
      if (!build_wtw(in, tables, remove, pt, search.saturation, m, &max_signal)) continue;
      if (!(max_signal > search.min_signal)) continue;  // zero signal: backscatter only
      symmetric_eigen3(m, ev, vec);
      if (!(ev[2] > 0) || !(ev[1] > 0)) continue;
      Vec3 nrm = vec[0];  // null vector of W(z*)
      if (dot(nrm, c - pt) < 0) nrm = -nrm;
      out.depth_mm[p] = static_cast<float>(z);
      out.normal[p] = nrm;
      out.rank_ratio[p] = static_cast<float>(static_cast<double>(cost[static_cast<size_t>(std::lround(kk))]) / area);
    }
  return out;
}

}  // namespace procam::media_stereo
