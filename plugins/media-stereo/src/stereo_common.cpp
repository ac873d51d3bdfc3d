// SPDX-License-Identifier: MIT
#include "stereo_common.hpp"

#include "synthetic.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace procam::media_stereo {

uint32_t DepthSearch::count() const {
  if (!(z_step_mm > 0) || !(z_max_mm > z_min_mm)) return 0;
  return static_cast<uint32_t>(std::floor((z_max_mm - z_min_mm) / z_step_mm + 1e-9)) + 1;
}

std::vector<Vec3> unit_rays(const PinholeCamera& cam, std::vector<double>* lengths) {
  std::vector<Vec3> rays(size_t{cam.width} * cam.height);
  if (lengths) lengths->resize(rays.size());
  for (uint32_t y = 0; y < cam.height; ++y)
    for (uint32_t x = 0; x < cam.width; ++x) {
      const Vec3 r = cam.ray_world(x, y);
      const double len = norm(r);
      rays[size_t{y} * cam.width + x] = r / len;
      if (lengths) (*lengths)[size_t{y} * cam.width + x] = len;
    }
  return rays;
}

bool bilinear_taps(uint32_t w, uint32_t h, double u, double v, size_t idx[4], double wt[4]) {
  if (!(u >= 0 && v >= 0 && u <= w - 1.0 && v <= h - 1.0)) return false;
  const auto x0 = std::min(static_cast<uint32_t>(u), w > 1 ? w - 2 : 0u);
  const auto y0 = std::min(static_cast<uint32_t>(v), h > 1 ? h - 2 : 0u);
  const uint32_t x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
  const double fx = u - x0, fy = v - y0;
  idx[0] = size_t{y0} * w + x0;
  idx[1] = size_t{y0} * w + x1;
  idx[2] = size_t{y1} * w + x0;
  idx[3] = size_t{y1} * w + x1;
  wt[0] = (1 - fx) * (1 - fy);
  wt[1] = fx * (1 - fy);
  wt[2] = (1 - fx) * fy;
  wt[3] = fx * fy;
  return true;
}

double sample_bilinear(const std::vector<float>& img, uint32_t w, uint32_t h, double u, double v,
                       double saturation) {
  size_t idx[4];
  double wt[4];
  if (!bilinear_taps(w, h, u, v, idx, wt)) return std::numeric_limits<double>::quiet_NaN();
  double s = 0;
  for (int i = 0; i < 4; ++i) {
    const double value = img[idx[i]];
    if (value >= saturation) return std::numeric_limits<double>::quiet_NaN();
    s += wt[i] * value;
  }
  return s;
}

void box_sum(std::vector<float>& vol, uint32_t w, uint32_t h, uint32_t slices, int r) {
  // Prefix sums of the finite values and of the NaN count (a NaN in a plain
  // prefix sum would poison every later window of the line).
  std::vector<double> line(std::max(w, h) + 1);
  std::vector<uint32_t> bad(std::max(w, h) + 1);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  auto pass = [&](float* base, uint32_t n, size_t stride) {
    line[0] = 0;
    bad[0] = 0;
    for (uint32_t i = 0; i < n; ++i) {
      const float v = base[i * stride];
      const bool finite = std::isfinite(v);
      line[i + 1] = line[i] + (finite ? static_cast<double>(v) : 0.0);
      bad[i + 1] = bad[i] + (finite ? 0u : 1u);
    }
    for (uint32_t i = 0; i < n; ++i) {
      const auto a = static_cast<size_t>(std::max(0, static_cast<int>(i) - r));
      const auto b = static_cast<size_t>(std::min(static_cast<int>(n) - 1, static_cast<int>(i) + r)) + 1;
      base[i * stride] = bad[b] != bad[a] ? nan : static_cast<float>(line[b] - line[a]);
    }
  };
  for (uint32_t s = 0; s < slices; ++s) {
    float* sl = &vol[size_t{s} * w * h];
    for (uint32_t y = 0; y < h; ++y) pass(sl + size_t{y} * w, w, 1);
    for (uint32_t x = 0; x < w; ++x) pass(sl + x, h, w);
  }
}

double refined_argmin(const float* cost, size_t stride, uint32_t count) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  uint32_t best = count;
  for (uint32_t k = 0; k < count; ++k) {
    const float c = cost[k * stride];
    if (std::isfinite(c) && (best == count || c < cost[best * stride])) best = k;
  }
  if (best == count || best == 0 || best + 1 == count) return nan;
  const double c0 = cost[(best - 1) * stride], c1 = cost[best * stride], c2 = cost[(best + 1) * stride];
  if (!std::isfinite(c0) || !std::isfinite(c2)) return best;
  const double den = c0 - 2 * c1 + c2;
  const double off = den > 0 ? 0.5 * (c0 - c2) / den : 0.0;
  return best + std::clamp(off, -0.5, 0.5);
}

void symmetric_eigen3(const double in[3][3], double ev[3], Vec3 vec[3]) {
  double a[3][3], v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a[i][j] = in[i][j];
  for (int sweep = 0; sweep < 50; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    const double diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
    if (off <= 1e-30 * diag || off == 0.0) break;
    for (int p = 0; p < 2; ++p)
      for (int q = p + 1; q < 3; ++q) {
        if (a[p][q] == 0.0) continue;
        const double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        const double t = (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1));
        const double c = 1 / std::sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 3; ++k) {  // A <- A J
          const double akp = a[k][p], akq = a[k][q];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < 3; ++k) {  // A <- J^T A
          const double apk = a[p][k], aqk = a[q][k];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (int k = 0; k < 3; ++k) {  // V <- V J
          const double vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
  }
  int order[3] = {0, 1, 2};
  std::sort(order, order + 3, [&](int i, int j) { return a[i][i] < a[j][j]; });
  for (int i = 0; i < 3; ++i) {
    ev[i] = a[order[i]][order[i]];
    vec[i] = normalized(Vec3{v[0][order[i]], v[1][order[i]], v[2][order[i]]});
  }
}

}  // namespace procam::media_stereo
