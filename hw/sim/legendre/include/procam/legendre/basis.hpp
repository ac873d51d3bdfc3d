// SPDX-License-Identifier: MIT
// One-dimensional Legendre machinery on [-1, 1] (thesis ch. 6 §6.2-6.3,
// Appendices A and B): polynomial values, Gauss-Legendre quadrature, the
// derivative and integral matrices, the triple-product tensor with its
// sparsity pattern, and the Chebyshev truncation matrix.
//
// Convention (used everywhere in procam::legendre): f(x) = sum_k F_k P_k(x)
// with the standard (unnormalised) Legendre polynomials P_k, P_k(1) = 1, so
// int_{-1}^{1} P_i P_j dx = 2/(2i+1) delta_ij and F_k = (2k+1)/2 int f P_k
// (thesis Eq. 6.6 up to that normalisation; the thesis writes the
// orthonormal form). Matrices are dense row-major (rows = output index).
//
// Contracts: pure functions, no global state, thread-safe. Sizes are
// polynomial counts n >= 1 (degree n-1); invalid sizes throw
// std::invalid_argument saying which argument was wrong.
#pragma once

#include <cstddef>
#include <vector>

namespace procam::legendre {

// Dense row-major matrix: a(r, c) = data[r * cols + c].
struct Matrix {
  size_t rows = 0, cols = 0;
  std::vector<double> data;
  Matrix() = default;
  Matrix(size_t r, size_t c) : rows(r), cols(c), data(r * c, 0.0) {}
  double& operator()(size_t r, size_t c) { return data[r * cols + c]; }
  double operator()(size_t r, size_t c) const { return data[r * cols + c]; }
};

// P_0(x) .. P_{n-1}(x) by the three-term recurrence; out.size() == n.
void legendre_values(double x, size_t n, double* out);
std::vector<double> legendre_values(double x, size_t n);

// Gauss-Legendre nodes/weights on [-1, 1]; exact for polynomials of degree
// <= 2m-1. Newton on P_m, converged to ~1e-15.
struct Quadrature {
  std::vector<double> nodes, weights;
};
Quadrature gauss_legendre(size_t m);

// Derivative matrix (thesis Eq. 6.9, Fig. 6.4): coefficients of f' from
// those of f, both of size n. D(k, i) = 2k+1 for k < i with i-k odd, else 0
// (from P_i' = sum_{k<i, i-k odd} (2k+1) P_k).
Matrix derivative_matrix(size_t n);

// Integral matrix (thesis Fig. 6.6, "I-hat"): coefficients (size n+1) of
// F(x) = int_{-1}^{x} f(s) ds from those of f (size n); exact, F(-1) = 0.
// Uses int P_i = (P_{i+1} - P_{i-1})/(2i+1) for i >= 1 and int P_0 = P_1 + P_0.
Matrix integral_matrix(size_t n);

// Triple-product integral TI(i, j, k) = int_{-1}^{1} P_i P_j P_k dx in closed
// form (the square of a Wigner 3j symbol with zero projections, times 2):
//   s = (i+j+k)/2, TI = 2/(2s+1) * [C(2s-2i, s-i) C(2s-2j, s-j) C(2s-2k, s-k)]
//                      / C(2s, s)
// and exactly 0 where Appendix A's theorem says so (i+j+k odd or the
// triangle inequality |i-j| <= k <= i+j fails). Evaluated in log-space,
// relative error ~1e-14 for indices < 200.
double triple_product(size_t i, size_t j, size_t k);

// Appendix A, Theorem 1: true when TI(i, j, k) may be nonzero (i+j+k even
// and the triangle inequality holds). The closed form shows these entries
// are in fact strictly positive.
bool triple_product_allowed(size_t i, size_t j, size_t k);

// The nonzero entries of TI for i < na, j < nb, k < nc as a flat list, so a
// product loops over ~1/4 of the na*nb*nc triples (Appendix A, Result 1).
// `w` already includes the output normalisation (2k+1)/2, i.e.
// (f g)_k = sum over entries of w * F_i * G_j.
struct TripleEntry {
  unsigned i, j, k;
  double w;
};
std::vector<TripleEntry> triple_product_entries(size_t na, size_t nb, size_t nc);
// The same list from a per-thread cache (products call this every time; the
// closed form costs four lgamma calls per entry). The reference stays valid
// for the calling thread's lifetime.
const std::vector<TripleEntry>& cached_triple_product_entries(size_t na, size_t nb, size_t nc);

// Appendix B truncation matrix T (n_out x n_in, n_out <= n_in): Legendre
// coefficients of the degree n_out-1 approximation of a degree n_in-1
// polynomial obtained by the cascade "replace the leading power x^m by its
// mini-max polynomial x^m - 2^{1-m} T_m(x)" down to degree n_out-1. Each
// cascade step subtracts exactly the current leading Chebyshev term, so the
// scheme equals dropping Chebyshev coefficients >= n_out; T is built that
// way (Legendre -> Chebyshev -> drop -> Legendre), each change of basis by
// exact Gauss quadrature, which avoids the ill-conditioned monomial basis.
Matrix chebyshev_truncation_matrix(size_t n_out, size_t n_in);

// Plain L2 (Galerkin) truncation is just "keep the first n_out coefficients"
// and needs no matrix; see field.hpp Truncation.

// y = A x (sizes checked by the caller; A.cols == x.size()).
std::vector<double> multiply(const Matrix& a, const std::vector<double>& x);

}  // namespace procam::legendre
