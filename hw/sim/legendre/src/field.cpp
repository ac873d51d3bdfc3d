// SPDX-License-Identifier: MIT
#include "procam/legendre/field.hpp"

#include <stdexcept>
#include <string>

namespace procam::legendre {
namespace {

std::string shape_str(const Shape& s) {
  return std::to_string(s[0]) + "x" + std::to_string(s[1]) + "x" + std::to_string(s[2]);
}

void require_same(const Field& f, const Field& g, const char* what) {
  if (f.n != g.n || f.d != g.d)
    throw std::invalid_argument(std::string(what) + ": shapes differ (" + shape_str(f.n) + " vs " +
                                shape_str(g.n) + "); truncate one first");
}

// Values of P_0..P_{n-1} at the midpoints of g cells along one axis:
// table[cell * n + k].
std::vector<double> midpoint_table(size_t cells, size_t n) {
  std::vector<double> t(cells * n);
  for (size_t i = 0; i < cells; ++i) {
    const double u = -1.0 + (2.0 * static_cast<double>(i) + 1.0) / static_cast<double>(cells);
    legendre_values(u, n, &t[i * n]);
  }
  return t;
}

}  // namespace

Field::Field(Shape shape, const Box& b, size_t dims) : n(shape), box(b), d(dims) {
  if (dims < 1 || dims > 3) throw std::invalid_argument("Field: dims must be 1, 2 or 3, got " + std::to_string(dims));
  for (size_t a = 0; a < 3; ++a) {
    if (shape[a] == 0) throw std::invalid_argument("Field: shape " + shape_str(shape) + " has an empty axis");
    if (a >= dims && shape[a] != 1)
      throw std::invalid_argument("Field: unused axis " + std::to_string(a) + " must have n = 1 in " + shape_str(shape));
    if (a < dims && !(b.hi[a] > b.lo[a]))
      throw std::invalid_argument("Field: box axis " + std::to_string(a) + " is empty (hi <= lo)");
  }
  c.assign(shape[0] * shape[1] * shape[2], 0.0);
}

Shape cube_shape(size_t dims, size_t n) {
  Shape s{1, 1, 1};
  for (size_t a = 0; a < dims && a < 3; ++a) s[a] = n;
  return s;
}

Field zero_field(size_t dims, size_t n, const Box& box) { return Field(cube_shape(dims, n), box, dims); }

Field apply_along(const Field& f, size_t axis, const Matrix& m) {
  if (m.cols != f.n[axis])
    throw std::invalid_argument("apply_along: matrix has " + std::to_string(m.cols) + " columns, field axis " +
                                std::to_string(axis) + " has " + std::to_string(f.n[axis]));
  Shape s = f.n;
  s[axis] = m.rows;
  Field out(s, f.box, f.d);
  // Strides of `axis` in the input and output layouts.
  const size_t in_stride = axis == 0 ? 1 : (axis == 1 ? f.n[0] : f.n[0] * f.n[1]);
  const size_t out_stride = axis == 0 ? 1 : (axis == 1 ? s[0] : s[0] * s[1]);
  const size_t inner = in_stride;  // same below the axis
  const size_t outer = f.size() / (inner * f.n[axis]);
  for (size_t o = 0; o < outer; ++o)
    for (size_t r = 0; r < m.rows; ++r) {
      const double* mr = &m.data[r * m.cols];
      double* dst = &out.c[o * inner * m.rows + r * out_stride];
      for (size_t i = 0; i < m.cols; ++i) {
        const double w = mr[i];
        if (w == 0.0) continue;
        const double* src = &f.c[o * inner * f.n[axis] + i * in_stride];
        for (size_t q = 0; q < inner; ++q) dst[q] += w * src[q];
      }
    }
  return out;
}

Field derivative(const Field& f, size_t axis) {
  Field out = apply_along(f, axis, derivative_matrix(f.n[axis]));
  const double s = 1.0 / f.box.half_width(axis);  // d/dx = (1/hw) d/du
  for (double& v : out.c) v *= s;
  return out;
}

Field integral(const Field& f, size_t axis) {
  Field out = apply_along(f, axis, integral_matrix(f.n[axis]));
  const double s = f.box.half_width(axis);  // dx = hw du
  for (double& v : out.c) v *= s;
  return out;
}

Field truncate(const Field& f, const Shape& shape, Truncation how) {
  Field out = f;
  for (size_t a = 0; a < 3; ++a) {
    if (out.n[a] == shape[a]) continue;
    Matrix m(shape[a], out.n[a]);
    if (how == Truncation::kChebyshev && shape[a] < out.n[a]) {
      m = chebyshev_truncation_matrix(shape[a], out.n[a]);
    } else {
      for (size_t k = 0; k < shape[a] && k < out.n[a]; ++k) m(k, k) = 1.0;
    }
    out = apply_along(out, a, m);
  }
  return out;
}

Field product(const Field& f, const Field& g, const Shape& out) {
  if (f.d != g.d) throw std::invalid_argument("product: fields have different dimensions");
  Field h(out, f.box, f.d);
  const auto& ex = cached_triple_product_entries(f.n[0], g.n[0], out[0]);
  const auto& ey = cached_triple_product_entries(f.n[1], g.n[1], out[1]);
  const auto& ez = cached_triple_product_entries(f.n[2], g.n[2], out[2]);
  // Thesis Eq. 6.10 / Appendix A: H_c = sum_{a,b} F_a G_b prod_axis w(a_ax, b_ax, c_ax),
  // visiting only each axis' nonzero triples, factorised one axis at a time
  // (x, then y, then z) so the cost is n^4 |Ex| + n^2 |Ey| n + |Ez| n^2
  // in 3D instead of |Ex| |Ey| |Ez| (|E| ~ n^3/4 per axis).
  const size_t fyz = f.n[1] * f.n[2], gyz = g.n[1] * g.n[2];
  const size_t cx = out[0], cy = out[1];
  // 1) x: p[(rf * gyz + rg) * cx + k] = sum_x w F[rf][i] G[rg][j].
  std::vector<double> p(fyz * gyz * cx, 0.0);
  for (size_t rf = 0; rf < fyz; ++rf) {
    const double* fr = &f.c[rf * f.n[0]];
    for (size_t rg = 0; rg < gyz; ++rg) {
      const double* gr = &g.c[rg * g.n[0]];
      double* pr = &p[(rf * gyz + rg) * cx];
      for (const TripleEntry& e : ex) pr[e.k] += e.w * fr[e.i] * gr[e.j];
    }
  }
  // 2) y: q[((fz * gz_n + gz) * cy + k) * cx + :] += w p[(fz, i), (gz, j)].
  const size_t fz_n = f.n[2], gz_n = g.n[2];
  std::vector<double> q(fz_n * gz_n * cy * cx, 0.0);
  for (size_t fz = 0; fz < fz_n; ++fz)
    for (size_t gz = 0; gz < gz_n; ++gz)
      for (const TripleEntry& e : ey) {
        const double* src = &p[((fz * f.n[1] + e.i) * gyz + gz * g.n[1] + e.j) * cx];
        double* dst = &q[((fz * gz_n + gz) * cy + e.k) * cx];
        for (size_t k = 0; k < cx; ++k) dst[k] += e.w * src[k];
      }
  // 3) z.
  const size_t plane = cy * cx;
  for (const TripleEntry& e : ez) {
    const double* src = &q[(e.i * gz_n + e.j) * plane];
    double* dst = &h.c[e.k * plane];
    for (size_t k = 0; k < plane; ++k) dst[k] += e.w * src[k];
  }
  return h;
}

Matrix product_matrix(const Field& g, const Shape& in, const Shape& out) {
  const auto& ex = cached_triple_product_entries(g.n[0], in[0], out[0]);
  const auto& ey = cached_triple_product_entries(g.n[1], in[1], out[1]);
  const auto& ez = cached_triple_product_entries(g.n[2], in[2], out[2]);
  const size_t gz = g.n[2], gy = g.n[1];
  const size_t ix = in[0], iy = in[1], ox = out[0], oy = out[1];
  // 1) x: t1[(az * gy + ay) * ix * ox + bx * ox + cx] = sum_ax w G[az][ay][ax].
  std::vector<double> t1(gz * gy * ix * ox, 0.0);
  for (size_t r = 0; r < gz * gy; ++r) {
    const double* gr = &g.c[r * g.n[0]];
    double* dst = &t1[r * ix * ox];
    for (const TripleEntry& e : ex) dst[e.j * ox + e.k] += e.w * gr[e.i];
  }
  // 2) y: t2[az][by][bx][cy][cx].
  const size_t bxcx = ix * ox;
  std::vector<double> t2(gz * iy * ix * oy * ox, 0.0);
  for (size_t az = 0; az < gz; ++az)
    for (const TripleEntry& e : ey) {
      const double* src = &t1[(az * gy + e.i) * bxcx];
      double* dst = &t2[(az * iy + e.j) * ix * oy * ox];
      for (size_t bx = 0; bx < ix; ++bx)
        for (size_t cx = 0; cx < ox; ++cx) dst[(bx * oy + e.k) * ox + cx] += e.w * src[bx * ox + cx];
    }
  // 3) z, scattered into M(c, b).
  const size_t kin = in[0] * in[1] * in[2], kout = out[0] * out[1] * out[2];
  Matrix m(kout, kin);
  for (const TripleEntry& e : ez) {
    const double* src = &t2[e.i * iy * ix * oy * ox];
    for (size_t by = 0; by < iy; ++by)
      for (size_t bx = 0; bx < ix; ++bx) {
        const size_t col = (e.j * iy + by) * ix + bx;
        const double* s2 = &src[(by * ix + bx) * oy * ox];
        for (size_t cy = 0; cy < oy; ++cy)
          for (size_t cx = 0; cx < ox; ++cx) m((e.k * oy + cy) * ox + cx, col) += e.w * s2[cy * ox + cx];
      }
  }
  return m;
}

Field apply(const Matrix& m, const Field& x, const Shape& out) {
  if (m.cols != x.size()) throw std::invalid_argument("apply: matrix/field size mismatch");
  Field y(out, x.box, x.d);
  if (m.rows != y.size()) throw std::invalid_argument("apply: matrix rows do not match the output shape");
  y.c = multiply(m, x.c);
  return y;
}

Field product_truncated(const Field& f, const Field& g, Truncation how) {
  if (how == Truncation::kL2) return product(f, g, f.n);
  Shape full{};
  for (size_t a = 0; a < 3; ++a) full[a] = f.n[a] + g.n[a] - 1;
  return truncate(product(f, g, full), f.n, how);
}

void axpy(Field& f, double s, const Field& g) {
  require_same(f, g, "axpy");
  for (size_t i = 0; i < f.c.size(); ++i) f.c[i] += s * g.c[i];
}

double evaluate(const Field& f, const std::array<double, 3>& p) {
  std::array<std::vector<double>, 3> v;
  for (size_t a = 0; a < 3; ++a)
    v[a] = legendre_values(a < f.d ? f.box.unit_from_box(a, p[a]) : 0.0, f.n[a]);
  double s = 0.0;
  for (size_t kz = 0; kz < f.n[2]; ++kz)
    for (size_t ky = 0; ky < f.n[1]; ++ky) {
      const double w = v[2][kz] * v[1][ky];
      const double* row = &f.c[f.index(0, ky, kz)];
      for (size_t kx = 0; kx < f.n[0]; ++kx) s += w * v[0][kx] * row[kx];
    }
  return s;
}

std::vector<double> evaluate_grid(const Field& f, const Shape& g) {
  // Three one-axis transforms with the midpoint tables.
  Field t = f;
  for (size_t a = 0; a < 3; ++a) {
    const size_t cells = a < f.d ? g[a] : 1;
    const std::vector<double> tab = midpoint_table(cells, f.n[a]);
    Matrix m(cells, f.n[a]);
    if (a < f.d) m.data = tab;
    else m(0, 0) = 1.0;
    t = apply_along(t, a, m);
  }
  return t.c;
}

Field project(const std::function<double(double, double, double)>& fn, const Shape& n, const Box& box,
              size_t nodes) {
  size_t d = 1;
  for (size_t a = 1; a < 3; ++a)
    if (n[a] > 1) d = a + 1;
  const Quadrature q = gauss_legendre(nodes);
  Shape m{1, 1, 1};
  for (size_t a = 0; a < d; ++a) m[a] = nodes;
  // Samples at the tensor nodes, stored as a field-shaped array, then one
  // weighted transform per axis.
  Field s(m, box, d);
  for (size_t iz = 0; iz < m[2]; ++iz)
    for (size_t iy = 0; iy < m[1]; ++iy)
      for (size_t ix = 0; ix < m[0]; ++ix) {
        const double x = box.box_from_unit(0, q.nodes[ix]);
        const double y = d > 1 ? box.box_from_unit(1, q.nodes[iy]) : 0.5 * (box.lo[1] + box.hi[1]);
        const double z = d > 2 ? box.box_from_unit(2, q.nodes[iz]) : 0.5 * (box.lo[2] + box.hi[2]);
        s.at(ix, iy, iz) = fn(x, y, z);
      }
  for (size_t a = 0; a < d; ++a) {
    Matrix t(n[a], nodes);
    std::vector<double> p(n[a]);
    for (size_t i = 0; i < nodes; ++i) {
      legendre_values(q.nodes[i], n[a], p.data());
      for (size_t k = 0; k < n[a]; ++k) t(k, i) = (2.0 * static_cast<double>(k) + 1.0) / 2.0 * q.weights[i] * p[k];
    }
    s = apply_along(s, a, t);
  }
  return s;
}

Field project_grid(const std::vector<double>& samples, const Shape& g, const Shape& n, const Box& box) {
  size_t d = 1;
  for (size_t a = 1; a < 3; ++a)
    if (n[a] > 1) d = a + 1;
  if (samples.size() != g[0] * g[1] * g[2])
    throw std::invalid_argument("project_grid: " + std::to_string(samples.size()) + " samples for grid " + shape_str(g));
  Field s(g, Box{}, 3);  // grid-shaped carrier (all axes "used" so any g is allowed)
  s.c = samples;
  for (size_t a = 0; a < 3; ++a) {
    const size_t na = a < d ? n[a] : 1;
    Matrix t(na, g[a]);
    const std::vector<double> tab = midpoint_table(g[a], na);
    const double wcell = 2.0 / static_cast<double>(g[a]);
    for (size_t i = 0; i < g[a]; ++i)
      for (size_t k = 0; k < na; ++k)
        t(k, i) = a < d ? (2.0 * static_cast<double>(k) + 1.0) / 2.0 * wcell * tab[i * na + k]
                        : 1.0 / static_cast<double>(g[a]);
    s = apply_along(s, a, t);
  }
  Field out(n, box, d);
  out.c = s.c;
  return out;
}

double inner(const Field& f, const Field& g) {
  require_same(f, g, "inner");
  double jac = 1.0;
  for (size_t a = 0; a < f.d; ++a) jac *= f.box.half_width(a);
  double s = 0.0;
  for (size_t kz = 0; kz < f.n[2]; ++kz)
    for (size_t ky = 0; ky < f.n[1]; ++ky)
      for (size_t kx = 0; kx < f.n[0]; ++kx) {
        double w = 2.0 / (2.0 * static_cast<double>(kx) + 1.0);
        if (f.d > 1) w *= 2.0 / (2.0 * static_cast<double>(ky) + 1.0);
        if (f.d > 2) w *= 2.0 / (2.0 * static_cast<double>(kz) + 1.0);
        const size_t i = f.index(kx, ky, kz);
        s += w * f.c[i] * g.c[i];
      }
  return s * jac;
}

double squared_norm(const Field& f) { return inner(f, f); }

}  // namespace procam::legendre
