// SPDX-License-Identifier: MIT
// Slow Monte Carlo reference for a medium's backscatter with multiple
// scattering (tests only; see medium.hpp backscatter_monte_carlo).
//
// Backward path tracing from the camera pixel centre: free flights sampled
// with pdf σ e^{−σs} inside the medium (a flight that reaches a surface or
// leaves the medium ends the path: surface light is not part of B), at each
// scattering vertex the path weight is multiplied by the single-scattering
// albedo β/σ and the projector is connected (next-event estimation:
// p(θ) I e(x_p) / d² · exp(−σ ℓ_L), shadow-tested), then the next direction is
// drawn from the Henyey-Greenstein phase function. The first vertex's
// connection alone estimates the single-scattering B of Eq. 5.13.
#include <algorithm>
#include <cmath>
#include <random>

#include "medium.hpp"
#include "procam/hw/sim/raycast.hpp"

namespace procam::sim {
namespace {
// A deflection below 30° counts as "small" (BackscatterOrders::multiple_small_turns).
const double kKeepCos = std::cos(30.0 * M_PI / 180.0);
}  // namespace

namespace detail {

Vec3 sample_hg(const Vec3& w, double g, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double xi = u01(rng), phi = 2 * M_PI * u01(rng);
  double c;
  if (std::abs(g) < 1e-6) {
    c = 1 - 2 * xi;
  } else {
    const double s = (1 - g * g) / (1 - g + 2 * g * xi);
    c = (1 + g * g - s * s) / (2 * g);
  }
  c = std::clamp(c, -1.0, 1.0);
  const double sn = std::sqrt(std::max(0.0, 1 - c * c));
  const Vec3 a = std::abs(w.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  const Vec3 t = normalized(cross(w, a)), b = cross(w, t);
  return normalized(w * c + t * (sn * std::cos(phi)) + b * (sn * std::sin(phi)));
}

}  // namespace detail

BackscatterOrders backscatter_monte_carlo_orders(const Scene& scene, const ProjectorModel& projector,
                                                const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                                                const Intrinsics& camera, double col, double row,
                                                const std::vector<float>& emitted, size_t paths, uint64_t seed,
                                                int max_vertices) {
  BackscatterOrders out;
  if (!scene.medium || paths == 0 || !(scene.medium->sigma_s_per_mm > 0)) return out;
  const Medium& m = *scene.medium;
  const SceneTracer tracer(scene);
  const Vec3 lc = world_from_proj.translation_mm;
  const Rigid3 proj_from_world = world_from_proj.inverse();
  const Intrinsics& K = projector.intrinsics;
  const double intensity = projector.irradiance_at_1m * 1e6, albedo = m.sigma_s_per_mm / m.sigma_t_per_mm;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  // Light from the projector arriving at y (to be scattered towards -w).
  auto connect = [&](const Vec3& y, const Vec3& w) {
    const Vec3 yp = proj_from_world * y;
    if (!(yp.z > 0)) return 0.0;
    double x = 0, yy = 0;
    K.project(yp, x, yy);
    const double ix = std::floor(x + 0.5), iy = std::floor(yy + 0.5);
    if (ix < 0 || iy < 0 || ix >= K.width || iy >= K.height) return 0.0;
    Hit h;
    if (tracer.first_hit(lc, y - lc, 1e-9, h) && h.t < 1.0 - 1e-7) return 0.0;
    const Vec3 v = y - lc;
    const double d2 = dot(v, v);
    const double cos_t = dot(v, -w) / std::sqrt(d2);  // propagation L→Y against the scattered -w
    const double e = static_cast<double>(emitted[static_cast<size_t>(iy) * K.width + static_cast<size_t>(ix)]);
    return hg_phase(m.g, cos_t) * intensity / d2 * std::exp(-m.sigma_t_per_mm * medium_length(m, lc, y)) * e;
  };
  // Per path: its first vertex's estimate and the sum of the others; the
  // means and their standard errors over the paths.
  double s1 = 0, s1q = 0, sm = 0, smq = 0, sk = 0;
  const Vec3 c0 = world_from_cam.translation_mm;
  const Vec3 w0 = normalized(world_from_cam.rotation * camera.ray(col, row));
  for (size_t p = 0; p < paths; ++p) {
    Vec3 o = c0, w = w0;
    double weight = 1, first = 0, rest = 0, keep = 0;
    bool small_turns = true;  // every sampled deflection so far below kKeepDeg
    for (int k = 0; k < max_vertices; ++k) {
      double t0 = 0, t1 = 0;
      if (!medium_interval(m, o, w, t0, t1)) break;
      Hit hit;
      if (tracer.first_hit(o, w, 1e-9, hit)) t1 = std::min(t1, hit.t);
      if (!(t1 > t0)) break;
      const double s = t0 - std::log(1 - u01(rng)) / m.sigma_t_per_mm;
      if (s >= t1) break;  // reached a surface or left the medium
      const Vec3 y = o + w * s;
      weight *= albedo;
      const double c = weight * connect(y, w);
      (k == 0 ? first : rest) += c;
      if (k > 0 && small_turns) keep += c;
      o = y;
      const Vec3 w_next = detail::sample_hg(w, m.g, rng);
      small_turns = small_turns && dot(w, w_next) > kKeepCos;
      w = w_next;
    }
    sk += keep;
    s1 += first;
    s1q += first * first;
    sm += rest;
    smq += rest * rest;
  }
  const double n = static_cast<double>(paths);
  out.single = s1 / n;
  out.multiple = sm / n;
  out.multiple_small_turns = sk / n;
  auto se = [n](double mean, double sq) { return n > 1 ? std::sqrt(std::max(0.0, sq / n - mean * mean) / (n - 1)) : 0.0; };
  out.se_single = se(out.single, s1q);
  out.se_multiple = se(out.multiple, smq);
  return out;
}

double backscatter_monte_carlo(const Scene& scene, const ProjectorModel& projector, const Rigid3& world_from_cam,
                               const Rigid3& world_from_proj, const Intrinsics& camera, double col, double row,
                               const std::vector<float>& emitted, size_t paths, uint64_t seed, int max_vertices) {
  const BackscatterOrders o = backscatter_monte_carlo_orders(scene, projector, world_from_cam, world_from_proj, camera,
                                                             col, row, emitted, paths, seed, max_vertices);
  return o.single + o.multiple;
}

}  // namespace procam::sim
