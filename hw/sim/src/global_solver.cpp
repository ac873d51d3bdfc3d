// SPDX-License-Identifier: MIT
// Dense solver of the radiosity system (A strictly diagonally dominant: Gauss–Jordan without pivoting).
#include <vector>

#include "global_internal.hpp"
#include "parallel.hpp"

namespace procam::sim::detail {

void solve_dense(std::vector<double>& A, std::vector<double>& R, size_t n, int threads) {
  for (size_t k = 0; k < n; ++k) {
    const double pivot = A[k * n + k];
    const double* ak = &A[k * n];
    const double* rk = &R[k * n];
    // Eliminate column k from every other row (Gauss–Jordan).
    detail::parallel_rows(static_cast<uint32_t>(n), threads, [&](uint32_t b, uint32_t e) {
      for (size_t i = b; i < e; ++i) {
        if (i == k) continue;
        const double l = A[i * n + k] / pivot;
        if (l == 0) continue;
        double* ai = &A[i * n];
        double* ri = &R[i * n];
        for (size_t j = k; j < n; ++j) ai[j] -= l * ak[j];
        for (size_t j = 0; j < n; ++j) ri[j] -= l * rk[j];
      }
    });
  }
  for (size_t i = 0; i < n; ++i) {
    const double d = A[i * n + i];
    for (size_t j = 0; j < n; ++j) R[i * n + j] /= d;
  }
}

}  // namespace procam::sim::detail
