// SPDX-License-Identifier: MIT
#include "procam/legendre/grid_fluid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace procam::legendre {

GridFluid::GridFluid(size_t dims, const Shape& cells, const Box& box, const GridParams& params)
    : dims_(dims), n_(cells), box_(box), params_(params) {
  if (dims != 2 && dims != 3) throw std::invalid_argument("GridFluid: dims must be 2 or 3");
  for (size_t a = 0; a < 3; ++a) {
    if (a < dims && cells[a] < 3) throw std::invalid_argument("GridFluid: need >= 3 cells per used axis");
    if (a >= dims && cells[a] != 1) throw std::invalid_argument("GridFluid: unused axes must have 1 cell");
    h_[a] = a < dims ? (box.hi[a] - box.lo[a]) / static_cast<double>(cells[a]) : 1.0;
  }
  const size_t n = cells[0] * cells[1] * cells[2];
  for (auto& v : velocity) v.assign(n, 0.0);
  for (auto& v : force) v.assign(n, 0.0);
  density.assign(n, 0.0);
  density_source.assign(n, 0.0);
}

double GridFluid::sample(const std::vector<double>& q, double fx, double fy, double fz) const {
  // (Bi/tri)linear interpolation in index space, clamped to the cell centres.
  const double f[3] = {fx, fy, fz};
  size_t i0[3], i1[3];
  double t[3];
  for (size_t a = 0; a < 3; ++a) {
    const double hi = static_cast<double>(n_[a] - 1);
    const double c = std::clamp(f[a], 0.0, hi);
    const double fl = std::floor(c);
    i0[a] = static_cast<size_t>(fl);
    i1[a] = std::min(i0[a] + 1, n_[a] - 1);
    t[a] = c - fl;
  }
  auto at = [&](size_t x, size_t y, size_t z) { return q[(z * n_[1] + y) * n_[0] + x]; };
  const double c00 = at(i0[0], i0[1], i0[2]) * (1 - t[0]) + at(i1[0], i0[1], i0[2]) * t[0];
  const double c10 = at(i0[0], i1[1], i0[2]) * (1 - t[0]) + at(i1[0], i1[1], i0[2]) * t[0];
  const double c0 = c00 * (1 - t[1]) + c10 * t[1];
  if (dims_ == 2) return c0;
  const double c01 = at(i0[0], i0[1], i1[2]) * (1 - t[0]) + at(i1[0], i0[1], i1[2]) * t[0];
  const double c11 = at(i0[0], i1[1], i1[2]) * (1 - t[0]) + at(i1[0], i1[1], i1[2]) * t[0];
  const double c1 = c01 * (1 - t[1]) + c11 * t[1];
  return c0 * (1 - t[2]) + c1 * t[2];
}

void GridFluid::advect(std::vector<double>& q, const std::vector<double>& q0, Bc, double dt) const {
  // Semi-Lagrangian: q(x) = q0(x - dt u(x)), u the velocity at the start of the step.
  const std::array<double, 3> s{dt / h_[0], dt / h_[1], dt / h_[2]};
  for (size_t z = 0; z < n_[2]; ++z)
    for (size_t y = 0; y < n_[1]; ++y)
      for (size_t x = 0; x < n_[0]; ++x) {
        const size_t i = (z * n_[1] + y) * n_[0] + x;
        const double fx = static_cast<double>(x) - s[0] * velocity[0][i];
        const double fy = static_cast<double>(y) - s[1] * velocity[1][i];
        const double fz = dims_ == 3 ? static_cast<double>(z) - s[2] * velocity[2][i] : 0.0;
        q[i] = sample(q0, fx, fy, fz);
      }
}

namespace {
// Neighbour of cell i along an axis with the wall rule: inside -> value,
// outside -> the cell itself, negated for the wall-normal velocity.
inline double minus_nb(const double* q, size_t i, size_t c, size_t stride, bool normal) {
  return c > 0 ? q[i - stride] : (normal ? -q[i] : q[i]);
}
inline double plus_nb(const double* q, size_t i, size_t c, size_t n, size_t stride, bool normal) {
  return c + 1 < n ? q[i + stride] : (normal ? -q[i] : q[i]);
}
}  // namespace

void GridFluid::gauss_seidel(std::vector<double>& q, const std::vector<double>& rhs, const std::array<double, 3>& c,
                             double denom, size_t normal_axis) const {
  // q_i = (rhs_i + sum_a c_a (q_{i-a} + q_{i+a})) / denom, in place, walls by
  // the neighbour rule above (normal_axis 3: none).
  const std::array<size_t, 3> stride{1, n_[0], n_[0] * n_[1]};
  double* d = q.data();
  for (int it = 0; it < params_.iterations; ++it)
    for_each_cell([&](size_t i, const size_t* co) {
      double s = rhs[i];
      for (size_t a = 0; a < dims_; ++a)
        s += c[a] * (minus_nb(d, i, co[a], stride[a], a == normal_axis) +
                     plus_nb(d, i, co[a], n_[a], stride[a], a == normal_axis));
      d[i] = s / denom;
    });
}

void GridFluid::diffuse(std::vector<double>& q, double coeff_dt, Bc bc) const {
  if (coeff_dt <= 0.0) return;
  // Implicit (1 - c lap) q' = q by Gauss-Seidel sweeps (Stam 1999).
  std::array<double, 3> c{};
  double denom = 1.0;
  for (size_t a = 0; a < dims_; ++a) {
    c[a] = coeff_dt / (h_[a] * h_[a]);
    denom += 2.0 * c[a];
  }
  const size_t normal = bc == Bc::kNormalX ? 0 : bc == Bc::kNormalY ? 1 : bc == Bc::kNormalZ ? 2 : 3;
  gauss_seidel(q, std::vector<double>(q), c, denom, normal);
}

void GridFluid::project() {
  const size_t n = size();
  const std::array<size_t, 3> stride{1, n_[0], n_[0] * n_[1]};
  std::vector<double> div(n), p(n, 0.0);
  for_each_cell([&](size_t i, const size_t* co) {
    double s = 0.0;
    for (size_t a = 0; a < dims_; ++a) {
      const double* u = velocity[a].data();
      s += (plus_nb(u, i, co[a], n_[a], stride[a], true) - minus_nb(u, i, co[a], stride[a], true)) / (2.0 * h_[a]);
    }
    div[i] = s;
  });
  // Poisson lap p = div u with zero-flux walls (Stam 1999's projection).
  for (double& v : div) v = -v;
  if (params_.cg_pressure) pressure_cg(std::move(div), p);
  else pressure_gauss_seidel(div, p);
  for_each_cell([&](size_t i, const size_t* co) {
    for (size_t a = 0; a < dims_; ++a)
      velocity[a][i] -= (plus_nb(p.data(), i, co[a], n_[a], stride[a], false) -
                         minus_nb(p.data(), i, co[a], stride[a], false)) / (2.0 * h_[a]);
  });
}

void GridFluid::pressure_gauss_seidel(const std::vector<double>& rhs, std::vector<double>& p) const {
  std::array<double, 3> c{};
  double denom = 0.0;
  for (size_t a = 0; a < dims_; ++a) {
    c[a] = 1.0 / (h_[a] * h_[a]);
    denom += 2.0 * c[a];
  }
  gauss_seidel(p, rhs, c, denom, 3);
}

void GridFluid::neg_laplacian(const std::vector<double>& p, std::vector<double>& out) const {
  const std::array<size_t, 3> stride{1, n_[0], n_[0] * n_[1]};
  for_each_cell([&](size_t i, const size_t* co) {
    double s = 0.0;
    for (size_t a = 0; a < dims_; ++a)
      s += (2.0 * p[i] - minus_nb(p.data(), i, co[a], stride[a], false) -
            plus_nb(p.data(), i, co[a], n_[a], stride[a], false)) / (h_[a] * h_[a]);
    out[i] = s;
  });
}

void GridFluid::pressure_cg(std::vector<double> rhs, std::vector<double>& p) const {
  // -lap is symmetric positive semidefinite (constants in its null space):
  // remove the mean of the right-hand side so the system is consistent.
  const size_t n = rhs.size();
  double mean = 0.0;
  for (double v : rhs) mean += v;
  mean /= static_cast<double>(n);
  for (double& v : rhs) v -= mean;
  std::vector<double> r = rhs, d = rhs, q(n);
  std::fill(p.begin(), p.end(), 0.0);
  double rr = 0.0;
  for (double v : r) rr += v * v;
  const double stop = params_.cg_tolerance * params_.cg_tolerance * rr;
  for (int it = 0; it < params_.cg_max_iterations && rr > stop && rr > 0.0; ++it) {
    neg_laplacian(d, q);
    double dq = 0.0;
    for (size_t i = 0; i < n; ++i) dq += d[i] * q[i];
    if (!(dq > 0.0)) break;
    const double alpha = rr / dq;
    double rr1 = 0.0;
    for (size_t i = 0; i < n; ++i) {
      p[i] += alpha * d[i];
      r[i] -= alpha * q[i];
      rr1 += r[i] * r[i];
    }
    const double beta = rr1 / rr;
    for (size_t i = 0; i < n; ++i) d[i] = r[i] + beta * d[i];
    rr = rr1;
  }
}

void GridFluid::step(double dt) {
  const Bc normal[3] = {Bc::kNormalX, Bc::kNormalY, Bc::kNormalZ};
  const auto u0 = velocity;  // advect with the velocity at the start of the step
  std::array<std::vector<double>, 3> advected = velocity;
  for (size_t a = 0; a < dims_; ++a) advect(advected[a], u0[a], normal[a], dt);
  std::vector<double> r = density;
  advect(r, density, Bc::kScalar, dt);  // still uses u0: velocity not yet replaced
  for (size_t a = 0; a < dims_; ++a) velocity[a] = std::move(advected[a]);
  for (size_t a = 0; a < dims_; ++a) diffuse(velocity[a], params_.viscosity * dt, normal[a]);
  for (size_t a = 0; a < dims_; ++a)  // same order as the Legendre step: forces after diffusion
    for (size_t i = 0; i < size(); ++i) velocity[a][i] += dt * force[a][i];
  project();
  density = std::move(r);
  diffuse(density, params_.diffusion * dt, Bc::kScalar);
  const double keep = 1.0 / (1.0 + dt * params_.dissipation);
  for (size_t i = 0; i < size(); ++i) density[i] = density[i] * keep + dt * density_source[i];
}

double GridFluid::kinetic_energy() const {
  double e = 0.0;
  for (size_t a = 0; a < dims_; ++a)
    for (double v : velocity[a]) e += v * v;
  double vol = 1.0;
  for (size_t a = 0; a < dims_; ++a) vol *= h_[a];
  return 0.5 * e * vol;
}

void GridFluid::set_from(const std::array<Field, 3>& u, const Field& r) {
  for (size_t a = 0; a < dims_; ++a) velocity[a] = evaluate_grid(u[a], n_);
  density = evaluate_grid(r, n_);
}

}  // namespace procam::legendre
