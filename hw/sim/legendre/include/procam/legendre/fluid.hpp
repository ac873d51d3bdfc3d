// SPDX-License-Identifier: MIT
// Incompressible fluid (velocity + density) simulated in the Legendre
// domain, thesis ch. 6 §6.4: advection (Eq. 6.13-6.14), implicit diffusion
// (6.16), external forces (6.17), projection (6.19-6.20) and density
// dissipation (6.21), in 2D or 3D on a closed box.
//
// Where this departs from the thesis, and why (see docs/legendre.md):
// * Every truncation is the L2 (Galerkin) one, and advection uses the
//   skew-symmetric form a.grad(q) + 1/2 div(a) q (equal to the thesis'
//   conservation form 6.12 for divergence-free a). With the walls' no-
//   penetration condition this makes the advection operator exactly
//   energy-conserving, so kinetic energy can never grow without forces.
// * exp(-dt A) (Eq. 6.14) is applied by its 4th-order Taylor polynomial
//   (the classical RK4 step for the frozen linear operator A) instead of an
//   eigen-decomposition: no nonsymmetric eigensolver is needed, and for
//   |dt| * rho(A) <= 2 sqrt(2) the step is non-expansive. That bound is the
//   CFL limit (dt_limit), computed each step from a rigorous upper bound of
//   rho(A): sum_j max|u_j| * ||D_j||.
// * The Laplacian in diffusion (6.16) is the Galerkin (weak) one,
//   -M^-1 sum_j D_j^T M D_j (natural boundary condition), symmetric negative
//   semidefinite, so implicit diffusion is non-expansive for any dt.
// * Projection (6.19-6.20) is the M-orthogonal projection onto the fields
//   with zero divergence and zero normal velocity on the box walls; Q is
//   the Lagrange multiplier of those constraints. The thesis' strong form
//   D^2 Q = div U is not solvable exactly in the truncated space.
//
// Threads: a LegendreFluid is not thread-safe; use one per thread.
// Units: box coordinates in the caller's length unit L, time in s,
// velocity L/s, viscosity/diffusion L^2/s, dissipation 1/s, force L/s^2.
#pragma once

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "procam/legendre/field.hpp"
#include "procam/legendre/linalg.hpp"

namespace procam::legendre {

enum class CflPolicy { kSubstep, kRefuse };

struct FluidParams {
  double viscosity = 0.0;    // nu in Eq. 6.1/6.16
  double diffusion = 0.0;    // kappa in Eq. 6.3 (density)
  double dissipation = 0.0;  // alpha in Eq. 6.3/6.21
  CflPolicy cfl = CflPolicy::kSubstep;
};

struct StepReport {
  bool ok = true;
  std::string error;      // why a step was refused, and what to do
  double dt_limit = 0.0;  // CFL limit at the start of the step (s); inf if at rest
  int substeps = 1;       // how many sub-steps the step was split into
  double energy_before = 0.0, energy_after = 0.0;  // kinetic energy 1/2 int |u|^2
};

class LegendreFluid {
 public:
  // dims 2 or 3, n polynomials per axis (K = n^dims coefficients per field).
  // Throws std::invalid_argument for dims/n out of range (3 <= n <= 24),
  // negative or NaN coefficients, or an empty box.
  LegendreFluid(size_t dims, size_t n, const Box& box, const FluidParams& params);

  size_t dims() const { return dims_; }
  size_t n() const { return n_; }
  const Box& box() const { return box_; }

  // State; set then call project() to make a velocity admissible.
  std::array<Field, 3> velocity;  // components x, y, z (z unused in 2D)
  Field density;
  std::array<Field, 3> force;     // B in Eq. 6.17, constant over a step
  Field density_source;           // S_r in Eq. 6.3
  // Passive scalars carried by the flow (e.g. an advected single-scattering
  // albedo): advected and diffused exactly like the density (Eq. 6.13-6.14,
  // 6.16, same kappa), no dissipation and no source. Each must have the
  // density's shape (step() refuses otherwise).
  std::vector<Field> passive;

  // Advance by dt (s): advect, diffuse, force, project; density advect,
  // diffuse, dissipate, source. Steps above the CFL limit are sub-stepped
  // or refused (params.cfl), never run unstable.
  StepReport step(double dt);

  // M-orthogonal projection of the velocity (Eq. 6.19-6.20 as above).
  void project();

  // CFL limit (s) for the current velocity; +inf when it is zero.
  double dt_limit() const;
  double kinetic_energy() const;
  // L2 norm over the box of div u, and max |u.n| over the walls (sampled).
  double divergence_l2() const;
  double wall_normal_max() const;

 private:
  struct Frozen {  // the advecting velocity of one sub-step
    std::array<Matrix, 3> m_u;  // M^{u_j} (Eq. 6.10), K x K
    Matrix m_div;               // M^{div u}
    bool moving = false;
  };
  // dq/dt = -A q with A q = Pi(u . grad q + 1/2 div(u) q), u frozen.
  Field advect_rate(const Field& q, const Frozen& f) const;
  void advect(Field& q, double dt, const Frozen& f) const;
  void diffuse(Field& q, double coeff_dt);
  StepReport substep(double dt);

  size_t dims_, n_;
  Box box_;
  FluidParams params_;
  std::vector<double> sqrt_w_;  // sqrt of the M (mass) weights per coefficient
  Matrix constraints_q_;        // orthonormal constraint rows, W^{1/2}-scaled
  Matrix stiffness_;            // W^{-1/2} S W^{-1/2}, S = sum_j D_j^T M D_j
  double diff_norm_ = 0.0;      // ||D|| on [-1,1] in the L2 norm, degree < n
  std::vector<std::pair<double, Matrix>> cholesky_cache_;  // (coeff*dt, factor), <= 4
};

}  // namespace procam::legendre
