// SPDX-License-Identifier: MIT
// Monte Carlo reference of the tank rig with multiple scattering (tank.hpp).
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "medium.hpp"
#include "parallel.hpp"
#include "tank.hpp"

namespace procam::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kForcedRoulette = 0.05;  // Russian roulette below this weight in forced mode

// Distance along unit w from p (inside the box) to its boundary.
double box_exit(const Medium& m, const Vec3& p, const Vec3& w) {
  double t = kInf;
  const double pc[3] = {p.x, p.y, p.z}, wc[3] = {w.x, w.y, w.z};
  const double lo[3] = {m.box_min_mm.x, m.box_min_mm.y, m.box_min_mm.z};
  const double hi[3] = {m.box_max_mm.x, m.box_max_mm.y, m.box_max_mm.z};
  for (int k = 0; k < 3; ++k) {
    if (wc[k] > 0) t = std::min(t, (hi[k] - pc[k]) / wc[k]);
    else if (wc[k] < 0) t = std::min(t, (lo[k] - pc[k]) / wc[k]);
  }
  return std::max(0.0, t);
}

// First hit of the ray p + s·w (s > 0) with the bulb; +inf if none.
double bulb_hit(const Medium::Bulb& b, const Vec3& p, const Vec3& w) {
  const Vec3 oc = p - b.center_mm;
  const double half_b = dot(oc, w), c = dot(oc, oc) - b.radius_mm * b.radius_mm;
  const double disc = half_b * half_b - c;
  if (disc < 0) return kInf;
  const double s = -half_b - std::sqrt(disc);
  return s > 0 ? s : kInf;
}

// The bulb connection from y, light then scattered into −w: the mean of
// L e^{−σl} p(g, u·w) Ω over k × k directions u, one drawn uniformly in each
// stratum of (cos θ, φ) of the bulb's cone (k = 1: one uniform direction).
double connect_bulb(const Medium& m, const Vec3& y, const Vec3& w, int k, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const Medium::Bulb& b = *m.bulb;
  const Vec3 dv = b.center_mm - y;
  const double d = norm(dv), r = b.radius_mm;
  if (!(d > r)) return 0;
  const double cos_max = std::sqrt(1 - (r / d) * (r / d));
  const double omega = 2 * kPi * (1 - cos_max);
  const Vec3 a = dv * (1.0 / d);
  const Vec3 helper = std::abs(a.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  const Vec3 e1 = normalized(cross(a, helper)), e2 = cross(a, e1);
  double sum = 0;
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j) {
      const double ct = 1 - (i + u01(rng)) / k * (1 - cos_max), st = std::sqrt(std::max(0.0, 1 - ct * ct));
      const double phi = 2 * kPi * (j + u01(rng)) / k;
      const Vec3 u = a * ct + (e1 * std::cos(phi) + e2 * std::sin(phi)) * st;
      const double l = d * ct - std::sqrt(std::max(0.0, r * r - d * d * st * st));
      // Light travels along −u, leaves along −w: cos of the scattering angle = u·w.
      sum += std::exp(-m.sigma_t_per_mm * l) * hg_phase(m.g, dot(u, w));
    }
  return b.radiance() * omega * sum / (k * k);
}

// Seed of path k for common random numbers (splitmix64 of seed and k).
uint64_t path_seed(uint64_t seed, uint64_t k) {
  uint64_t z = seed + 0x9E3779B97F4A7C15ull * (k + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace

TankMonteCarlo tank_monte_carlo(const Medium& m, double x_mm, double y_mm, size_t paths, uint64_t seed,
                                int max_vertices) {
  return tank_monte_carlo(m, x_mm, y_mm, paths, seed, max_vertices, TankMcOptions{});
}

TankMonteCarlo tank_monte_carlo(const Medium& m, double x_mm, double y_mm, size_t paths, uint64_t seed,
                                int max_vertices, const TankMcOptions& opt) {
  TankMonteCarlo out;
  const int splits = std::max(1, opt.connections);
  if (!m.bulb || m.whole_scene || paths == 0 || !(m.sigma_s_per_mm > 0) || max_vertices < 1) return out;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double albedo = m.sigma_s_per_mm / m.sigma_t_per_mm;
  // The medium the paths are drawn in (importance sampling when it is not m).
  const bool reweight = opt.sampling_sigma_t_per_mm > 0;
  if (reweight && !(std::abs(opt.sampling_g) < 1)) return out;
  const double sigma = reweight ? opt.sampling_sigma_t_per_mm : m.sigma_t_per_mm;
  const double g_draw = reweight ? opt.sampling_g : m.g;
  double s1 = 0, s1q = 0, st = 0, stq = 0, sxq = 0, sx = 0;
  for (size_t k = 0; k < paths; ++k) {
    if (opt.common_random_numbers) rng.seed(path_seed(seed, k));
    Vec3 p{x_mm, y_mm, m.box_min_mm.z};
    Vec3 w{0, 0, 1};
    double weight = 1, first = 0, all = 0;
    for (int v = 1; v <= max_vertices; ++v) {
      const double exit = std::min(box_exit(m, p, w), bulb_hit(*m.bulb, p, w));  // black wall or the bulb
      double s = 0;
      if (opt.forced) {
        // Collide before the exit: pdf σe^{−σs} / (1 − e^{−σ exit}) on [0, exit).
        const double hit = -std::expm1(-sigma * exit);
        if (!(hit > 0)) break;
        s = std::min(-std::log1p(-u01(rng) * hit) / sigma, std::nextafter(exit, 0.0));
        weight *= hit;
      } else {
        s = -std::log(1 - u01(rng)) / sigma;
        if (s >= exit) break;
      }
      p = p + w * s;
      // e^{−σs}·β / (σe^{−σs}); drawn with σ_ref: × e^{−(σ−σ_ref)s} σ / σ_ref.
      weight *= reweight ? albedo * m.sigma_t_per_mm / sigma * std::exp(-(m.sigma_t_per_mm - sigma) * s) : albedo;
      const double c = weight * connect_bulb(m, p, w, splits, rng);
      if (v == 1) first = c;
      all += c;
      const Vec3 w_next = detail::sample_hg(w, g_draw, rng);
      if (reweight) {
        const double cos_turn = std::clamp(dot(w, w_next), -1.0, 1.0);
        weight *= hg_phase(m.g, cos_turn) / hg_phase(g_draw, cos_turn);
      }
      w = w_next;
      // Common random numbers: the roulette's number is drawn at every
      // vertex, used or not, so a path's later draws do not depend on the medium.
      const double roulette = opt.common_random_numbers ? u01(rng) : -1.0;
      auto draw = [&] { return roulette >= 0 ? roulette : u01(rng); };
      if (opt.forced && weight < kForcedRoulette) {
        // Forced paths never leave by themselves: roulette early, survive
        // with weight / kForcedRoulette and carry kForcedRoulette (unbiased).
        if (draw() * kForcedRoulette > weight) break;
        weight = kForcedRoulette;
      } else if (weight < 1e-4) {  // Russian roulette: survive with 1/10, weight ×10 (unbiased)
        if (draw() > 0.1) break;
        weight *= 10;
      }
    }
    s1 += first;
    s1q += first * first;
    st += all;
    stq += all * all;
    sx += all - first;
    sxq += (all - first) * (all - first);
  }
  const double n = static_cast<double>(paths);
  auto se = [n](double sum, double sq) { return n > 1 ? std::sqrt(std::max(0.0, sq / n - (sum / n) * (sum / n)) / (n - 1)) : 0.0; };
  out.single = s1 / n;
  out.single_se = se(s1, s1q);
  out.total = st / n;
  out.total_se = se(st, stq);
  out.excess_se = se(sx, sxq);
  if (opt.exact_single) {
    const double rho = std::hypot(x_mm - m.bulb->center_mm.x, y_mm - m.bulb->center_mm.y);
    const double exact = tank_profile(m, rho, 768).scatter;
    out.total = exact + (out.total - out.single);
    out.total_se = out.excess_se;
    out.single = exact;
    out.single_se = 0;
  }
  return out;
}

TankEnergy tank_energy_monte_carlo(const Medium& m, int nx, int ny, size_t paths_per_point, uint64_t seed,
                                   int threads) {
  TankEnergy out;
  if (!m.bulb || m.whole_scene || nx < 1 || ny < 1) return out;
  const Medium::Bulb& b = *m.bulb;
  std::vector<TankMonteCarlo> cells(static_cast<size_t>(nx) * static_cast<size_t>(ny));
  std::vector<uint8_t> used(cells.size(), 0);
  detail::parallel_rows(static_cast<uint32_t>(ny), threads, [&](uint32_t lo, uint32_t hi) {
    for (uint32_t j = lo; j < hi; ++j)
      for (int i = 0; i < nx; ++i) {
        const double x = m.box_min_mm.x + (i + 0.5) * (m.box_max_mm.x - m.box_min_mm.x) / nx;
        const double y = m.box_min_mm.y + (j + 0.5) * (m.box_max_mm.y - m.box_min_mm.y) / ny;
        if (std::hypot(x - b.center_mm.x, y - b.center_mm.y) < b.radius_mm + 2.0) continue;
        const size_t c = size_t{j} * static_cast<size_t>(nx) + static_cast<size_t>(i);
        cells[c] = tank_monte_carlo(m, x, y, paths_per_point, seed + 7919 * c, 1 << 20);
        used[c] = 1;
      }
  });
  double single = 0, total = 0, var_excess = 0, var_total = 0, sq_diff = 0, sq_total = 0;
  size_t count = 0;
  for (size_t c = 0; c < cells.size(); ++c) {
    if (!used[c]) continue;
    const TankMonteCarlo& k = cells[c];
    single += k.single;
    total += k.total;
    var_excess += k.excess_se * k.excess_se;
    var_total += k.total_se * k.total_se;
    // E[(X̂)²] = X² + se²: subtract the Monte Carlo variance from the squares.
    sq_diff += (k.total - k.single) * (k.total - k.single) - k.excess_se * k.excess_se;
    sq_total += k.total * k.total - k.total_se * k.total_se;
    ++count;
  }
  if (count == 0 || !(total > 0)) return out;
  out.single = single / static_cast<double>(count);
  out.total = total / static_cast<double>(count);
  const double excess = total - single;
  out.relative_excess = excess / total;
  // First-order error of the ratio (numerator and denominator correlated:
  // conservative to add the terms).
  out.relative_excess_se =
      std::sqrt(var_excess / (total * total) + excess * excess * var_total / (total * total * total * total));
  out.relative_rms = sq_total > 0 ? std::sqrt(std::max(0.0, sq_diff) / sq_total) : 0.0;
  return out;
}

}  // namespace procam::sim
