// SPDX-License-Identifier: MIT
// Eq. 4.2 as a radial profile (see scatter_model.hpp).
#include "scatter_model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace procam::medium {
namespace {

constexpr double kInv4Pi = 1.0 / (4.0 * std::numbers::pi);

// 8-point Gauss–Legendre on [-1, 1].
constexpr std::array<double, 8> kGlX = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                                        -0.1834346424956498, 0.1834346424956498,  0.5255324099163290,
                                        0.7966664774136267,  0.9602898564975363};
constexpr std::array<double, 8> kGlW = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                                        0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                                        0.2223810344533745, 0.1012285362903763};
// Panel edges as fractions of [a0, a1], graded geometrically towards both
// ends (the forward H-G peak at a0; the steep path length near a1).
constexpr std::array<double, 18> kEdges = {0.0,  1e-5, 1e-4, 1e-3, 0.005, 0.02,  0.06,   0.15,    0.3,
                                           0.5,  0.7,  0.85, 0.94, 0.98,  0.995, 0.999, 0.9999, 1.0};

constexpr size_t kTable = 2049;
constexpr double kTableStep = double(kTable - 1) / std::numbers::pi;  // table entries per radian

}  // namespace

double hg_phase(double g, double cos_angle) noexcept {
  const double q = 1.0 + g * g - 2.0 * g * cos_angle;  // > 0 for |g| < 1
  return kInv4Pi * (1.0 - g * g) / (q * std::sqrt(q));
}

double legendre_phase(double g, double cos_angle, int terms) noexcept {
  // (1/4pi) sum (2i+1) g^i P_i(x), P_i by Bonnet's recurrence (thesis §4.3.3).
  double p_prev = 1.0, p = cos_angle, gi = g, sum = 1.0;
  for (int i = 1; i < terms; ++i) {
    sum += double(2 * i + 1) * gi * p;
    const double next = (double(2 * i + 1) * cos_angle * p - double(i) * p_prev) / double(i + 1);
    p_prev = p;
    p = next;
    gi *= g;
  }
  return kInv4Pi * sum;
}

namespace {

// 3-point Gauss–Legendre on [-1, 1] (the cap's rings in cos psi).
constexpr std::array<double, 3> kRingX = {-0.7745966692414834, 0.0, 0.7745966692414834};
constexpr std::array<double, 3> kRingW = {0.5555555555555556, 0.8888888888888888, 0.5555555555555556};
// Nodes whose phase may vary across the cap get it sampled (see the header).
constexpr double kForwardLobeRad = 1.2;
constexpr double kNearRadii = 4.0;

}  // namespace

ProfileModel::ProfileModel(const TankGeometry& geo, std::vector<double> rho_mm, double max_panel_rad)
    : rho_(std::move(rho_mm)) {
  const double b = geo.bulb_depth_mm, back = geo.depth_mm - geo.bulb_depth_mm, r = geo.bulb_radius_mm;
  if (!(b > 0) || !(back > 0)) throw std::invalid_argument("ProfileModel: needs 0 < bulb depth < tank depth");
  if (!(r >= 0) || !(r < b)) throw std::invalid_argument("ProfileModel: needs 0 <= bulb radius < bulb depth");
  // Every rho gets the same panels: panel p is split into sub[p] equal
  // parts, enough for max_panel_rad at the widest span a1 - a0 < pi.
  std::array<size_t, kEdges.size() - 1> sub{};
  size_t per_rho = 0;
  for (size_t p = 0; p + 1 < kEdges.size(); ++p) {
    sub[p] = max_panel_rad > 0
                 ? std::max<size_t>(1, static_cast<size_t>(std::ceil((kEdges[p + 1] - kEdges[p]) * std::numbers::pi / max_panel_rad)))
                 : 1;
    per_rho += sub[p] * kGlX.size();
  }
  nodes_.reserve(rho_.size() * per_rho);
  const double inv_area = r > 0 ? 1.0 / (std::numbers::pi * r * r) : 0.0;
  auto add_node = [&](double rho, double w, double a) {
    // z + d = B + rho tan(a/2): source -> scattering point -> front face.
    const double path = b + rho * std::tan(0.5 * a), ca = std::cos(a);
    if (r == 0) {
      nodes_.push_back({w, path, ca, a, 0.0, 0.0});
      return;
    }
    const double d = rho / std::sin(a), z = path - d;
    const double cos_alpha = d > r ? std::sqrt(1.0 - (r / d) * (r / d)) : 0.0;  // d <= r: on the bulb (masked)
    const double half = 0.5 * (1.0 - cos_alpha);                                 // GL scale on [cos alpha, 1]
    std::array<double, 3> cpsi{}, wpsi{}, len{};
    for (size_t i = 0; i < kRingX.size(); ++i) {
      cpsi[i] = cos_alpha + half * (kRingX[i] + 1.0);
      wpsi[i] = half * kRingW[i];
      const double s2 = 1.0 - cpsi[i] * cpsi[i];
      len[i] = d * cpsi[i] - std::sqrt(std::max(0.0, r * r - d * d * s2));  // to the sphere's surface
    }
    const double scale = w * d * d * inv_area;  // dz / d^2 weight -> per unit solid angle of the cap
    if (a < kForwardLobeRad || d < kNearRadii * r) {
      const double sa = std::sin(a);
      for (size_t i = 0; i < kRingX.size(); ++i) {
        const double spsi = std::sqrt(std::max(0.0, 1.0 - cpsi[i] * cpsi[i]));
        // 8 azimuth midpoints over [0, pi], each standing for its mirror image too.
        rings_.push_back({scale * wpsi[i] * 2.0 * std::numbers::pi / double(kAzimuths), z + len[i],
                          static_cast<uint32_t>(ring_cos_.size())});
        for (size_t k = 0; k < kAzimuths; ++k) {
          const double phi = (double(k) + 0.5) * std::numbers::pi / double(kAzimuths);
          const double c = std::clamp(cpsi[i] * ca + spsi * std::cos(phi) * sa, -1.0, 1.0);
          ring_cos_.push_back(c);
          ring_angle_.push_back(std::acos(c));
        }
      }
      return;
    }
    double wsum = 0, lmean = 0, l2 = 0, s2mean = 0;
    for (size_t i = 0; i < kRingX.size(); ++i) {
      wsum += wpsi[i];
      lmean += wpsi[i] * len[i];
      l2 += wpsi[i] * len[i] * len[i];
      s2mean += wpsi[i] * (1.0 - cpsi[i] * cpsi[i]);
    }
    lmean /= wsum;
    const double omega = 2.0 * std::numbers::pi * (1.0 - cos_alpha);
    // The cap's mean of the phase to second order: p + <sin^2 psi> / 4 * Lap p
    // (Lap on the sphere; evaluate()). Without it the model was 0.1 % low
    // at 90 deg for g = 0.93, 40-300 mm off a 10 mm bulb, and the fitted
    // kappa = sigma - beta of lowfat chocolate milk 170 % off (issue 14).
    nodes_.push_back({scale * omega, z + lmean, ca, a, std::max(0.0, l2 / wsum - lmean * lmean), 0.25 * s2mean / wsum});
  };
  for (const double rho : rho_) {
    if (!(rho > 0)) throw std::invalid_argument("ProfileModel: every rho must be > 0");
    const double a0 = std::atan2(rho, b), a1 = std::numbers::pi - std::atan2(rho, back);
    for (size_t p = 0; p + 1 < kEdges.size(); ++p) {
      const double plo = a0 + (a1 - a0) * kEdges[p], phi = a0 + (a1 - a0) * kEdges[p + 1];
      for (size_t q = 0; q < sub[p]; ++q) {
        const double lo = plo + (phi - plo) * double(q) / double(sub[p]);
        const double hi = plo + (phi - plo) * double(q + 1) / double(sub[p]);
        const double half = 0.5 * (hi - lo), mid = 0.5 * (hi + lo);
        for (size_t k = 0; k < kGlX.size(); ++k) add_node(rho, half * kGlW[k] / rho, mid + half * kGlX[k]);
      }
    }
    node_end_.push_back(nodes_.size());
    ring_end_.push_back(rings_.size());
  }
}

void ProfileModel::evaluate(double sigma, double g, Phase phase, int legendre_terms, std::vector<double>& out) const {
  out.assign(rho_.size(), 0.0);
  // The truncated series is tabulated once per call over the scattering
  // angle (its oscillations have period ~ 2 pi / terms = 0.06 rad at 99
  // terms; the table step is 0.0015 rad) and interpolated linearly.
  std::vector<double> table;
  if (phase == Phase::truncated_legendre) {
    table.resize(kTable);
    for (size_t j = 0; j < kTable; ++j) table[j] = legendre_phase(g, std::cos(double(j) / kTableStep), legendre_terms);
  }
  const double num = kInv4Pi * (1.0 - g * g), g2 = 1.0 + g * g, g2x = 2.0 * g, half_s2 = 0.5 * sigma * sigma;
  auto hg = [&](double c) {
    const double q = g2 - g2x * c;
    return num / (q * std::sqrt(q));
  };
  // H-G with its curvature term over a small cap: p + m2 Lap p, Lap p =
  // (1 - c^2) p'' - 2 c p' in c = cos a, = num q^-7/2 (15 g^2 (1 - c^2) - 6 g c q).
  const double g15 = 15.0 * g * g, g6 = 6.0 * g;
  auto hg_cap = [&](double c, double m2) {
    const double q = g2 - g2x * c, q32 = q * std::sqrt(q);
    return num / q32 * (1.0 + m2 * (g15 * (1.0 - c * c) - g6 * c * q) / (q * q));
  };
  auto tab = [&](double angle) {
    const double t = angle * kTableStep;
    const auto j = std::min(static_cast<size_t>(t), kTable - 2);
    const double f = t - double(j);
    return (1.0 - f) * table[j] + f * table[j + 1];
  };
  // The same for the tabulated series: Lap p = p_aa + cot(a) p_a by central
  // differences (h well below the series' 0.06 rad period at 99 terms).
  auto tab_cap = [&](double angle, double m2) {
    const double p = tab(angle);
    if (m2 == 0) return p;
    constexpr double h = 0.005;
    const double pp = tab(angle + h), pm = tab(angle - h);
    return p + m2 * ((pp - 2.0 * p + pm) / (h * h) + (pp - pm) / (2.0 * h) / std::tan(angle));
  };
  const bool is_hg = phase == Phase::henyey_greenstein;
  size_t n0 = 0, r0 = 0;
  for (size_t i = 0; i < rho_.size(); ++i) {
    double s = 0;
    for (size_t k = n0; k < node_end_[i]; ++k) {
      const Node& n = nodes_[k];
      // exp averaged over the cap's paths to second order: e^{-s l} (1 + s^2 var / 2).
      const double att = std::exp(-sigma * n.path_mm) * (1.0 + half_s2 * n.path_var);
      s += n.weight * att * (is_hg ? hg_cap(n.cos_angle, n.cap_m2) : tab_cap(n.angle, n.cap_m2));
    }
    for (size_t k = r0; k < ring_end_[i]; ++k) {
      const Ring& rg = rings_[k];
      double p = 0;
      if (is_hg) {
        for (size_t j = 0; j < kAzimuths; ++j) p += hg(ring_cos_[rg.first + j]);
      } else {
        for (size_t j = 0; j < kAzimuths; ++j) p += tab(ring_angle_[rg.first + j]);
      }
      s += rg.weight * std::exp(-sigma * rg.path_mm) * p;
    }
    n0 = node_end_[i];
    r0 = ring_end_[i];
    out[i] = s;
  }
}

}  // namespace procam::medium
