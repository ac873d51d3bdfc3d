// SPDX-License-Identifier: MIT
// Legendre fields on a box (thesis ch. 6 §6.2.1, Eq. 6.7; operators of
// Fig. 6.6): a scalar field f(x, y, z) = sum F_{kz,ky,kx} P_kx(x') P_ky(y')
// P_kz(z') where x' = 2 (x - lo.x)/(hi.x - lo.x) - 1 maps the box to [-1,1].
// 1D and 2D fields are 3D fields with n = 1 on the unused axes, so every
// operator below is written once for all dimensions.
//
// Units: box coordinates are in the caller's length unit (metres in the
// sim); derivatives are per that unit, integrals are times it.
// Contracts: Field is a value type; operators are pure functions, thread
// safe, allocate their result. Shape mismatches throw std::invalid_argument
// naming both shapes. Cost notes give K = nx*ny*nz.
#pragma once

#include <array>
#include <cstddef>
#include <functional>
#include <vector>

#include "procam/legendre/basis.hpp"

namespace procam::legendre {

struct Box {
  std::array<double, 3> lo{-1.0, -1.0, -1.0}, hi{1.0, 1.0, 1.0};
  double half_width(size_t axis) const { return 0.5 * (hi[axis] - lo[axis]); }
  // [-1, 1] coordinate of a box coordinate along `axis`.
  double unit_from_box(size_t axis, double x) const { return (x - lo[axis]) / half_width(axis) - 1.0; }
  double box_from_unit(size_t axis, double u) const { return lo[axis] + (u + 1.0) * half_width(axis); }
};

using Shape = std::array<size_t, 3>;  // polynomial count per axis (x, y, z); 1 = unused axis

struct Field {
  Shape n{1, 1, 1};
  Box box;
  size_t d = 1;           // used axes: 0 .. d-1 (axes >= d have n = 1)
  std::vector<double> c;  // c[(kz * n[1] + ky) * n[0] + kx]

  Field() : c(1, 0.0) {}
  // Throws std::invalid_argument when dims is not 1..3, an axis has n = 0,
  // or an unused axis has n != 1.
  Field(Shape shape, const Box& b, size_t dims);
  size_t size() const { return c.size(); }
  size_t index(size_t kx, size_t ky, size_t kz) const { return (kz * n[1] + ky) * n[0] + kx; }
  double& at(size_t kx, size_t ky = 0, size_t kz = 0) { return c[index(kx, ky, kz)]; }
  double at(size_t kx, size_t ky = 0, size_t kz = 0) const { return c[index(kx, ky, kz)]; }
  size_t dims() const { return d; }
};

// Cube shape with n polynomials on each of the first `dims` axes.
Shape cube_shape(size_t dims, size_t n);
// Zero field with n polynomials per used axis.
Field zero_field(size_t dims, size_t n, const Box& box);

// out(.., k_axis, ..) = sum_i m(k_axis, i) f(.., i, ..): the generic
// "one-axis matrix" used by derivative, integral and truncation.
// Cost O(K * m.rows).
Field apply_along(const Field& f, size_t axis, const Matrix& m);

// d f / d axis (thesis Eq. 6.9, D_x); same shape. Cost O(K n).
Field derivative(const Field& f, size_t axis);
// int_{lo}^{x} f d axis (thesis Fig. 6.6, I-hat); shape n+1 along axis.
Field integral(const Field& f, size_t axis);

enum class Truncation {
  kL2,         // keep the first coefficients: the L2-best (Galerkin) truncation
  kChebyshev,  // Appendix B: drop Chebyshev modes, near-mini-max in L_inf
};
// Truncate (or zero-pad) to `shape`. Cost O(K n) for kChebyshev.
Field truncate(const Field& f, const Shape& shape, Truncation how = Truncation::kL2);

// Product through the triple-product tensor (thesis Eq. 6.10) with only the
// entries allowed by Appendix A's theorem visited. `out` is the result
// shape: f.n + g.n - 1 per axis gives the exact product; a smaller shape
// gives its L2 (Galerkin) truncation directly. Boxes must match.
Field product(const Field& f, const Field& g, const Shape& out);
// The multiplication matrix M^G of Eq. 6.10: product(g, f, out) == M f for
// every f of shape `in` (rows: out coefficients, columns: in). Built in
// O(n^{d+3}) by factorising over the axes (Theorem 1's entries only); worth
// it when one field multiplies many (the fluid's advecting velocity, the
// renderer's density): each use is then one K x K matrix-vector product.
Matrix product_matrix(const Field& g, const Shape& in, const Shape& out);
// y = M x for a field of the matrix' input shape, result of shape `out`.
Field apply(const Matrix& m, const Field& x, const Shape& out);

// Exact product, then truncation to f's shape by `how` (thesis: T M^G).
Field product_truncated(const Field& f, const Field& g, Truncation how);

// f + s * g (same shape and box).
void axpy(Field& f, double s, const Field& g);

// Value at a box point. Cost O(K).
double evaluate(const Field& f, const std::array<double, 3>& p);

// Values on a cell-centred uniform grid of g[0] x g[1] x g[2] cells spanning
// the box, layout (z * g[1] + y) * g[0] + x. Separable: O(N n) per axis
// (thesis Fig. 6.6 "Legendre to spatial", O(NK) at worst).
std::vector<double> evaluate_grid(const Field& f, const Shape& g);

// Projection of a function of box coordinates (thesis Eq. 6.6) by tensor
// Gauss-Legendre quadrature with `nodes` points per used axis (exact when f
// is a polynomial of degree < 2 nodes - n + 1 per axis).
Field project(const std::function<double(double, double, double)>& fn, const Shape& n, const Box& box,
              size_t nodes);

// Projection of cell-centred grid samples (layout as evaluate_grid) by the
// midpoint rule; error O(h^2) for smooth fields.
Field project_grid(const std::vector<double>& samples, const Shape& g, const Shape& n, const Box& box);

// int_box f^2 dV from the coefficients (Parseval): sum F_k^2 prod 2/(2k+1)
// times the Jacobian prod half_width (used axes only).
double squared_norm(const Field& f);
// int_box f g dV (same shape).
double inner(const Field& f, const Field& g);

}  // namespace procam::legendre
