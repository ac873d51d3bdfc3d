// SPDX-License-Identifier: MIT
#include "procam/legendre/fluid.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace procam::legendre {
namespace {

// Largest singular value of the 1D derivative matrix in the L2 norm of
// [-1, 1] (weights 2/(2k+1)), by power iteration on B^T B with
// B = W^{1/2} D W^{-1/2}; returned with a 1% margin (power iteration
// approaches from below).
double derivative_norm(size_t n) {
  const Matrix d = derivative_matrix(n);
  std::vector<double> sw(n);
  for (size_t k = 0; k < n; ++k) sw[k] = std::sqrt(2.0 / (2.0 * static_cast<double>(k) + 1.0));
  Matrix b(n, n);
  for (size_t r = 0; r < n; ++r)
    for (size_t c = 0; c < n; ++c) b(r, c) = sw[r] * d(r, c) / sw[c];
  std::vector<double> v(n, 1.0), w(n);
  double sigma2 = 0.0;
  for (int it = 0; it < 500; ++it) {
    for (size_t r = 0; r < n; ++r) {
      double s = 0;
      for (size_t c = 0; c < n; ++c) s += b(r, c) * v[c];
      w[r] = s;
    }
    for (size_t c = 0; c < n; ++c) {
      double s = 0;
      for (size_t r = 0; r < n; ++r) s += b(r, c) * w[r];
      v[c] = s;
    }
    double nv = 0;
    for (double x : v) nv += x * x;
    nv = std::sqrt(nv);
    if (nv == 0.0) return 0.0;
    sigma2 = nv;  // ||B^T B v|| with ||v|| = 1 from the previous pass
    for (double& x : v) x /= nv;
  }
  return 1.01 * std::sqrt(sigma2);
}

double max_abs_bound(const Field& f) {  // |P_k| <= 1 on [-1, 1]
  double s = 0.0;
  for (double v : f.c) s += std::fabs(v);
  return s;
}

}  // namespace

LegendreFluid::LegendreFluid(size_t dims, size_t n, const Box& box, const FluidParams& params)
    : dims_(dims), n_(n), box_(box), params_(params) {
  if (dims != 2 && dims != 3) throw std::invalid_argument("LegendreFluid: dims must be 2 or 3");
  if (n < 3 || n > 24) throw std::invalid_argument("LegendreFluid: n must be 3..24 polynomials per axis");
  if (!(params.viscosity >= 0.0) || !(params.diffusion >= 0.0) || !(params.dissipation >= 0.0))
    throw std::invalid_argument("LegendreFluid: viscosity, diffusion and dissipation must be finite and >= 0");
  for (size_t a = 0; a < dims; ++a)
    if (!(box.hi[a] > box.lo[a])) throw std::invalid_argument("LegendreFluid: box axis " + std::to_string(a) + " is empty");
  const Field zero = zero_field(dims, n, box);
  for (auto& f : velocity) f = zero;
  for (auto& f : force) f = zero;
  density = zero;
  density_source = zero;
  const size_t K = zero.size();

  // Mass weights w_k = int phi_k^2 (thesis Fig. 6.4 orthogonality, on the box).
  sqrt_w_.resize(K);
  for (size_t i = 0; i < K; ++i) {
    Field e = zero;
    e.c[i] = 1.0;
    sqrt_w_[i] = std::sqrt(squared_norm(e));
  }
  // Dense derivative operators D_a (K x K) from unit coefficients.
  std::vector<Matrix> dk(dims, Matrix(K, K));
  for (size_t a = 0; a < dims; ++a)
    for (size_t i = 0; i < K; ++i) {
      Field e = zero;
      e.c[i] = 1.0;
      const Field de = derivative(e, a);
      for (size_t r = 0; r < K; ++r) dk[a](r, i) = de.c[r];
    }
  // Constraints on the stacked velocity (component a at offset a*K):
  // divergence (K rows) and no-penetration on the 2*dims walls.
  const size_t walls = 2 * dims * (K / n);
  Matrix c(K + walls, dims * K);
  for (size_t a = 0; a < dims; ++a)
    for (size_t r = 0; r < K; ++r)
      for (size_t i = 0; i < K; ++i) c(r, a * K + i) = dk[a](r, i);
  size_t row = K;
  for (size_t a = 0; a < dims; ++a) {
    const size_t stride = a == 0 ? 1 : (a == 1 ? n : n * n);
    for (int side = -1; side <= 1; side += 2)
      for (size_t i = 0; i < K; ++i) {
        if ((i / stride) % n != 0) continue;  // one row per index of the other axes
        for (size_t k = 0; k < n; ++k)        // u_a(side) = sum_k U_k P_k(side), P_k(-1) = (-1)^k
          c(row, a * K + i + k * stride) = (side < 0 && k % 2 == 1) ? -1.0 : 1.0;
        ++row;
      }
  }
  for (size_t r = 0; r < c.rows; ++r)
    for (size_t j = 0; j < c.cols; ++j) c(r, j) /= sqrt_w_[j % K];
  constraints_q_ = orthonormal_rows(c);

  // Stiffness S = sum_a D_a^T M D_a, scaled by W^{-1/2} on both sides.
  stiffness_ = Matrix(K, K);
  for (size_t a = 0; a < dims; ++a)
    for (size_t i = 0; i < K; ++i)
      for (size_t j = i; j < K; ++j) {
        double s = 0.0;
        for (size_t r = 0; r < K; ++r) s += dk[a](r, i) * dk[a](r, j) * sqrt_w_[r] * sqrt_w_[r];
        s /= sqrt_w_[i] * sqrt_w_[j];
        stiffness_(i, j) += s;
        if (j != i) stiffness_(j, i) += s;
      }
  diff_norm_ = derivative_norm(n);
}

void LegendreFluid::project() {
  const size_t K = density.size();
  std::vector<double> v(dims_ * K);
  for (size_t a = 0; a < dims_; ++a)
    for (size_t i = 0; i < K; ++i) v[a * K + i] = sqrt_w_[i] * velocity[a].c[i];
  // Eq. 6.19-6.20: v <- v - Q^T (Q v), Q orthonormal constraint rows.
  const Matrix& q = constraints_q_;
  for (size_t r = 0; r < q.rows; ++r) {
    const double* qr = &q.data[r * q.cols];
    double d = 0.0;
    for (size_t j = 0; j < q.cols; ++j) d += qr[j] * v[j];
    for (size_t j = 0; j < q.cols; ++j) v[j] -= d * qr[j];
  }
  for (size_t a = 0; a < dims_; ++a)
    for (size_t i = 0; i < K; ++i) velocity[a].c[i] = v[a * K + i] / sqrt_w_[i];
}

double LegendreFluid::dt_limit() const {
  Field div = derivative(velocity[0], 0);
  for (size_t a = 1; a < dims_; ++a) axpy(div, 1.0, derivative(velocity[a], a));
  double rho = 0.5 * max_abs_bound(div);
  for (size_t a = 0; a < dims_; ++a) rho += max_abs_bound(velocity[a]) * diff_norm_ / box_.half_width(a);
  if (rho == 0.0) return std::numeric_limits<double>::infinity();
  return 2.0 * std::sqrt(2.0) / rho;  // RK4 is non-expansive for |dt lambda| <= 2 sqrt 2
}

double LegendreFluid::kinetic_energy() const {
  double e = 0.0;
  for (size_t a = 0; a < dims_; ++a) e += squared_norm(velocity[a]);
  return 0.5 * e;
}

double LegendreFluid::divergence_l2() const {
  Field div = derivative(velocity[0], 0);
  for (size_t a = 1; a < dims_; ++a) axpy(div, 1.0, derivative(velocity[a], a));
  return std::sqrt(squared_norm(div));
}

double LegendreFluid::wall_normal_max() const {
  double worst = 0.0;
  const int m = 12;
  for (size_t a = 0; a < dims_; ++a)
    for (int side = 0; side < 2; ++side)
      for (int i = 0; i <= m; ++i)
        for (int j = 0; j <= (dims_ == 3 ? m : 0); ++j) {
          std::array<double, 3> p{};
          const size_t b = (a + 1) % dims_, c = (a + 2) % 3;
          p[a] = side ? box_.hi[a] : box_.lo[a];
          p[b] = box_.box_from_unit(b, -1.0 + 2.0 * i / m);
          if (dims_ == 3) p[c] = box_.box_from_unit(c, -1.0 + 2.0 * j / m);
          worst = std::fmax(worst, std::fabs(evaluate(velocity[a], p)));
        }
  return worst;
}

Field LegendreFluid::advect_rate(const Field& q, const Frozen& f) const {
  // Eq. 6.13 (skew-symmetric form): -Pi(sum_j u_j d_j q + 1/2 div(u) q),
  // each product through its multiplication matrix.
  Field r = apply(f.m_div, q, q.n);
  for (double& v : r.c) v *= 0.5;
  for (size_t j = 0; j < dims_; ++j) axpy(r, 1.0, apply(f.m_u[j], derivative(q, j), q.n));
  for (double& v : r.c) v = -v;
  return r;
}

void LegendreFluid::advect(Field& q, double dt, const Frozen& f) const {
  if (!f.moving) return;  // u == 0: A == 0
  // Eq. 6.14: q <- exp(-dt A) q, by its 4th-order Taylor polynomial (RK4).
  const Field k1 = advect_rate(q, f);
  Field t = q;
  axpy(t, 0.5 * dt, k1);
  const Field k2 = advect_rate(t, f);
  t = q;
  axpy(t, 0.5 * dt, k2);
  const Field k3 = advect_rate(t, f);
  t = q;
  axpy(t, dt, k3);
  const Field k4 = advect_rate(t, f);
  for (size_t i = 0; i < q.size(); ++i) q.c[i] += dt / 6.0 * (k1.c[i] + 2.0 * k2.c[i] + 2.0 * k3.c[i] + k4.c[i]);
}

void LegendreFluid::diffuse(Field& q, double coeff_dt) {
  // Eq. 6.16, Galerkin form: (I + c W^-1/2 S W^-1/2) v' = v, v = W^1/2 q.
  if (coeff_dt <= 0.0) return;
  const Matrix* l = nullptr;
  for (const auto& [c, f] : cholesky_cache_)
    if (c == coeff_dt) l = &f;
  if (l == nullptr) {
    Matrix g = stiffness_;
    for (double& v : g.data) v *= coeff_dt;
    for (size_t i = 0; i < g.rows; ++i) g(i, i) += 1.0;
    auto f = cholesky(g);  // SPD: identity plus a PSD matrix
    if (!f) throw std::logic_error("LegendreFluid: diffusion matrix not positive definite (bug)");
    if (cholesky_cache_.size() >= 4) cholesky_cache_.erase(cholesky_cache_.begin());
    cholesky_cache_.emplace_back(coeff_dt, std::move(*f));
    l = &cholesky_cache_.back().second;
  }
  std::vector<double> v(q.size());
  for (size_t i = 0; i < v.size(); ++i) v[i] = sqrt_w_[i] * q.c[i];
  cholesky_solve(*l, v);
  for (size_t i = 0; i < v.size(); ++i) q.c[i] = v[i] / sqrt_w_[i];
}

StepReport LegendreFluid::substep(double dt) {
  StepReport r;
  Frozen f;
  Field div_u = derivative(velocity[0], 0);
  for (size_t a = 1; a < dims_; ++a) axpy(div_u, 1.0, derivative(velocity[a], a));
  for (size_t a = 0; a < dims_; ++a)
    for (double v : velocity[a].c) f.moving = f.moving || v != 0.0;
  if (f.moving) {
    for (size_t a = 0; a < dims_; ++a) f.m_u[a] = product_matrix(velocity[a], density.n, density.n);
    f.m_div = product_matrix(div_u, density.n, density.n);
  }
  for (size_t a = 0; a < dims_; ++a) {
    advect(velocity[a], dt, f);                      // Eq. 6.13-6.14
    diffuse(velocity[a], params_.viscosity * dt);    // Eq. 6.16
    axpy(velocity[a], dt, force[a]);                 // Eq. 6.17
  }
  project();                                         // Eq. 6.19-6.20
  advect(density, dt, f);
  diffuse(density, params_.diffusion * dt);
  for (Field& q : passive) {  // the same transport as the density, nothing else
    advect(q, dt, f);
    diffuse(q, params_.diffusion * dt);
  }
  const double keep = 1.0 / (1.0 + dt * params_.dissipation);  // Eq. 6.21
  for (double& v : density.c) v *= keep;
  axpy(density, dt, density_source);
  return r;
}

StepReport LegendreFluid::step(double dt) {
  StepReport r;
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    r.ok = false;
    r.error = "LegendreFluid::step: dt must be a positive finite number of seconds";
    return r;
  }
  for (const Field& q : passive)
    if (q.n != density.n || q.c.size() != density.c.size()) {
      r.ok = false;
      r.error = "LegendreFluid::step: a passive scalar's shape differs from the density's; build it like the density";
      return r;
    }
  const auto unprojected = velocity;
  project();  // the advecting velocity must satisfy the wall/divergence constraints
  r.energy_before = kinetic_energy();
  if (!std::isfinite(r.energy_before) || !std::isfinite(squared_norm(density))) {
    r.ok = false;
    r.error = "LegendreFluid::step: the velocity or density holds NaN/inf; set finite coefficients";
    velocity = unprojected;
    return r;
  }
  r.dt_limit = dt_limit();
  r.substeps = 1;
  if (dt > r.dt_limit) {
    if (params_.cfl == CflPolicy::kRefuse) {
      r.ok = false;
      r.error = "LegendreFluid::step: dt " + std::to_string(dt) + " s exceeds the CFL limit " +
                std::to_string(r.dt_limit) + " s; use a smaller dt or CflPolicy::kSubstep";
      r.energy_after = r.energy_before;
      velocity = unprojected;  // a refused step changes nothing
      return r;
    }
  }
  // Equal sub-steps under the limit; the limit is re-checked before each
  // one (forces can speed the flow up) and the rest re-split if needed.
  double left = dt;
  double h = dt / std::ceil(dt / std::fmin(dt, r.dt_limit) - 1e-12);
  int count = 0;
  while (left > 1e-15 * dt) {
    const double lim = count == 0 ? r.dt_limit : dt_limit();
    if (h > lim) h = left / std::ceil(left / lim);
    h = std::fmin(h, left);
    substep(h);
    left -= h;
    ++count;
  }
  r.substeps = count;
  r.energy_after = kinetic_energy();
  return r;
}

}  // namespace procam::legendre
