// SPDX-License-Identifier: MIT
// The spatial-domain baseline (thesis §6.6 compares against it): Stable
// Fluids (Stam, SIGGRAPH 1999) on a cell-centred 2D/3D grid, written here
// from the paper's description: semi-Lagrangian advection with (bi/tri)linear
// interpolation, implicit diffusion and the pressure projection both by
// Gauss-Seidel sweeps, walls with no penetration (normal velocity mirrored,
// tangential free slip) and zero-flux density.
//
// Layout: value of cell (x, y, z) at (z * ny + y) * nx + x; cell centres at
// lo + (i + 1/2) h. Units as in fluid.hpp.
// Threads: a GridFluid is not thread-safe; use one per thread.
#pragma once

#include <array>
#include <vector>

#include "procam/legendre/field.hpp"

namespace procam::legendre {

struct GridParams {
  double viscosity = 0.0, diffusion = 0.0, dissipation = 0.0;
  int iterations = 20;  // Gauss-Seidel sweeps per solve (Stam's demo uses 20)
  // Pressure by conjugate gradients to a relative residual instead of the
  // fixed Gauss-Seidel sweeps: slower, but the projection is then accurate
  // on fine grids (20 sweeps barely reach the low frequencies at 256^2).
  bool cg_pressure = false;
  double cg_tolerance = 1e-8;
  int cg_max_iterations = 5000;
};

class GridFluid {
 public:
  // dims 2 or 3; cells per axis (unused axes must be 1). Throws
  // std::invalid_argument otherwise.
  GridFluid(size_t dims, const Shape& cells, const Box& box, const GridParams& params);

  size_t dims() const { return dims_; }
  const Shape& cells() const { return n_; }
  const Box& box() const { return box_; }
  size_t size() const { return density.size(); }

  std::array<std::vector<double>, 3> velocity;  // per cell, components x, y, z
  std::vector<double> density;
  std::array<std::vector<double>, 3> force;     // per cell, L/s^2
  std::vector<double> density_source;           // per cell, 1/s

  // One Stable Fluids step: advect, diffuse, forces, project (velocity);
  // advect, diffuse, dissipate, source (density). Unconditionally stable.
  void step(double dt);
  void project();
  double kinetic_energy() const;  // 1/2 sum |u|^2 dV

  // Fill from Legendre fields (sampled at cell centres) and back.
  void set_from(const std::array<Field, 3>& u, const Field& r);

 private:
  enum class Bc { kScalar, kNormalX, kNormalY, kNormalZ };
  void advect(std::vector<double>& q, const std::vector<double>& q0, Bc bc, double dt) const;
  void diffuse(std::vector<double>& q, double coeff_dt, Bc bc) const;
  void gauss_seidel(std::vector<double>& q, const std::vector<double>& rhs, const std::array<double, 3>& c,
                    double denom, size_t normal_axis) const;
  // Solves -lap p = rhs (zero-flux walls) into p.
  void pressure_gauss_seidel(const std::vector<double>& rhs, std::vector<double>& p) const;
  void pressure_cg(std::vector<double> rhs, std::vector<double>& p) const;
  void neg_laplacian(const std::vector<double>& p, std::vector<double>& out) const;
  // fn(i, coords) for every cell in layout order (Gauss-Seidel relies on it).
  template <class Fn>
  void for_each_cell(Fn&& fn) const {
    for (size_t z = 0; z < n_[2]; ++z)
      for (size_t y = 0; y < n_[1]; ++y)
        for (size_t x = 0; x < n_[0]; ++x) {
          const size_t co[3] = {x, y, z};
          fn((z * n_[1] + y) * n_[0] + x, co);
        }
  }
  double sample(const std::vector<double>& q, double fx, double fy, double fz) const;

  size_t dims_;
  Shape n_;
  Box box_;
  GridParams params_;
  std::array<double, 3> h_{};
};

}  // namespace procam::legendre
