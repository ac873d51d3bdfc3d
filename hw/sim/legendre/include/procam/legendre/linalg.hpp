// SPDX-License-Identifier: MIT
// Small dense linear algebra for the K x K systems of the Legendre domain
// (K <= a few hundred): Cholesky, LU with partial pivoting, and an
// orthonormal basis of a row space. Plain loops; no external library.
// Contracts: pure functions on value types; failures (not positive
// definite, singular) are reported by return value, never NaN.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "procam/legendre/basis.hpp"

namespace procam::legendre {

// Lower-triangular L with A = L L^T, or nullopt when A is not (numerically)
// symmetric positive definite.
std::optional<Matrix> cholesky(const Matrix& a);
// Solves L L^T x = b in place.
void cholesky_solve(const Matrix& l, std::vector<double>& b);

struct Lu {
  Matrix lu;                // L (unit diagonal, below) and U (on/above)
  std::vector<size_t> perm; // row permutation
};
// Partial-pivoting LU; nullopt when a pivot is below tol * max|a|.
std::optional<Lu> lu_factor(const Matrix& a, double tol = 1e-13);
void lu_solve(const Lu& f, std::vector<double>& b);

// Orthonormal rows spanning the row space of `rows` (modified Gram-Schmidt,
// twice, dropping rows whose remaining norm is below rel_tol times their
// original norm: linearly dependent constraints are allowed).
Matrix orthonormal_rows(const Matrix& rows, double rel_tol = 1e-10);

}  // namespace procam::legendre
