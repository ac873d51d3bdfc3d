// SPDX-License-Identifier: MIT
#include "procam/legendre/linalg.hpp"

#include <cmath>
#include <utility>

namespace procam::legendre {

std::optional<Matrix> cholesky(const Matrix& a) {
  const size_t n = a.rows;
  Matrix l(n, n);
  for (size_t j = 0; j < n; ++j) {
    double s = a(j, j);
    for (size_t k = 0; k < j; ++k) s -= l(j, k) * l(j, k);
    if (!(s > 0.0)) return std::nullopt;
    const double d = std::sqrt(s);
    l(j, j) = d;
    for (size_t i = j + 1; i < n; ++i) {
      double t = a(i, j);
      for (size_t k = 0; k < j; ++k) t -= l(i, k) * l(j, k);
      l(i, j) = t / d;
    }
  }
  return l;
}

void cholesky_solve(const Matrix& l, std::vector<double>& b) {
  const size_t n = l.rows;
  for (size_t i = 0; i < n; ++i) {
    double s = b[i];
    for (size_t k = 0; k < i; ++k) s -= l(i, k) * b[k];
    b[i] = s / l(i, i);
  }
  for (size_t i = n; i-- > 0;) {
    double s = b[i];
    for (size_t k = i + 1; k < n; ++k) s -= l(k, i) * b[k];
    b[i] = s / l(i, i);
  }
}

std::optional<Lu> lu_factor(const Matrix& a, double tol) {
  const size_t n = a.rows;
  Lu f{a, std::vector<size_t>(n)};
  double amax = 0.0;
  for (double v : a.data) amax = std::fmax(amax, std::fabs(v));
  if (amax == 0.0) return std::nullopt;
  for (size_t i = 0; i < n; ++i) f.perm[i] = i;
  Matrix& m = f.lu;
  for (size_t k = 0; k < n; ++k) {
    size_t p = k;
    for (size_t i = k + 1; i < n; ++i)
      if (std::fabs(m(i, k)) > std::fabs(m(p, k))) p = i;
    if (std::fabs(m(p, k)) < tol * amax) return std::nullopt;
    if (p != k) {
      for (size_t c = 0; c < n; ++c) std::swap(m(k, c), m(p, c));
      std::swap(f.perm[k], f.perm[p]);
    }
    for (size_t i = k + 1; i < n; ++i) {
      const double r = m(i, k) / m(k, k);
      m(i, k) = r;
      if (r == 0.0) continue;
      for (size_t c = k + 1; c < n; ++c) m(i, c) -= r * m(k, c);
    }
  }
  return f;
}

void lu_solve(const Lu& f, std::vector<double>& b) {
  const size_t n = f.lu.rows;
  std::vector<double> x(n);
  for (size_t i = 0; i < n; ++i) {
    double s = b[f.perm[i]];
    for (size_t k = 0; k < i; ++k) s -= f.lu(i, k) * x[k];
    x[i] = s;
  }
  for (size_t i = n; i-- > 0;) {
    double s = x[i];
    for (size_t k = i + 1; k < n; ++k) s -= f.lu(i, k) * x[k];
    x[i] = s / f.lu(i, i);
  }
  b = std::move(x);
}

Matrix orthonormal_rows(const Matrix& rows, double rel_tol) {
  const size_t m = rows.cols;
  std::vector<std::vector<double>> q;
  for (size_t r = 0; r < rows.rows; ++r) {
    std::vector<double> v(rows.data.begin() + static_cast<std::ptrdiff_t>(r * m),
                          rows.data.begin() + static_cast<std::ptrdiff_t>((r + 1) * m));
    double n0 = 0.0;
    for (double x : v) n0 += x * x;
    n0 = std::sqrt(n0);
    if (n0 == 0.0) continue;
    for (int pass = 0; pass < 2; ++pass)
      for (const auto& u : q) {
        double d = 0.0;
        for (size_t i = 0; i < m; ++i) d += u[i] * v[i];
        for (size_t i = 0; i < m; ++i) v[i] -= d * u[i];
      }
    double n1 = 0.0;
    for (double x : v) n1 += x * x;
    n1 = std::sqrt(n1);
    if (n1 < rel_tol * n0) continue;
    for (double& x : v) x /= n1;
    q.push_back(std::move(v));
  }
  Matrix out(q.size(), m);
  for (size_t r = 0; r < q.size(); ++r)
    for (size_t i = 0; i < m; ++i) out(r, i) = q[r][i];
  return out;
}

}  // namespace procam::legendre
