// SPDX-License-Identifier: MIT
// The sigma / g / beta fit (see fit.hpp).
#include "fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace procam::medium {
namespace {

constexpr double kLinearBinsPx = 100;  // 1-px bins below, 1 %-of-rho bins above
constexpr double kGMax = 0.999;
constexpr double kLegendrePanelRad = 0.02;  // quadrature panels for the Legendre series (scatter_model.hpp)

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

size_t bin_of(double rho_px) {
  if (rho_px < kLinearBinsPx) return static_cast<size_t>(rho_px);
  return static_cast<size_t>(kLinearBinsPx + kLinearBinsPx * std::log(rho_px / kLinearBinsPx));
}

// The objective of Eq. 4.7 (or its profiled form) over a profile.
class Problem {
 public:
  Problem(const RadialProfile& p, const FitSettings& s) : p_(p), s_(s) {
    std::vector<double> rho;
    rho.reserve(2 * p.bins.size());
    for (const Bin& b : p.bins) {
      const double sd = b.rho_px < kLinearBinsPx ? b.rho_sd_px : 0.0;
      if (sd > 0) {  // two points: the bin mean of K to second order
        rho.push_back((b.rho_px - sd) * s.mm_per_px);
        rho.push_back((b.rho_px + sd) * s.mm_per_px);
        pair_.push_back(1);
      } else {
        rho.push_back(b.rho_mm);
        pair_.push_back(0);
      }
      emax_ = std::max(emax_, b.mean);
    }
    model_ = ProfileModel(s.tank, rho);
    rho_ = std::move(rho);
    // Per-bin weights: n (uniform) or n / var(E) (fit.hpp, Weights::noise),
    // scaled so they sum to the pixel count (the objective keeps its size).
    weight_.resize(p.bins.size());
    double sum_w = 0, sum_n = 0;
    const double read = s.noise_read > 0 ? s.noise_read : 1e-3 * emax_;
    for (size_t i = 0; i < p.bins.size(); ++i) {
      const double n = double(p.bins[i].n), e = std::max(0.0, p.bins[i].mean);
      double w = n;
      if (s.weights == Weights::noise) {
        const double var = (s.noise_relative * e) * (s.noise_relative * e) + s.noise_shot * e + read * read;
        w = var > 0 ? n / var : n;
      }
      weight_[i] = w;
      sum_w += w;
      sum_n += n;
    }
    if (sum_w > 0)
      for (double& w : weight_) w *= sum_n / sum_w;
  }
  double emax() const { return emax_; }
  // The weight of bin i in every sum of squares (n_i for uniform weights).
  double weight(size_t i) const { return weight_[i]; }

  // K at the bins into k_; returns false if the model is not usable (max <= 0).
  void unit_model(double sigma, double g, Phase ph, std::vector<double>& k) const {
    if (ph == Phase::truncated_legendre && fine_.size() == 0) fine_ = ProfileModel(s_.tank, rho_, kLegendrePanelRad);
    (ph == Phase::truncated_legendre ? fine_ : model_).evaluate(sigma, g, ph, s_.legendre_terms, raw_);
    k.resize(pair_.size());
    for (size_t i = 0, j = 0; i < pair_.size(); ++i) {
      k[i] = pair_[i] != 0 ? 0.5 * (raw_[j] + raw_[j + 1]) : raw_[j];
      j += 1u + pair_[i];
    }
  }

  // Least-squares scale s minimising sum n (E - s K)^2 (Eq. 4.4–4.5 for beta I0).
  double ls_scale(const std::vector<double>& k) const {
    double num = 0, den = 0;
    for (size_t i = 0; i < k.size(); ++i) {
      num += weight_[i] * p_.bins[i].mean * k[i];
      den += weight_[i] * k[i] * k[i];
    }
    return den > 0 ? num / den : 0.0;
  }

  double objective(double sigma, double g, Phase ph) {
    ++evaluations;
    unit_model(sigma, g, ph, k_);
    double j = 0;
    if (s_.objective == Objective::normalized) {
      // Eq. 4.6: E / max E - RHS / max RHS, summed in squares over pixels (Eq. 4.7).
      double kmax = 0;
      for (double v : k_) kmax = std::max(kmax, v);
      if (!(kmax > 0)) return 1e300;
      for (size_t i = 0; i < k_.size(); ++i) {
        const double r = p_.bins[i].mean / emax_ - k_[i] / kmax;
        j += weight_[i] * r * r;
      }
    } else {
      const double sc = ls_scale(k_);
      for (size_t i = 0; i < k_.size(); ++i) {
        const double r = (p_.bins[i].mean - sc * k_[i]) / emax_;
        j += weight_[i] * r * r;
      }
    }
    return j;
  }

  int evaluations = 0;

 private:
  const RadialProfile& p_;
  const FitSettings& s_;
  ProfileModel model_;
  mutable ProfileModel fine_;         // for the truncated Legendre series, built on first use
  std::vector<double> rho_;
  std::vector<uint8_t> pair_;         // per bin: 1 = two model points (rho -/+ sd)
  std::vector<double> weight_;        // per bin: n or n / var(E)
  mutable std::vector<double> raw_;   // model at the points (Problem is single-threaded)
  std::vector<double> k_;
  double emax_ = 0;
};

// Objective in the search coordinates (ln sigma, atanh g), with a quadratic
// wall outside the sigma range so the simplex comes back.
double search_objective(Problem& pr, const FitSettings& s, Phase ph, const std::array<double, 2>& x) {
  const double lo = std::log(s.sigma_min), hi = std::log(s.sigma_max);
  const double u = std::clamp(x[0], lo, hi);
  const double g = std::clamp(std::tanh(x[1]), -kGMax, kGMax);
  const double wall = (x[0] - u) * (x[0] - u) + (std::abs(x[1]) > std::atanh(kGMax) ? 1.0 : 0.0);
  return pr.objective(std::exp(u), g, ph) * (1.0 + wall) + wall;
}

// Nelder–Mead (reflection 1, expansion 2, contraction 1/2, shrink 1/2) in 2-D.
Minimum nelder_mead(Problem& pr, const FitSettings& s, Phase ph, std::array<double, 2> x0) {
  std::array<std::array<double, 2>, 3> x = {x0, x0, x0};
  x[1][0] += 0.3;
  x[2][1] += 0.3;
  std::array<double, 3> f{};
  for (size_t i = 0; i < 3; ++i) f[i] = search_objective(pr, s, ph, x[i]);
  const int start = pr.evaluations;
  for (int iter = 0; iter < 400; ++iter) {
    std::array<size_t, 3> o = {0, 1, 2};
    std::sort(o.begin(), o.end(), [&](size_t a, size_t b) { return f[a] < f[b]; });
    const size_t best = o[0], mid = o[1], worst = o[2];
    const double size = std::max(std::abs(x[worst][0] - x[best][0]) + std::abs(x[worst][1] - x[best][1]),
                                 std::abs(x[mid][0] - x[best][0]) + std::abs(x[mid][1] - x[best][1]));
    // Converged: simplex below 1e-6 in (ln sigma, atanh g) (a 1e-6 relative change of sigma) and flat.
    if (size < 1e-6 && f[worst] - f[best] <= 1e-10 * std::abs(f[best]) + 1e-300) break;
    const std::array<double, 2> c = {0.5 * (x[best][0] + x[mid][0]), 0.5 * (x[best][1] + x[mid][1])};
    auto along = [&](double t) {
      return std::array<double, 2>{c[0] + t * (x[worst][0] - c[0]), c[1] + t * (x[worst][1] - c[1])};
    };
    const std::array<double, 2> r = along(-1.0);
    const double fr = search_objective(pr, s, ph, r);
    if (fr < f[best]) {
      const std::array<double, 2> e = along(-2.0);
      const double fe = search_objective(pr, s, ph, e);
      if (fe < fr) x[worst] = e, f[worst] = fe;
      else x[worst] = r, f[worst] = fr;
    } else if (fr < f[mid]) {
      x[worst] = r, f[worst] = fr;
    } else {
      const bool outside = fr < f[worst];
      const std::array<double, 2> k = along(outside ? -0.5 : 0.5);
      const double fk = search_objective(pr, s, ph, k);
      if (fk < std::min(fr, f[worst])) {
        x[worst] = k, f[worst] = fk;
      } else {  // shrink towards the best
        for (size_t i : {mid, worst}) {
          x[i] = {0.5 * (x[i][0] + x[best][0]), 0.5 * (x[i][1] + x[best][1])};
          f[i] = search_objective(pr, s, ph, x[i]);
        }
      }
    }
  }
  const size_t b = static_cast<size_t>(std::min_element(f.begin(), f.end()) - f.begin());
  Minimum m;
  m.sigma = std::exp(std::clamp(x[b][0], std::log(s.sigma_min), std::log(s.sigma_max)));
  m.g = std::clamp(std::tanh(x[b][1]), -kGMax, kGMax);
  m.objective = f[b];
  m.evaluations = pr.evaluations - start + 3;
  return m;
}

// A 10 x |gs| grid (sigma log-spaced), then NM from the best `starts` nodes
// and from `extra` (if given); the best minimum.
Minimum search(Problem& pr, const FitSettings& s, Phase ph, const std::vector<double>& gs, size_t starts,
               const Minimum* extra = nullptr) {
  struct Node {
    double f;
    std::array<double, 2> x;
  };
  std::vector<Node> nodes;
  const double lo = std::log(s.sigma_min), hi = std::log(s.sigma_max);
  for (int i = 0; i < 10; ++i)
    for (double g : gs) {
      const std::array<double, 2> x = {lo + (hi - lo) * (double(i) + 0.5) / 10.0, std::atanh(g)};
      nodes.push_back({search_objective(pr, s, ph, x), x});
    }
  starts = std::min(starts, nodes.size());
  std::partial_sort(nodes.begin(), nodes.begin() + std::ptrdiff_t(starts), nodes.end(),
                    [](const Node& a, const Node& b) { return a.f < b.f; });
  Minimum best;
  for (size_t i = 0; i < starts; ++i) {
    const Minimum m = nelder_mead(pr, s, ph, nodes[i].x);
    if (!(best.objective <= m.objective)) best = m;
  }
  if (extra != nullptr) {
    const Minimum m = nelder_mead(pr, s, ph, {std::log(extra->sigma), std::atanh(extra->g)});
    if (!(best.objective <= m.objective)) best = m;
  }
  best.evaluations = pr.evaluations;
  return best;
}

// 3x3 symmetric inverse; false when singular.
bool invert3(const std::array<std::array<double, 3>, 3>& a, std::array<std::array<double, 3>, 3>& inv) {
  const double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                     a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  if (!(std::abs(det) > 0) || !std::isfinite(det)) return false;
  for (size_t i = 0; i < 3; ++i)
    for (size_t j = 0; j < 3; ++j) {
      const size_t i1 = (j + 1) % 3, i2 = (j + 2) % 3, j1 = (i + 1) % 3, j2 = (i + 2) % 3;
      inv[i][j] = (a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1]) / det;
    }
  return true;
}

using Cov3 = std::array<std::array<double, 3>, 3>;

// The covariance of (sigma, g, s = beta I0) at the optimum (fit.hpp step 5).
//
// Delta method over the data, the bins' means E_j (independent, variance
// v_j): cov = sum_j a_j a_j^T v_j, a_j = d(sigma, g, s) / dE_j, for either
// objective:
//  - profiled: least squares of E - s K(sigma, g) with weights w, so
//    a_j = (J^T W J)^-1 J_j^T w_j, J_j = (s dK_j/dsigma, s dK_j/dg, K_j).
//  - normalized (Eq. 4.6-4.7): (sigma, g) minimise
//    sum w_i (E_i / E_m - u_i)^2, u = K / max K, where E_m = max E is itself
//    one of the data (the brightest bin). The implicit-function theorem on
//    the gradient (Gauss-Newton Hessian 2M, M = sum w D D^T, D_i = du_i/d(sigma, g))
//    gives  d(sigma, g)/dE_j = M^-1 (w_j D_j - [j = m] c) / E_m,
//    c = sum_i w_i D_i E_i / E_m: the second term is the normaliser, whose
//    noise moves every normalised sample together (brief k14: leaving it out
//    made the intervals miss the truth in 4 of 5 noise seeds). s is the least
//    squares scale at (sigma, g): ds/dE_j = w_j K_j / Q + ds/d(sigma, g) .
//    d(sigma, g)/dE_j, Q = sum w K^2.
// The variance of a bin's mean is measured, not assumed: v_j = (tau_j^2 +
// x) / n_j, tau_j^2 = Bin::noise_var (the pixel variance inside the bin
// about a quadratic in rho, so the profile's own fall-off across a 1-px ring
// next to the bulb is not counted; bins without one take their neighbour's).
// No noise model, so shot, multiplicative or read noise and the HDR merge's
// quantisation all count as they are. x >= 0 is a common excess per-pixel
// variance (shaped by the weights' noise model, below), the smallest that
// brings chi^2 = sum n res^2 / (tau^2 + x) down to its bins - 3 degrees of
// freedom: 0 when that noise explains the profile's residuals, more for a
// model error or noise correlated across pixels (on a noise-free image, or a
// profile built without pixels, it is the weighted residual variance
// s^2 = sum w res^2 / (bins - 3), the estimate used before). `noise2` returns the pixel-weighted mean tau^2.
// Assumes independent pixel noise within a bin; a real rig's angular
// non-uniformity inside a ring counts as noise (wider intervals).
bool parameter_covariance(const Problem& pr, const RadialProfile& p, const FitSettings& s, Phase ph, double sigma,
                          double g, double scale, const std::vector<double>& k, Cov3& cov, double& excess, double& noise2) {
  const size_t nb = k.size();
  if (nb < 4) return false;
  const double hs = 1e-4 * sigma, hg = 1e-4 * (1.0 - std::abs(g));
  std::vector<double> kp, km, gp, gm;
  pr.unit_model(sigma + hs, g, ph, kp);
  pr.unit_model(sigma - hs, g, ph, km);
  pr.unit_model(sigma, g + hg, ph, gp);
  pr.unit_model(sigma, g - hg, ph, gm);
  std::vector<std::array<double, 2>> dk(nb);  // dK/dsigma, dK/dg
  for (size_t i = 0; i < nb; ++i) dk[i] = {(kp[i] - km[i]) / (2 * hs), (gp[i] - gm[i]) / (2 * hg)};
  std::vector<std::array<double, 3>> a(nb);
  if (s.objective == Objective::profiled) {
    Cov3 jtj{}, inv{};
    for (size_t i = 0; i < nb; ++i) {
      const std::array<double, 3> row = {scale * dk[i][0], scale * dk[i][1], k[i]};
      for (size_t u = 0; u < 3; ++u)
        for (size_t v = 0; v < 3; ++v) jtj[u][v] += pr.weight(i) * row[u] * row[v];
    }
    if (!invert3(jtj, inv)) return false;
    for (size_t i = 0; i < nb; ++i) {
      const std::array<double, 3> row = {scale * dk[i][0], scale * dk[i][1], k[i]};
      for (size_t u = 0; u < 3; ++u) a[i][u] = pr.weight(i) * (inv[u][0] * row[0] + inv[u][1] * row[1] + inv[u][2] * row[2]);
    }
  } else {
    const size_t km_i = size_t(std::max_element(k.begin(), k.end()) - k.begin());
    size_t em_i = 0;  // the normaliser's bin (Problem::emax: the largest mean)
    for (size_t i = 1; i < nb; ++i)
      if (p.bins[i].mean > p.bins[em_i].mean) em_i = i;
    const double emax = p.bins[em_i].mean;
    if (!(emax > 0) || !(kp[km_i] > 0) || !(km[km_i] > 0) || !(gp[km_i] > 0) || !(gm[km_i] > 0)) return false;
    std::vector<std::array<double, 2>> d(nb);  // du_i / d(sigma, g), u = K / K[max]
    double m00 = 0, m01 = 0, m11 = 0;
    std::array<double, 2> c = {0, 0};
    for (size_t i = 0; i < nb; ++i) {
      d[i] = {(kp[i] / kp[km_i] - km[i] / km[km_i]) / (2 * hs), (gp[i] / gp[km_i] - gm[i] / gm[km_i]) / (2 * hg)};
      const double w = pr.weight(i);
      m00 += w * d[i][0] * d[i][0];
      m01 += w * d[i][0] * d[i][1];
      m11 += w * d[i][1] * d[i][1];
      c[0] += w * d[i][0] * p.bins[i].mean / emax;
      c[1] += w * d[i][1] * p.bins[i].mean / emax;
    }
    const double det = m00 * m11 - m01 * m01;
    if (!(det > 0) || !std::isfinite(det)) return false;
    const double i00 = m11 / det, i01 = -m01 / det, i11 = m00 / det;
    double q = 0, nq = 0;
    std::array<double, 2> ek = {0, 0}, kk = {0, 0};  // sum w E dK, sum w K dK
    for (size_t i = 0; i < nb; ++i) {
      const double w = pr.weight(i);
      q += w * k[i] * k[i];
      nq += w * p.bins[i].mean * k[i];
      for (size_t u = 0; u < 2; ++u) {
        ek[u] += w * p.bins[i].mean * dk[i][u];
        kk[u] += w * k[i] * dk[i][u];
      }
    }
    if (!(q > 0)) return false;
    const std::array<double, 2> ds = {ek[0] / q - 2 * nq * kk[0] / (q * q), ek[1] / q - 2 * nq * kk[1] / (q * q)};
    for (size_t j = 0; j < nb; ++j) {
      const double w = pr.weight(j);
      std::array<double, 2> b = {w * d[j][0], w * d[j][1]};
      if (j == em_i) b[0] -= c[0], b[1] -= c[1];
      const double t0 = (i00 * b[0] + i01 * b[1]) / emax, t1 = (i01 * b[0] + i11 * b[1]) / emax;
      a[j] = {t0, t1, w * k[j] / q + ds[0] * t0 + ds[1] * t1};
    }
  }
  // Each bin's pixel variance, measured (Bin::noise_var).
  std::vector<double> tau2(nb, kNaN);
  bool any = false;
  for (size_t i = 0; i < nb; ++i)
    if (p.bins[i].noise_var >= 0) tau2[i] = p.bins[i].noise_var, any = true;
  if (!any) tau2.assign(nb, 0.0);  // a profile without pixels (bins built by hand): the residuals decide
  double last = kNaN;  // bins too small for their own estimate: the nearest one before (or after)
  for (size_t i = 0; i < nb; ++i) std::isnan(tau2[i]) ? void(tau2[i] = last) : void(last = tau2[i]);
  last = kNaN;
  for (size_t i = nb; i-- > 0;) std::isnan(tau2[i]) ? void(tau2[i] = last) : void(last = tau2[i]);
  double sum_n = 0;
  noise2 = 0;
  for (size_t i = 0; i < nb; ++i) noise2 += double(p.bins[i].n) * tau2[i], sum_n += double(p.bins[i].n);
  noise2 /= sum_n;
  // Excess per-pixel variance x >= 0 that brings chi^2 = sum n res^2 /
  // (tau^2 + x) to its degrees of freedom (bins - 3); 0 when the measured
  // noise explains the residuals. (With tau^2 = 0, a noise-free image, x is
  // the residuals' own per-pixel variance s^2 = sum n res^2 / (bins - 3).)
  // The excess is shaped like the objective's own noise model: per pixel
  // x n_j / w_j (x for uniform weights, w = n; the stated model's relative
  // variance for noise weights), so that with tau^2 = 0 the covariance is
  // exactly the former s^2 (J^T W J)^-1 of a weighted least squares.
  const double dof = double(nb) - 3.0;
  std::vector<double> nres2(nb), shape(nb);
  double wss = 0;
  for (size_t i = 0; i < nb; ++i) {
    const double res = p.bins[i].mean - scale * k[i];
    nres2[i] = double(p.bins[i].n) * res * res;
    shape[i] = pr.weight(i) > 0 ? double(p.bins[i].n) / pr.weight(i) : 1.0;
    wss += nres2[i] / shape[i];
  }
  const auto chi2 = [&](double x) {
    double c = 0;
    for (size_t i = 0; i < nb; ++i)
      if (nres2[i] > 0) c += nres2[i] / (tau2[i] + x * shape[i]);
    return c;
  };
  excess = 0;
  if (chi2(0) > dof) {
    double lo = 0, hi = wss / dof;  // chi2(hi) <= dof since tau^2 >= 0
    for (int it = 0; it < 100 && hi - lo > 1e-9 * hi; ++it) {
      const double mid = 0.5 * (lo + hi);
      (chi2(mid) > dof ? lo : hi) = mid;
    }
    excess = hi;
  }
  cov = {};
  for (size_t j = 0; j < nb; ++j) {
    const double v = (tau2[j] + excess * shape[j]) / double(p.bins[j].n);
    for (size_t u = 0; u < 3; ++u)
      for (size_t w = 0; w < 3; ++w) cov[u][w] += a[j][u] * a[j][w] * v;
  }
  return true;
}

}  // namespace

RadialProfile radial_profile(const std::vector<float>& radiance, uint32_t w, uint32_t h, const FitSettings& s) {
  RadialProfile p;
  const int64_t x0 = std::max(0, s.roi_x0), y0 = std::max(0, s.roi_y0);
  const int64_t x1 = s.roi_x1 < 0 ? int64_t{w} - 1 : std::min<int64_t>(s.roi_x1, int64_t{w} - 1);
  const int64_t y1 = s.roi_y1 < 0 ? int64_t{h} - 1 : std::min<int64_t>(s.roi_y1, int64_t{h} - 1);
  struct Acc {
    double n = 0, rho = 0, rho2 = 0, sum = 0, sumsq = 0, invalid = 0;
    // For Bin::noise_var: moments of x = rho - (the bin's first rho) up to
    // x^4 and of d = e - shift against 1, x, x^2.
    double x0 = kNaN, x1 = 0, x2 = 0, x3 = 0, x4 = 0, xd = 0, x2d = 0;
  };
  std::vector<Acc> acc;
  // Welford-free two-pass would cost a second sweep; values are shifted by
  // the bin's first sample instead, which keeps the sum of squares accurate.
  std::vector<double> shift;
  for (int64_t y = y0; y <= y1; ++y)
    for (int64_t x = x0; x <= x1; ++x) {
      const float e = radiance[size_t(y) * w + size_t(x)];
      const double rho = std::hypot(double(x) - s.bulb_x_px, double(y) - s.bulb_y_px);
      if (rho < s.mask_radius_px || rho < 0.5) continue;
      const size_t b = bin_of(rho);
      if (b >= acc.size()) {
        acc.resize(b + 1);
        shift.resize(b + 1, kNaN);
      }
      if (!std::isfinite(e)) {  // saturated in every frame: the whole ring is suspect
        acc[b].invalid += 1;
        continue;
      }
      if (std::isnan(shift[b])) shift[b] = double(e);
      const double d = double(e) - shift[b];
      acc[b].n += 1;
      acc[b].rho += rho;
      acc[b].rho2 += rho * rho;
      acc[b].sum += d;
      acc[b].sumsq += d * d;
      if (std::isnan(acc[b].x0)) acc[b].x0 = rho;
      const double xr = rho - acc[b].x0, xr2 = xr * xr;
      acc[b].x1 += xr;
      acc[b].x2 += xr2;
      acc[b].x3 += xr2 * xr;
      acc[b].x4 += xr2 * xr2;
      acc[b].xd += xr * d;
      acc[b].x2d += xr2 * d;
    }
  for (size_t b = 0; b < acc.size(); ++b) {
    if (acc[b].n == 0) continue;
    if (acc[b].invalid > 0) {
      // A ring with saturated pixels keeps only its darker, noise-selected
      // ones (the image is radially symmetric): its mean would be biased low.
      ++p.bins_dropped;
      continue;
    }
    Bin bin;
    bin.n = static_cast<uint64_t>(acc[b].n);
    bin.rho_px = acc[b].rho / acc[b].n;
    bin.rho_mm = bin.rho_px * s.mm_per_px;
    bin.rho_sd_px = std::sqrt(std::max(0.0, acc[b].rho2 / acc[b].n - bin.rho_px * bin.rho_px));
    const double md = acc[b].sum / acc[b].n;
    bin.mean = shift[b] + md;
    if (s.min_bin_radiance > 0 && !(bin.mean >= s.min_bin_radiance)) {
      // Too dark in every exposure: the bin's mean decides, not its pixels
      // (a per-pixel cut would keep the noise-selected bright ones).
      ++p.bins_dark;
      p.pixels_dark += bin.n;
      continue;
    }
    bin.sumsq_dev = std::max(0.0, acc[b].sumsq - acc[b].n * md * md);
    if (bin.n >= 8) {
      // Least squares d ~ c0 + c1 x + c2 x^2 over the bin's pixels; RSS =
      // sum d^2 - c . (X^T d). Singular (too few distinct radii): NaN.
      const Acc& q = acc[b];
      const std::array<std::array<double, 3>, 3> xtx = {{{q.n, q.x1, q.x2}, {q.x1, q.x2, q.x3}, {q.x2, q.x3, q.x4}}};
      const std::array<double, 3> xtd = {q.sum, q.xd, q.x2d};
      std::array<std::array<double, 3>, 3> inv{};
      const double det = xtx[0][0] * (xtx[1][1] * xtx[2][2] - xtx[1][2] * xtx[2][1]) -
                         xtx[0][1] * (xtx[1][0] * xtx[2][2] - xtx[1][2] * xtx[2][0]) +
                         xtx[0][2] * (xtx[1][0] * xtx[2][1] - xtx[1][1] * xtx[2][0]);
      const double x2c = q.x2 - q.x1 * q.x1 / q.n;  // n var(x): the bin must span rho
      if (x2c > 1e-6 * q.n && det > 1e-9 * xtx[0][0] * xtx[1][1] * xtx[2][2] && invert3(xtx, inv)) {
        double fit_ss = 0;
        for (size_t u = 0; u < 3; ++u)
          for (size_t v = 0; v < 3; ++v) fit_ss += xtd[u] * inv[u][v] * xtd[v];
        const double rss = q.sumsq - fit_ss;
        // A quadratic through too few distinct radii fits them exactly (rss
        // ~ 0 from rounding): only a positive rss well above rounding counts.
        if (rss > 1e-12 * q.sumsq) bin.noise_var = rss / (q.n - 3);
      }
    }
    p.pixels += bin.n;
    p.within_ss += bin.sumsq_dev;
    p.bins.push_back(bin);
  }
  return p;
}

Minimum minimise_from(const RadialProfile& p, const FitSettings& s, Phase phase, double sigma0, double g0) {
  Problem pr(p, s);
  return nelder_mead(pr, s, phase, {std::log(sigma0), std::atanh(std::clamp(g0, -kGMax, kGMax))});
}

FitResult fit_profile(const RadialProfile& p, const FitSettings& s, const std::vector<float>& radiance, uint32_t w,
                      uint32_t h) {
  FitResult r;
  // Too few bins because the rest were too dark in every exposure
  // (min_bin_radiance): no scattered light the camera can measure, which is
  // a pure absorber's image (M5), not a geometry error.
  const bool too_dark = (p.bins.size() < 8 || p.pixels < 64) && p.bins_dark > 0;
  if ((p.bins.size() < 8 || p.pixels < 64) && !too_dark) {
    r.error = "only " + std::to_string(p.pixels) + " usable pixels in " + std::to_string(p.bins.size()) +
              " radial bins outside the bulb mask: check bulb_x_px/bulb_y_px, mask_radius_px and the ROI, and that "
              "the radiance map is not saturated everywhere";
    return r;
  }
  // I0 for beta's absolute scale.
  r.source_intensity = s.source_intensity > 0 ? s.source_intensity
                       : (s.water_radiance > 0 && s.bulb_radius_mm > 0)
                           ? s.water_radiance * std::numbers::pi * s.bulb_radius_mm * s.bulb_radius_mm
                           : 1.0;
  r.beta_absolute = s.source_intensity > 0 || (s.water_radiance > 0 && s.bulb_radius_mm > 0);
  if (!r.beta_absolute) r.notes.emplace_back("beta is relative (I0 = 1): give source_intensity or water_radiance + bulb_radius_mm");

  Problem pr(p, s);
  bool absorber = too_dark || !(pr.emax() > 0);
  std::vector<double> k;
  if (!absorber) {
    Minimum m = search(pr, s, Phase::henyey_greenstein, {-0.6, -0.2, 0.2, 0.5, 0.7, 0.8, 0.87, 0.92, 0.96, 0.99}, 3);
    r.model_reason = "H-G fit";
    if (m.g > s.legendre_above_g) {
      // §4.3.3: for g > 0.95 the truncated Legendre expansion of H-G. It rings
      // in the side and back directions (relative error > 100 at g = 0.97 with
      // 99 terms), so it is kept only where it fits the image at least as well.
      // Its own grid (its minimum may lie far from H-G's), NM from the best
      // node and from the H-G optimum: ~30x the cost of an H-G evaluation.
      const Minimum l = search(pr, s, Phase::truncated_legendre, {0.955, 0.965, 0.975, 0.985, 0.995}, 1, &m);
      const std::string head = "H-G fit gave g = " + fmt(m.g) + " > legendre_above_g = " +
                               fmt(s.legendre_above_g) + ": refit with the truncated Legendre expansion (" +
                               std::to_string(s.legendre_terms) + " terms, thesis §4.3.3); ";
      r.legendre_objective = l.objective;
      if (l.objective <= m.objective) {
        r.phase = Phase::truncated_legendre;
        r.model = "truncated_legendre";
        r.model_reason = head + "it fits better (objective " + fmt(l.objective) + " vs " +
                         fmt(m.objective) + ")";
        m = l;
      } else {
        r.model_reason = head + "it fits worse (objective " + fmt(l.objective) + " vs H-G " +
                         fmt(m.objective) + "; its tail rings): kept H-G";
      }
    }
    r.evaluations = pr.evaluations;
    r.objective = m.objective;
    pr.unit_model(m.sigma, m.g, r.phase, k);
    r.scale = pr.ls_scale(k);
    r.sigma.value = m.sigma;
    r.g.value = m.g;
    // 95 % intervals: the delta-method (sandwich) covariance of (sigma, g,
    // beta I0) over the bins' means, each with its measured variance
    // (parameter_covariance above).
    Cov3 cov{};
    double excess = 0, noise2 = 0;
    double se_scale = kNaN;
    if (parameter_covariance(pr, p, s, r.phase, m.sigma, m.g, r.scale, k, cov, excess, noise2)) {
      r.sigma.ci95 = 1.96 * std::sqrt(std::max(0.0, cov[0][0]));
      r.g.ci95 = 1.96 * std::sqrt(std::max(0.0, cov[1][1]));
      se_scale = std::sqrt(std::max(0.0, cov[2][2]));
      r.beta.ci95 = 1.96 * se_scale / r.source_intensity;
      // kappa = sigma - beta: var = var sigma + var beta - 2 cov.
      const double vk = cov[0][0] + cov[2][2] / (r.source_intensity * r.source_intensity) -
                        2.0 * cov[0][2] / r.source_intensity;
      r.kappa.ci95 = 1.96 * std::sqrt(std::max(0.0, vk));
      if (excess > noise2)
        r.notes.emplace_back("the profile's residuals exceed the pixel noise measured inside the radial bins (RMS " +
                             fmt(std::sqrt(noise2)) + " DN/us; a model error or structured noise of " +
                             fmt(std::sqrt(excess)) + " DN/us per pixel): the intervals count it as noise");
    } else {
      r.notes.emplace_back("the Jacobian is singular at the optimum: no confidence intervals");
    }
    r.beta.value = r.scale / r.source_intensity;
    r.kappa.value = r.sigma.value - r.beta.value;
    const bool insignificant = !(r.scale > 1.96 * se_scale) && std::isfinite(se_scale);
    const bool low_albedo = r.beta_absolute && r.beta.value < s.absorber_albedo * r.sigma.value;
    absorber = r.scale <= 0 || insignificant || low_albedo;
    if (absorber)
      r.model_reason = r.scale <= 0 ? "the least-squares scattering scale is <= 0"
                       : insignificant ? "beta is below 1.96 standard errors (not significant)"
                                       : "beta / sigma = " + fmt(r.beta.value / r.sigma.value) +
                                             " < absorber_albedo";
  } else if (too_dark) {
    r.model_reason = "only " + std::to_string(p.bins.size()) + " radial bins outside the bulb mask reach min_signal (" +
                     std::to_string(p.bins_dark) + " are darker in every exposure): no measurable scattered light";
  } else {
    r.model_reason = "no light outside the bulb mask (max radiance <= 0)";
  }
  if (absorber) {
    // M5: pure absorber. g is undefined, beta = 0, kappa = sigma from attenuation.
    r.model = "pure_absorber";
    r.g_defined = false;
    r.g = {};
    r.beta = {0.0, r.beta.ci95};
    r.scale = 0;
    std::string why;
    r.sigma = sigma_from_attenuation(s, s.water_radiance, radiance, w, h, why);
    if (!why.empty()) r.notes.push_back("pure absorber: " + why);
    r.kappa = r.sigma;
    k.assign(p.bins.size(), 0.0);
  }
  // The fitted profile and its RMS errors.
  r.fit.resize(p.bins.size());
  double sum_n = 0, sum_e = 0, sum_r2 = 0, sum_norm2 = 0, fmax = 0;
  for (size_t i = 0; i < k.size(); ++i) fmax = std::max(fmax, r.scale * k[i]);
  for (size_t i = 0; i < k.size(); ++i) {
    const double n = double(p.bins[i].n);
    r.fit[i] = r.scale * k[i];
    const double res = p.bins[i].mean - r.fit[i];
    sum_n += n;
    sum_e += n * p.bins[i].mean;
    sum_r2 += n * res * res;
    if (pr.emax() > 0 && fmax > 0) {
      const double q = p.bins[i].mean / pr.emax() - r.fit[i] / fmax;
      sum_norm2 += n * q * q;
    }
  }
  if (sum_e > 0) r.rms_percent = 100.0 * std::sqrt(sum_r2 / sum_n) / (sum_e / sum_n);
  if (pr.emax() > 0 && fmax > 0)
    r.rms_normalized_percent = 100.0 * std::sqrt((sum_norm2 + p.within_ss / (pr.emax() * pr.emax())) / sum_n);
  return r;
}

namespace {

// The bulb's central pixels: within R/2 of the centre (1 px for a point
// source), finite and > 0; calls fn(path_mm, radiance) for each. The path
// is the line of sight's length in the medium in front of the bulb:
// l = B - sqrt(R^2 - s^2) at lateral offset s (B for a point source).
template <class Fn>
size_t for_bulb_pixels(const FitSettings& s, const std::vector<float>& radiance, uint32_t w, uint32_t h, Fn&& fn) {
  const double r_px = s.bulb_radius_mm > 0 ? 0.5 * s.bulb_radius_mm / s.mm_per_px : 1.0;
  size_t n = 0;
  const auto x0 = static_cast<int64_t>(std::floor(s.bulb_x_px - r_px)), x1 = static_cast<int64_t>(std::ceil(s.bulb_x_px + r_px));
  const auto y0 = static_cast<int64_t>(std::floor(s.bulb_y_px - r_px)), y1 = static_cast<int64_t>(std::ceil(s.bulb_y_px + r_px));
  for (int64_t y = std::max<int64_t>(0, y0); y <= std::min<int64_t>(int64_t{h} - 1, y1); ++y)
    for (int64_t x = std::max<int64_t>(0, x0); x <= std::min<int64_t>(int64_t{w} - 1, x1); ++x) {
      const double sp = std::hypot(double(x) - s.bulb_x_px, double(y) - s.bulb_y_px);
      const double e = double(radiance[size_t(y) * w + size_t(x)]);
      if (sp > r_px || !(e > 0) || !std::isfinite(e)) continue;
      const double smm = std::min(sp * s.mm_per_px, s.bulb_radius_mm);
      fn(s.tank.bulb_depth_mm - std::sqrt(s.bulb_radius_mm * s.bulb_radius_mm - smm * smm), e);
      ++n;
    }
  return n;
}

}  // namespace

double bulb_radiance(const FitSettings& s, const std::vector<float>& radiance, uint32_t w, uint32_t h) {
  double sum = 0;
  const size_t n = for_bulb_pixels(s, radiance, w, h, [&](double, double e) { sum += e; });
  return n > 0 ? sum / double(n) : kNaN;
}

Estimate sigma_from_attenuation(const FitSettings& s, double water_radiance, const std::vector<float>& radiance,
                                uint32_t w, uint32_t h, std::string& why) {
  if (!(water_radiance > 0)) {
    why = "sigma by attenuation needs the bulb's radiance through pure water: give water_radiance (DN/us)";
    return {};
  }
  double num = 0, den = 0;
  std::vector<double> est;
  for_bulb_pixels(s, radiance, w, h, [&](double l, double e) {
    const double y_ln = std::log(water_radiance / e);  // = sigma l (Eq. 4.3 in radiance)
    num += l * y_ln;
    den += l * l;
    est.push_back(y_ln / l);
  });
  if (est.empty() || !(den > 0)) {
    why = "no unsaturated pixel of the bulb's direct image near its centre (bulb_x_px, bulb_y_px): check the bulb "
          "position, add shorter exposures";
    return {};
  }
  Estimate e;
  e.value = std::max(0.0, num / den);
  double m = 0, v = 0;
  for (double q : est) m += q;
  m /= double(est.size());
  for (double q : est) v += (q - m) * (q - m);
  e.ci95 = est.size() > 1 ? 1.96 * std::sqrt(v / double(est.size() - 1) / double(est.size())) : kNaN;
  return e;
}

std::vector<float> model_image(const FitResult& r, const FitSettings& s, uint32_t w, uint32_t h) {
  std::vector<float> out(size_t{w} * h, std::numeric_limits<float>::quiet_NaN());
  if (!r.error.empty()) return out;
  // Farthest pixel from the bulb; a fine log grid of rho, linear in ln rho.
  double far = 1;
  for (double cx : {0.0, double(w) - 1})
    for (double cy : {0.0, double(h) - 1}) far = std::max(far, std::hypot(cx - s.bulb_x_px, cy - s.bulb_y_px));
  const double near = std::max(0.5, s.mask_radius_px);
  if (far <= near) return out;
  constexpr size_t kN = 1024;
  std::vector<double> rho(kN), k;
  const double l0 = std::log(near), l1 = std::log(far), step = (l1 - l0) / double(kN - 1);
  for (size_t i = 0; i < kN; ++i) rho[i] = std::exp(l0 + step * double(i)) * s.mm_per_px;
  if (r.scale > 0)
    ProfileModel(s.tank, rho, r.phase == Phase::truncated_legendre ? kLegendrePanelRad : 0.0).evaluate(r.sigma.value, r.g.value, r.phase, s.legendre_terms, k);
  else k.assign(kN, 0.0);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const double d = std::hypot(double(x) - s.bulb_x_px, double(y) - s.bulb_y_px);
      if (d < near) continue;
      const double t = std::clamp((std::log(d) - l0) / step, 0.0, double(kN - 1));
      const auto i = std::min(static_cast<size_t>(t), kN - 2);
      const double f = t - double(i);
      out[size_t{y} * w + x] = static_cast<float>(r.scale * ((1 - f) * k[i] + f * k[i + 1]));
    }
  return out;
}

}  // namespace procam::medium
