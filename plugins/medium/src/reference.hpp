// SPDX-License-Identifier: MIT
// Test-only: an independent, brute-force evaluation of the thesis's Eq. 4.2
// and synthetic tank images made from it (never used by the plugin).
//
// Eq. 4.2 is integrated directly in z over [0, D] by composite Simpson on a
// grid graded around the bulb depth (z = B + rho sinh u, u uniform): a
// different variable, rule and code path from the plugin's Gauss–Legendre in
// the scattering angle. The H-G phase function is written out here again.
// Images: radiance at pixel centres, bulb at an integer pixel, values cached
// per integer squared distance.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <unordered_map>
#include <vector>

namespace procam::medium::reference {

struct Medium {
  double sigma, beta, g;  // 1/mm, 1/mm, H-G asymmetry
  int legendre_terms = 0; // > 0: the phase function is the truncated Legendre series of H-G instead
};

// The phase function, 1/sr: H-G, or sum_{i<N} (2i+1) g^i P_i / 4 pi (P_i by
// the three-term recurrence).
inline double phase(const Medium& m, double c) {
  if (m.legendre_terms <= 0) {
    const double q = 1 + m.g * m.g - 2 * m.g * c;
    return (1 - m.g * m.g) / (4 * std::numbers::pi * std::pow(q, 1.5));
  }
  double p0 = 1, p1 = c, sum = 1, gi = 1;
  for (int i = 1; i < m.legendre_terms; ++i) {
    gi *= m.g;
    sum += (2 * i + 1) * gi * p1;
    const double p2 = ((2 * i + 1) * c * p1 - i * p0) / (i + 1);
    p0 = p1;
    p1 = p2;
  }
  return sum / (4 * std::numbers::pi);
}

// E(rho) / I0 by Eq. 4.2, tank depth d_mm, bulb depth b_mm.
inline double eq_4_2(const Medium& m, double rho, double d_mm, double b_mm, int intervals = 4000) {
  const double u0 = std::asinh(-b_mm / rho), u1 = std::asinh((d_mm - b_mm) / rho);
  const double hu = (u1 - u0) / intervals;
  double sum = 0;
  for (int i = 0; i <= intervals; ++i) {
    const double u = u0 + hu * i;
    const double t = rho * std::sinh(u);  // z - B
    const double z = b_mm + t;
    const double dist2 = rho * rho + t * t, dist = std::sqrt(dist2);
    const double cos_scatter = -t / dist;  // pi - theta, cos theta = (z - B) / d (Eq. 4.1)
    const double f = std::exp(-m.sigma * (z + dist)) / dist2 * phase(m, cos_scatter) * rho * std::cosh(u);
    sum += f * (i == 0 || i == intervals ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0));
  }
  return m.beta * sum * hu / 3.0;
}

// E(rho) / I0 for a Lambertian sphere of radius r (radiance I0 / (pi r^2)) at
// depth b_mm instead of a point (thesis §4.3.3), by brute force over the
// sphere's surface: for each point Y on the line of sight (Simpson in
// asinh((z - B) / rho), `intervals`), every surface element q facing Y
// (n . (Y - q) > 0, an n_theta x 2 n_theta grid in the sphere's polar angle
// and azimuth, polar axis along x, towards the line of sight) contributes
// L dA cos(theta_q) / |Y - q|^2 exp(-sigma (z + |Y - q|)) P(cos), cos the
// cosine between the light's direction (Y - q) and the way to the camera
// (-z). An independent route from ProfileModel's cap rings.
inline double eq_4_2_sphere(const Medium& m, double rho, double d_mm, double b_mm, double r, int intervals = 400,
                            int n_theta = 60) {
  const double pi = std::numbers::pi, radiance = 1.0 / (pi * r * r);
  const double u0 = std::asinh(-b_mm / rho), u1 = std::asinh((d_mm - b_mm) / rho);
  const double hu = (u1 - u0) / intervals;
  const double dth = pi / n_theta, dph = pi / n_theta;  // azimuth over 2 pi in 2 n_theta steps
  double sum = 0;
  for (int i = 0; i <= intervals; ++i) {
    const double u = u0 + hu * i;
    const double t = rho * std::sinh(u), z = b_mm + t;  // Y = (rho, 0, t) from the centre
    double cap = 0;
    for (int a = 0; a < n_theta; ++a) {
      const double th = (a + 0.5) * dth, st = std::sin(th), ct = std::cos(th);
      for (int b = 0; b < 2 * n_theta; ++b) {
        const double ph = (b + 0.5) * dph;
        const double nx = ct, ny = st * std::cos(ph), nz = st * std::sin(ph);  // outward normal
        const double vx = rho - r * nx, vy = -r * ny, vz = t - r * nz;        // q -> Y
        const double l2 = vx * vx + vy * vy + vz * vz, l = std::sqrt(l2);
        const double cos_q = (nx * vx + ny * vy + nz * vz) / l;
        if (cos_q <= 0) continue;
        const double da = r * r * st * dth * dph;
        cap += radiance * da * cos_q / l2 * std::exp(-m.sigma * l) * phase(m, -vz / l);
      }
    }
    const double f = std::exp(-m.sigma * z) * cap * rho * std::cosh(u);  // dz = rho cosh(u) du
    sum += f * (i == 0 || i == intervals ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0));
  }
  return m.beta * sum * hu / 3.0;
}

struct Scene {
  uint32_t width = 200, height = 150;
  int bulb_x = 0, bulb_y = 75;
  double mm_per_px = 1.5, depth_mm = 300, bulb_depth_mm = 150, i0 = 5e4;
};

// Radiance (DN/us-like units) at every pixel; the bulb pixel itself gets the
// value at rho = 0.5 px (it is masked in fits).
inline std::vector<double> image(const Medium& m, const Scene& s) {
  std::unordered_map<int64_t, double> cache;
  std::vector<double> e(size_t{s.width} * s.height);
  for (uint32_t y = 0; y < s.height; ++y)
    for (uint32_t x = 0; x < s.width; ++x) {
      const int64_t dx = int64_t(x) - s.bulb_x, dy = int64_t(y) - s.bulb_y, r2 = dx * dx + dy * dy;
      auto it = cache.find(r2);
      if (it == cache.end()) {
        const double rho = std::max(0.5, std::sqrt(double(r2))) * s.mm_per_px;
        it = cache.emplace(r2, s.i0 * eq_4_2(m, rho, s.depth_mm, s.bulb_depth_mm)).first;
      }
      e[size_t{y} * s.width + x] = it->second;
    }
  return e;
}

// Gaussian noise of standard deviation `fraction` x the image mean outside
// `mask_px` of the bulb.
inline void add_noise(std::vector<double>& e, const Scene& s, double fraction, double mask_px, uint32_t seed) {
  double sum = 0;
  size_t n = 0;
  for (uint32_t y = 0; y < s.height; ++y)
    for (uint32_t x = 0; x < s.width; ++x)
      if (std::hypot(double(x) - s.bulb_x, double(y) - s.bulb_y) >= mask_px) sum += e[size_t{y} * s.width + x], ++n;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, fraction * sum / double(n));
  for (double& v : e) v += noise(rng);
}

}  // namespace procam::medium::reference
