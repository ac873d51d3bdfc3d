// SPDX-License-Identifier: MIT
#include "procam/legendre/basis.hpp"

#include <cmath>
#include <map>
#include <tuple>
#include <numbers>
#include <stdexcept>
#include <string>

namespace procam::legendre {

void legendre_values(double x, size_t n, double* out) {
  if (n == 0) return;
  out[0] = 1.0;
  if (n == 1) return;
  out[1] = x;
  for (size_t k = 1; k + 1 < n; ++k) {
    const double kd = static_cast<double>(k);
    out[k + 1] = ((2.0 * kd + 1.0) * x * out[k] - kd * out[k - 1]) / (kd + 1.0);
  }
}

std::vector<double> legendre_values(double x, size_t n) {
  std::vector<double> v(n);
  legendre_values(x, n, v.data());
  return v;
}

Quadrature gauss_legendre(size_t m) {
  if (m == 0) throw std::invalid_argument("gauss_legendre: need at least one node (m >= 1)");
  Quadrature q;
  q.nodes.resize(m);
  q.weights.resize(m);
  const double md = static_cast<double>(m);
  for (size_t i = 0; i < m; ++i) {
    // Tricomi's initial guess, then Newton on P_m.
    double x = std::cos(std::numbers::pi * (static_cast<double>(i) + 0.75) / (md + 0.5));
    double dp = 1.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = x;
      for (size_t k = 1; k < m; ++k) {
        const double kd = static_cast<double>(k);
        const double p2 = ((2.0 * kd + 1.0) * x * p1 - kd * p0) / (kd + 1.0);
        p0 = p1;
        p1 = p2;
      }
      dp = md * (x * p1 - p0) / (x * x - 1.0);
      const double dx = p1 / dp;
      x -= dx;
      if (std::fabs(dx) < 1e-16) break;
    }
    q.nodes[m - 1 - i] = x;  // ascending
    q.weights[m - 1 - i] = 2.0 / ((1.0 - x * x) * dp * dp);
  }
  return q;
}

Matrix derivative_matrix(size_t n) {
  Matrix d(n, n);
  for (size_t i = 0; i < n; ++i)
    for (size_t k = (i % 2 == 0) ? 1 : 0; k < i; k += 2) d(k, i) = 2.0 * static_cast<double>(k) + 1.0;
  return d;
}

Matrix integral_matrix(size_t n) {
  Matrix a(n + 1, n);
  // int_{-1}^x P_0 = x + 1 = P_0 + P_1.
  if (n > 0) a(0, 0) = 1.0, a(1, 0) = 1.0;
  // int_{-1}^x P_i = (P_{i+1} - P_{i-1}) / (2i+1) (both vanish at -1).
  for (size_t i = 1; i < n; ++i) {
    const double s = 1.0 / (2.0 * static_cast<double>(i) + 1.0);
    a(i + 1, i) += s;
    a(i - 1, i) -= s;
  }
  return a;
}

bool triple_product_allowed(size_t i, size_t j, size_t k) {
  if ((i + j + k) % 2 != 0) return false;
  return k <= i + j && i <= j + k && j <= i + k;
}

namespace {
double log_binomial(size_t a, size_t b) {
  return std::lgamma(static_cast<double>(a) + 1.0) - std::lgamma(static_cast<double>(b) + 1.0) -
         std::lgamma(static_cast<double>(a - b) + 1.0);
}
}  // namespace

double triple_product(size_t i, size_t j, size_t k) {
  if (!triple_product_allowed(i, j, k)) return 0.0;  // Appendix A, Theorem 1
  const size_t s = (i + j + k) / 2;
  const double l = log_binomial(2 * (s - i), s - i) + log_binomial(2 * (s - j), s - j) +
                   log_binomial(2 * (s - k), s - k) - log_binomial(2 * s, s);
  return 2.0 / (2.0 * static_cast<double>(s) + 1.0) * std::exp(l);
}

std::vector<TripleEntry> triple_product_entries(size_t na, size_t nb, size_t nc) {
  std::vector<TripleEntry> out;
  for (size_t k = 0; k < nc; ++k)
    for (size_t i = 0; i < na; ++i) {
      // j runs over |i-k| .. i+k with the parity of i+k (Theorem 1).
      const size_t j0 = i > k ? i - k : k - i;
      for (size_t j = j0; j < nb && j <= i + k; j += 2)
        out.push_back({static_cast<unsigned>(i), static_cast<unsigned>(j), static_cast<unsigned>(k),
                       (2.0 * static_cast<double>(k) + 1.0) / 2.0 * triple_product(i, j, k)});
    }
  return out;
}

const std::vector<TripleEntry>& cached_triple_product_entries(size_t na, size_t nb, size_t nc) {
  thread_local std::map<std::tuple<size_t, size_t, size_t>, std::vector<TripleEntry>> cache;
  const auto key = std::make_tuple(na, nb, nc);
  auto it = cache.find(key);
  if (it == cache.end()) it = cache.emplace(key, triple_product_entries(na, nb, nc)).first;
  return it->second;
}

Matrix chebyshev_truncation_matrix(size_t n_out, size_t n_in) {
  if (n_out == 0 || n_out > n_in)
    throw std::invalid_argument("chebyshev_truncation_matrix: need 1 <= n_out <= n_in, got n_out=" +
                                std::to_string(n_out) + " n_in=" + std::to_string(n_in));
  // Chebyshev coefficients of P_i (i < n_in) by Gauss-Chebyshev quadrature
  // with n_in nodes: exact for degree <= 2 n_in - 1, enough for P_i T_m.
  const size_t m = n_in;
  Matrix cheb(n_in, n_in);  // cheb(mode, i): Chebyshev coefficient of P_i
  std::vector<double> p(n_in);
  for (size_t q = 0; q < m; ++q) {
    const double theta = std::numbers::pi * (static_cast<double>(q) + 0.5) / static_cast<double>(m);
    const double x = std::cos(theta);
    legendre_values(x, n_in, p.data());
    for (size_t mode = 0; mode < n_in; ++mode) {
      const double t = std::cos(static_cast<double>(mode) * theta);
      const double scale = (mode == 0 ? 1.0 : 2.0) / static_cast<double>(m);
      for (size_t i = 0; i < n_in; ++i) cheb(mode, i) += scale * t * p[i];
    }
  }
  // Legendre coefficients of T_mode (mode < n_out) by Gauss-Legendre with
  // n_out nodes (exact for degree <= 2 n_out - 1).
  const Quadrature gl = gauss_legendre(n_out);
  Matrix leg(n_out, n_out);  // leg(k, mode)
  std::vector<double> pk(n_out);
  for (size_t q = 0; q < n_out; ++q) {
    const double x = gl.nodes[q];
    legendre_values(x, n_out, pk.data());
    const double theta = std::acos(std::fmax(-1.0, std::fmin(1.0, x)));
    for (size_t mode = 0; mode < n_out; ++mode) {
      const double t = std::cos(static_cast<double>(mode) * theta);
      for (size_t k = 0; k < n_out; ++k)
        leg(k, mode) += (2.0 * static_cast<double>(k) + 1.0) / 2.0 * gl.weights[q] * t * pk[k];
    }
  }
  Matrix t(n_out, n_in);
  for (size_t k = 0; k < n_out; ++k)
    for (size_t i = 0; i < n_in; ++i) {
      double s = 0.0;
      for (size_t mode = 0; mode < n_out; ++mode) s += leg(k, mode) * cheb(mode, i);
      t(k, i) = s;
    }
  return t;
}

std::vector<double> multiply(const Matrix& a, const std::vector<double>& x) {
  std::vector<double> y(a.rows, 0.0);
  for (size_t r = 0; r < a.rows; ++r) {
    double s = 0.0;
    for (size_t c = 0; c < a.cols; ++c) s += a(r, c) * x[c];
    y[r] = s;
  }
  return y;
}

}  // namespace procam::legendre
