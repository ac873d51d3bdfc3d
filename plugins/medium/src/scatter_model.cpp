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

ProfileModel::ProfileModel(const TankGeometry& geo, std::vector<double> rho_mm, double max_panel_rad)
    : rho_(std::move(rho_mm)) {
  const double b = geo.bulb_depth_mm, back = geo.depth_mm - geo.bulb_depth_mm;
  if (!(b > 0) || !(back > 0)) throw std::invalid_argument("ProfileModel: needs 0 < bulb depth < tank depth");
  // Every rho gets the same node count: panel p is split into sub[p] equal
  // parts, enough for max_panel_rad at the widest span a1 - a0 < pi.
  std::array<size_t, kEdges.size() - 1> sub{};
  nodes_per_rho_ = 0;
  for (size_t p = 0; p + 1 < kEdges.size(); ++p) {
    sub[p] = max_panel_rad > 0
                 ? std::max<size_t>(1, static_cast<size_t>(std::ceil((kEdges[p + 1] - kEdges[p]) * std::numbers::pi / max_panel_rad)))
                 : 1;
    nodes_per_rho_ += sub[p] * kGlX.size();
  }
  nodes_.reserve(rho_.size() * nodes_per_rho_);
  for (const double rho : rho_) {
    if (!(rho > 0)) throw std::invalid_argument("ProfileModel: every rho must be > 0");
    const double a0 = std::atan2(rho, b), a1 = std::numbers::pi - std::atan2(rho, back);
    for (size_t p = 0; p + 1 < kEdges.size(); ++p) {
      const double plo = a0 + (a1 - a0) * kEdges[p], phi = a0 + (a1 - a0) * kEdges[p + 1];
      for (size_t q = 0; q < sub[p]; ++q) {
        const double lo = plo + (phi - plo) * double(q) / double(sub[p]);
        const double hi = plo + (phi - plo) * double(q + 1) / double(sub[p]);
        const double half = 0.5 * (hi - lo), mid = 0.5 * (hi + lo);
        for (size_t k = 0; k < kGlX.size(); ++k) {
          const double a = mid + half * kGlX[k];
          // z + d = B + rho tan(a/2): source -> scattering point -> front face.
          nodes_.push_back({half * kGlW[k] / rho, b + rho * std::tan(0.5 * a), std::cos(a), a});
        }
      }
    }
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
  const Node* n = nodes_.data();
  for (size_t i = 0; i < rho_.size(); ++i, n += nodes_per_rho_) {
    double s = 0;
    if (phase == Phase::henyey_greenstein) {
      const double num = kInv4Pi * (1.0 - g * g), g2 = 1.0 + g * g, g2x = 2.0 * g;
      for (size_t k = 0; k < nodes_per_rho_; ++k) {
        const double q = g2 - g2x * n[k].cos_angle;
        s += n[k].weight * std::exp(-sigma * n[k].path_mm) * num / (q * std::sqrt(q));
      }
    } else {
      for (size_t k = 0; k < nodes_per_rho_; ++k) {
        const double t = n[k].angle * kTableStep;
        const auto j = std::min(static_cast<size_t>(t), kTable - 2);
        const double f = t - double(j);
        s += n[k].weight * std::exp(-sigma * n[k].path_mm) * ((1.0 - f) * table[j] + f * table[j + 1]);
      }
    }
    out[i] = s;
  }
}

}  // namespace procam::medium
