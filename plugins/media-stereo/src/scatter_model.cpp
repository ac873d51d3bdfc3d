// SPDX-License-Identifier: MIT
#include "scatter_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace procam::media_stereo {

double hg_phase(double g, double cos_theta) {
  const double g2 = g * g;
  const double den = std::max(1.0 + g2 - 2.0 * g * cos_theta, 1e-300);
  return (1.0 - g2) / (4.0 * std::numbers::pi * den * std::sqrt(den));
}

double backscatter_integrand(const MediumParams& m, double light_intensity, const Vec3& cam, const Vec3& dir,
                             const Vec3& light, double x) {
  const Vec3 y = cam + dir * x;
  const Vec3 ly = y - light;  // light's propagation direction (unnormalised)
  const double a2 = dot(ly, ly);
  if (a2 <= 1e-18) return 0.0;
  const double a = std::sqrt(a2);
  // Scattered light travels y -> cam, i.e. along -dir: cos γ = (ly/a)·(-dir).
  const double cos_gamma = -dot(ly, dir) / a;
  return m.beta_per_mm * hg_phase(m.g, cos_gamma) * light_intensity * std::exp(-m.sigma_per_mm * (a + x)) / a2;
}

namespace {
// 3-point Gauss-Legendre on [x0, x1] (exact for polynomials of degree 5).
double gl3(const MediumParams& m, double i0, const Vec3& cam, const Vec3& dir, const Vec3& light, double x0,
           double x1) {
  static constexpr double kNode = 0.7745966692414834;  // sqrt(3/5)
  const double c = 0.5 * (x0 + x1), h = 0.5 * (x1 - x0);
  return h * (5.0 / 9.0 * backscatter_integrand(m, i0, cam, dir, light, c - h * kNode) +
              8.0 / 9.0 * backscatter_integrand(m, i0, cam, dir, light, c) +
              5.0 / 9.0 * backscatter_integrand(m, i0, cam, dir, light, c + h * kNode));
}
// Keep the s of [t0, t1] where c0 + c1·s >= 0.
void clip_halfspace(double c0, double c1, double& t0, double& t1) {
  if (c1 == 0) {
    if (c0 < 0) t1 = t0 - 1;
  } else if (c1 > 0) {
    t0 = std::max(t0, -c0 / c1);
  } else {
    t1 = std::min(t1, -c0 / c1);
  }
}

// gl3 over [x0, x1] ∩ [c0, c1] (the cone's interval).
double gl3_clipped(const MediumParams& m, double i0, const Vec3& cam, const Vec3& dir, const Vec3& light, double x0,
                   double x1, double c0, double c1) {
  const double a = std::max(x0, c0), b = std::min(x1, c1);
  return b > a ? gl3(m, i0, cam, dir, light, a, b) : 0.0;
}
}  // namespace

bool cone_interval(const LightCone& c, const Vec3& cam, const Vec3& dir, double& t0, double& t1) {
  t0 = 0;
  t1 = std::numeric_limits<double>::infinity();
  // The point in the light's frame is p0 + p1·s; "projects inside the image"
  // is linear in s after multiplying by its z (> 0).
  const Vec3 p0 = c.light_from_world * cam, p1 = c.light_from_world.rotation * dir;
  const double ax = c.fx * p0.x + c.cx * p0.z, bx = c.fx * p1.x + c.cx * p1.z;
  const double ay = c.fy * p0.y + c.cy * p0.z, by = c.fy * p1.y + c.cy * p1.z;
  const double xmax = c.width - 0.5, ymax = c.height - 0.5;
  clip_halfspace(p0.z - 1e-6, p1.z, t0, t1);
  clip_halfspace(ax + 0.5 * p0.z, bx + 0.5 * p1.z, t0, t1);
  clip_halfspace(xmax * p0.z - ax, xmax * p1.z - bx, t0, t1);
  clip_halfspace(ay + 0.5 * p0.z, by + 0.5 * p1.z, t0, t1);
  clip_halfspace(ymax * p0.z - ay, ymax * p1.z - by, t0, t1);
  return t1 > t0;
}

double backscatter(const MediumParams& m, double light_intensity, const Vec3& cam, const Vec3& dir,
                   const Vec3& light, double t, double segment_mm, const LightCone* cone) {
  if (!(t > 0) || m.beta_per_mm == 0.0) return 0.0;
  double c0 = 0, c1 = t;
  if (cone != nullptr && !cone_interval(*cone, cam, dir, c0, c1)) return 0.0;
  c1 = std::min(c1, t);
  if (!(c1 > c0)) return 0.0;
  // Segments over the lit stretch only, so the cone's edges are segment ends.
  const double len = c1 - c0;
  const int n = std::max(1, static_cast<int>(std::ceil(len / std::max(segment_mm, 1e-3))));
  double sum = 0;
  for (int k = 0; k < n; ++k)
    sum += gl3(m, light_intensity, cam, dir, light, c0 + len * k / n, c0 + len * (k + 1) / n);
  return sum;
}

double BackscatterTable::at(size_t ray, double t) const {
  if (!(t >= 0) || samples < 2) return std::numeric_limits<double>::quiet_NaN();
  const double s = t / step_mm;
  const auto k = static_cast<size_t>(s);
  if (k + 1 >= samples) {
    if (k + 1 == samples && s == static_cast<double>(k)) return static_cast<double>(b[ray * samples + k]);
    return std::numeric_limits<double>::quiet_NaN();
  }
  const double f = s - static_cast<double>(k);
  const float* r = &b[ray * samples];
  return (1.0 - f) * static_cast<double>(r[k]) + f * static_cast<double>(r[k + 1]);
}

BackscatterTable backscatter_table(const MediumParams& m, double light_intensity, const Vec3& cam,
                                   const std::vector<Vec3>& rays, const Vec3& light, double max_mm, double step_mm,
                                   const LightCone* cone) {
  BackscatterTable t;
  t.step_mm = step_mm;
  t.samples = static_cast<uint32_t>(std::ceil(max_mm / step_mm)) + 1;
  t.b.assign(rays.size() * t.samples, 0.0f);
  if (m.beta_per_mm == 0.0) return t;
  for (size_t r = 0; r < rays.size(); ++r) {
    double acc = 0, c0 = 0, c1 = std::numeric_limits<double>::infinity();
    if (cone != nullptr && !cone_interval(*cone, cam, rays[r], c0, c1)) continue;  // never lit: B = 0
    float* out = &t.b[r * t.samples];
    for (uint32_t k = 1; k < t.samples; ++k) {
      acc += gl3_clipped(m, light_intensity, cam, rays[r], light, (k - 1) * step_mm, k * step_mm, c0, c1);
      out[k] = static_cast<float>(acc);
    }
  }
  return t;
}

}  // namespace procam::media_stereo
