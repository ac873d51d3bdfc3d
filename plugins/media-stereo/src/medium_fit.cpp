// SPDX-License-Identifier: MIT
#include "medium_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace procam::media_stereo {

namespace {

struct Samples {
  std::vector<Vec3> dir;
  std::vector<double> t_end, value;
  const LightCone* cone = nullptr;
};

// Residual of the best β for (σ, g); writes β.
double residual(const Samples& s, const Vec3& cam, const Vec3& light, double i0, double sigma, double g,
                double& beta) {
  const MediumParams unit{sigma, 1.0, g};
  double ff = 0, fi = 0, ii = 0;
  for (size_t k = 0; k < s.dir.size(); ++k) {
    const double f = backscatter(unit, i0, cam, s.dir[k], light, s.t_end[k], 16.0, s.cone);
    ff += f * f;
    fi += f * s.value[k];
    ii += s.value[k] * s.value[k];
  }
  beta = ff > 0 ? std::max(0.0, fi / ff) : 0.0;
  return ii - 2 * beta * fi + beta * beta * ff;
}

}  // namespace

MediumFit fit_medium(const PinholeCamera& cam, const std::vector<float>& image, const Vec3& light,
                     double light_intensity, double wall_z_mm, uint32_t stride, double saturation,
                     const LightCone* cone) {
  MediumFit out;
  Samples s;
  s.cone = cone;
  stride = std::max(stride, 1u);
  for (uint32_t y = stride / 2; y < cam.height; y += stride)
    for (uint32_t x = stride / 2; x < cam.width; x += stride) {
      const double v = image[size_t{y} * cam.width + x];
      if (!std::isfinite(v) || v >= saturation) continue;
      const Vec3 r = cam.ray_world(x, y);
      const double len = norm(r);
      s.dir.push_back(r / len);
      s.t_end.push_back(wall_z_mm * len);
      s.value.push_back(v);
    }
  if (s.dir.size() < 3) return out;
  const Vec3 c = cam.centre();
  // Grid over log σ in [1e-4, 3e-2] mm⁻¹ and g in [-0.5, 0.95].
  double best = 1e300, bl = 0, bg = 0, beta = 0;
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 21; ++j) {
      const double ls = std::log(1e-4) + (std::log(3e-2) - std::log(1e-4)) * i / 15.0;
      const double g = -0.5 + 1.45 * j / 20.0;
      const double r = residual(s, c, light, light_intensity, std::exp(ls), g, beta);
      if (r < best) best = r, bl = ls, bg = g;
    }
  // Nelder-Mead on (log σ, g), g clamped to (-0.99, 0.99).
  auto f = [&](const std::array<double, 2>& q) {
    double b = 0;
    return residual(s, c, light, light_intensity, std::exp(q[0]), std::clamp(q[1], -0.99, 0.99), b);
  };
  // Restarted twice from its own best point with a fresh simplex (the
  // residual has a long curved valley in (log σ, g) where one run stalls).
  std::array<std::array<double, 2>, 3> x{};
  std::array<double, 3> fx{};
  for (int start = 0; start < 3; ++start) {
  const double step = start == 0 ? 1.0 : 0.3;
  x = {{{bl, bg}, {bl + 0.25 * step, bg}, {bl, bg + 0.06 * step}}};
  fx = {f(x[0]), f(x[1]), f(x[2])};
  for (int it = 0; it < 200; ++it) {
    std::array<size_t, 3> o = {0, 1, 2};
    std::sort(o.begin(), o.end(), [&](size_t a, size_t b) { return fx[a] < fx[b]; });
    const auto xb = x[o[0]], xm = x[o[1]], xw = x[o[2]];
    const double fb = fx[o[0]], fm = fx[o[1]], fw = fx[o[2]];
    if (std::abs(fw - fb) <= 1e-12 * (std::abs(fb) + 1e-300)) break;
    const std::array<double, 2> cen = {(xb[0] + xm[0]) / 2, (xb[1] + xm[1]) / 2};
    auto lerp = [&](double t) { return std::array<double, 2>{cen[0] + t * (xw[0] - cen[0]), cen[1] + t * (xw[1] - cen[1])}; };
    const auto xr = lerp(-1.0);
    const double fr = f(xr);
    std::array<double, 2> xn;
    double fn;
    if (fr < fb) {
      const auto xe = lerp(-2.0);
      const double fe = f(xe);
      xn = fe < fr ? xe : xr;
      fn = std::min(fe, fr);
    } else if (fr < fm) {
      xn = xr, fn = fr;
    } else {
      xn = lerp(0.5);
      fn = f(xn);
      if (fn >= fw) {  // shrink towards the best
        x = {xb, std::array<double, 2>{(xb[0] + xm[0]) / 2, (xb[1] + xm[1]) / 2},
             std::array<double, 2>{(xb[0] + xw[0]) / 2, (xb[1] + xw[1]) / 2}};
        fx = {fb, f(x[1]), f(x[2])};
        continue;
      }
    }
    x[o[2]] = xn;
    fx[o[2]] = fn;
  }
  const auto im = static_cast<size_t>(std::min_element(fx.begin(), fx.end()) - fx.begin());
  bl = x[im][0];
  bg = x[im][1];
  }
  const auto ib = static_cast<size_t>(std::min_element(fx.begin(), fx.end()) - fx.begin());
  out.medium.sigma_per_mm = std::exp(x[ib][0]);
  out.medium.g = std::clamp(x[ib][1], -0.99, 0.99);
  const double r = residual(s, c, light, light_intensity, out.medium.sigma_per_mm, out.medium.g, beta);
  out.medium.beta_per_mm = beta;
  out.rms_residual = std::sqrt(std::max(r, 0.0) / static_cast<double>(s.dir.size()));
  out.ok = beta > 0;
  return out;
}

}  // namespace procam::media_stereo
