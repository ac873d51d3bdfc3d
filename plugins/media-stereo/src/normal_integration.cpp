// SPDX-License-Identifier: MIT
#include "normal_integration.hpp"

#include <cmath>
#include <limits>

namespace procam::media_stereo {

std::vector<float> integrate_normals(const PinholeCamera& cam, const std::vector<Vec3>& normal_world,
                                     const std::vector<float>& seed_depth_mm, const IntegrationOptions& opt) {
  const uint32_t w = cam.width, h = cam.height;
  const size_t n = size_t{w} * h;
  std::vector<float> out(n, std::numeric_limits<float>::quiet_NaN());
  if (normal_world.size() != n || seed_depth_mm.size() != n || !(opt.lambda > 0)) return out;
  const Mat3 cam_from_world = cam.world_from_cam.rotation.transposed();
  // Per pixel: the log-depth gradients (gu, gv) and the seed.
  std::vector<double> gu(n, 0), gv(n, 0), q0(n, 0);
  std::vector<uint8_t> ok(n, 0);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t i = size_t{y} * w + x;
      const Vec3 nw = normal_world[i];
      const double z0 = static_cast<double>(seed_depth_mm[i]);
      if (!std::isfinite(nw.x) || !std::isfinite(nw.y) || !std::isfinite(nw.z) || !(z0 > 0) || !std::isfinite(z0))
        continue;
      Vec3 nc = cam_from_world * nw;
      const Vec3 r{(x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy, 1.0};
      double nr = dot(nc, r);
      if (nr > 0) {  // orient towards the camera
        nc = -nc;
        nr = -nr;
      }
      if (!(nr < -1e-9)) continue;  // grazing: no finite gradient
      gu[i] = -nc.x / (cam.fx * nr);
      gv[i] = -nc.y / (cam.fy * nr);
      q0[i] = std::log(z0);
      ok[i] = 1;
    }
  // Edges (i, j) with j the right or lower neighbour, both valid and not too steep.
  auto edge_ok = [&](size_t i, size_t j, const std::vector<double>& g) {
    return ok[i] && ok[j] && std::abs(g[i]) <= opt.max_log_slope && std::abs(g[j]) <= opt.max_log_slope;
  };
  // Pixels no kept edge touches carry only their seed: invalid.
  std::vector<uint8_t> linked(n, 0);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t i = size_t{y} * w + x;
      if (x + 1 < w && edge_ok(i, i + 1, gu)) linked[i] = linked[i + 1] = 1;
      if (y + 1 < h && edge_ok(i, i + w, gv)) linked[i] = linked[i + w] = 1;
    }
  // A·q = b with A = L + λI (L the edge graph's Laplacian), b = div-like term + λ q0.
  std::vector<double> b(n, 0);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t i = size_t{y} * w + x;
      if (!ok[i]) continue;
      b[i] += opt.lambda * q0[i];
      if (x + 1 < w && edge_ok(i, i + 1, gu)) {
        const double d = 0.5 * (gu[i] + gu[i + 1]);  // q_{i+1} − q_i ≈ d
        b[i] -= d;
        b[i + 1] += d;
      }
      if (y + 1 < h && edge_ok(i, i + w, gv)) {
        const double d = 0.5 * (gv[i] + gv[i + w]);
        b[i] -= d;
        b[i + w] += d;
      }
    }
  auto apply = [&](const std::vector<double>& v, std::vector<double>& av) {
    for (size_t i = 0; i < n; ++i) av[i] = ok[i] ? opt.lambda * v[i] : 0.0;
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) {
        const size_t i = size_t{y} * w + x;
        if (x + 1 < w && edge_ok(i, i + 1, gu)) {
          const double d = v[i] - v[i + 1];
          av[i] += d;
          av[i + 1] -= d;
        }
        if (y + 1 < h && edge_ok(i, i + w, gv)) {
          const double d = v[i] - v[i + w];
          av[i] += d;
          av[i + w] -= d;
        }
      }
  };
  // Conjugate gradient from the seed.
  std::vector<double> q = q0, r(n), p(n), ap(n);
  apply(q, ap);
  double bb = 0, rr = 0;
  for (size_t i = 0; i < n; ++i) {
    r[i] = b[i] - ap[i];
    p[i] = r[i];
    rr += r[i] * r[i];
    bb += b[i] * b[i];
  }
  const double stop = opt.tolerance * opt.tolerance * bb;
  for (int it = 0; it < opt.max_iterations && rr > stop; ++it) {
    apply(p, ap);
    double pap = 0;
    for (size_t i = 0; i < n; ++i) pap += p[i] * ap[i];
    if (!(pap > 0)) break;
    const double alpha = rr / pap;
    double rr_new = 0;
    for (size_t i = 0; i < n; ++i) {
      q[i] += alpha * p[i];
      r[i] -= alpha * ap[i];
      rr_new += r[i] * r[i];
    }
    const double beta = rr_new / rr;
    rr = rr_new;
    for (size_t i = 0; i < n; ++i) p[i] = r[i] + beta * p[i];
  }
  for (size_t i = 0; i < n; ++i)
    if (ok[i] && linked[i]) out[i] = static_cast<float>(std::exp(q[i]));
  return out;
}

}  // namespace procam::media_stereo
