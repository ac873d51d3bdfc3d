// SPDX-License-Identifier: MIT
#include "procam/legendre/render.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace procam::legendre {
namespace {

std::array<size_t, 3> strides(const Shape& n) { return {1, n[0], n[0] * n[1]}; }

void check_lighting(size_t dims, const Lighting& l) {
  if (l.light_axis >= dims || l.view_axis >= dims)
    throw std::invalid_argument("Lighting: light_axis/view_axis must be < dims (" + std::to_string(dims) + ")");
  if ((l.light_sign != 1 && l.light_sign != -1) || (l.view_sign != 1 && l.view_sign != -1))
    throw std::invalid_argument("Lighting: light_sign/view_sign must be +1 or -1");
  if (!(l.sigma >= 0.0) || !(l.beta >= 0.0))
    throw std::invalid_argument("Lighting: sigma and beta must be >= 0");
}

// P_k(side) for side = +-1.
double p_at_side(size_t k, int side) { return (side < 0 && k % 2 == 1) ? -1.0 : 1.0; }

}  // namespace

double Lighting::phase() const {
  const double cos_theta = light_axis == view_axis ? static_cast<double>(light_sign * view_sign) : 0.0;
  const double den = 1.0 + g * g - 2.0 * g * cos_theta;
  return (1.0 - g * g) / (4.0 * std::numbers::pi * den * std::sqrt(den));
}

LegendreRenderer::LegendreRenderer(size_t dims, size_t n_render, const Box& box, const Lighting& light)
    : dims_(dims), n_(n_render), box_(box), light_(light) {
  if (dims != 2 && dims != 3) throw std::invalid_argument("LegendreRenderer: dims must be 2 or 3");
  if (n_render < 2 || n_render > 24) throw std::invalid_argument("LegendreRenderer: n_render must be 2..24");
  check_lighting(dims, light);
  const Shape s = cube_shape(dims, n_render);
  const size_t K = s[0] * s[1] * s[2];
  const auto st = strides(s);
  const Matrix d1 = derivative_matrix(n_render);
  for (size_t a = 0; a < dims; ++a) {
    d_[a] = Matrix(K, K);
    const double scale = 1.0 / box.half_width(a);
    for (size_t i = 0; i < K; ++i) {
      const size_t ki = (i / st[a]) % n_render, base = i - ki * st[a];
      for (size_t kr = 0; kr < ki; ++kr) d_[a](base + kr * st[a], i) = scale * d1(kr, ki);
    }
  }
}

Matrix LegendreRenderer::tau_system(const Matrix& m, size_t axis, int sign) const {
  // sign * D_axis + sigma * M^R (Eq. 6.22/6.23), rows of top degree along
  // the axis replaced by "value on the inflow face" (face u = -sign).
  Matrix a = m;
  for (double& v : a.data) v *= light_.sigma;
  for (size_t i = 0; i < a.data.size(); ++i) a.data[i] += static_cast<double>(sign) * d_[axis].data[i];
  const Shape s = cube_shape(dims_, n_);
  const auto st = strides(s);
  for (size_t r = 0; r < a.rows; ++r) {
    const size_t kr = (r / st[axis]) % n_;
    if (kr != n_ - 1) continue;
    const size_t base = r - kr * st[axis];
    for (size_t c = 0; c < a.cols; ++c) a(r, c) = 0.0;
    for (size_t k = 0; k < n_; ++k) a(r, base + k * st[axis]) = p_at_side(k, -sign);
  }
  return a;
}

RenderResult LegendreRenderer::render(const Field& density, const Shape& image_cells) const {
  RenderResult out;
  if (density.d != dims_) throw std::invalid_argument("LegendreRenderer::render: density has the wrong dimension");
  const Shape s = cube_shape(dims_, n_);
  const size_t K = s[0] * s[1] * s[2];
  const auto st = strides(s);
  // M^R (Eq. 6.10), sparse per axis (Appendix A).
  const Matrix m = product_matrix(density, s, s);
  auto bc_rows = [&](size_t axis, double value_at_constant, std::vector<double>& rhs) {
    for (size_t r = 0; r < K; ++r) {
      const size_t kr = (r / st[axis]) % n_;
      if (kr == n_ - 1) rhs[r] = (r - kr * st[axis] == 0) ? value_at_constant : 0.0;
    }
  };
  // Eq. 6.22: direct transmission along the light.
  const auto lu_d = lu_factor(tau_system(m, light_.light_axis, light_.light_sign));
  const auto lu_s = lu_factor(tau_system(m, light_.view_axis, light_.view_sign));
  if (!lu_d || !lu_s) {
    out.ok = false;
    out.error = "LegendreRenderer: singular transport system; the medium is too dense for n_render (optically thick) "
                "- lower sigma or raise n_render";
    return out;
  }
  std::vector<double> id(K, 0.0);
  bc_rows(light_.light_axis, light_.irradiance, id);
  lu_solve(*lu_d, id);
  // Eq. 6.23: scattered field, source beta Omega M^R I^d, zero on the far face.
  std::vector<double> is = multiply(m, id);
  const double src = light_.beta * light_.phase();
  for (double& v : is) v *= src;
  bc_rows(light_.view_axis, 0.0, is);
  lu_solve(*lu_s, is);
  // Transmittance: the same operator with no source and 1 on the far face.
  std::vector<double> it(K, 0.0);
  bc_rows(light_.view_axis, 1.0, it);
  lu_solve(*lu_s, it);
  // Eq. 6.24: the camera-face trace, evaluated at the image cells.
  Matrix face(1, n_);
  for (size_t k = 0; k < n_; ++k) face(0, k) = p_at_side(k, light_.view_sign);
  Field fs(s, box_, dims_), ft(s, box_, dims_);
  fs.c = std::move(is);
  ft.c = std::move(it);
  out.image = image_cells;
  out.image[light_.view_axis] = 1;
  for (size_t a = dims_; a < 3; ++a) out.image[a] = 1;
  out.airlight = evaluate_grid(apply_along(fs, light_.view_axis, face), out.image);
  out.transmittance = evaluate_grid(apply_along(ft, light_.view_axis, face), out.image);
  for (size_t i = 0; i < out.airlight.size(); ++i)
    if (!std::isfinite(out.airlight[i]) || !std::isfinite(out.transmittance[i])) {
      out.ok = false;
      out.error = "LegendreRenderer: non-finite image; lower sigma or raise n_render";
      return out;
    }
  return out;
}

RenderResult render_grid(const std::vector<double>& density, size_t dims, const Shape& cells, const Box& box,
                         const Lighting& light) {
  check_lighting(dims, light);
  const size_t n = cells[0] * cells[1] * cells[2];
  if (density.size() != n) throw std::invalid_argument("render_grid: density size does not match cells");
  const auto st = strides(cells);
  auto h = [&](size_t a) { return (box.hi[a] - box.lo[a]) / static_cast<double>(cells[a]); };
  // Calls fn(first, stride, count) for every line of cells along `axis`,
  // starting at the face the ray enters (sign > 0: lo face).
  auto for_lines = [&](size_t axis, int sign, auto&& fn) {
    for (size_t i = 0; i < n; ++i) {
      if ((i / st[axis]) % cells[axis] != 0) continue;
      const size_t last = i + (cells[axis] - 1) * st[axis];
      if (sign > 0) fn(i, static_cast<std::ptrdiff_t>(st[axis]), cells[axis]);
      else fn(last, -static_cast<std::ptrdiff_t>(st[axis]), cells[axis]);
    }
  };
  // Eq. 6.4 marched: E^d at cell centres.
  std::vector<double> ed(n);
  const double hl = h(light.light_axis);
  for_lines(light.light_axis, light.light_sign, [&](size_t first, std::ptrdiff_t step, size_t count) {
    double tau = 0.0;
    for (size_t k = 0; k < count; ++k) {
      const size_t i = static_cast<size_t>(static_cast<std::ptrdiff_t>(first) + static_cast<std::ptrdiff_t>(k) * step);
      const double dt = light.sigma * density[i] * hl;
      ed[i] = light.irradiance * std::exp(-(tau + 0.5 * dt));
      tau += dt;
    }
  });
  // Eq. 6.5 marched from the camera face inwards.
  RenderResult out;
  out.image = cells;
  out.image[light.view_axis] = 1;
  out.airlight.assign(n / cells[light.view_axis], 0.0);
  out.transmittance.assign(out.airlight.size(), 1.0);
  const double hv = h(light.view_axis);
  const double src = light.beta * light.phase();
  const auto ist = strides(out.image);
  for_lines(light.view_axis, -light.view_sign, [&](size_t first, std::ptrdiff_t step, size_t count) {
    double tau = 0.0, es = 0.0;
    for (size_t k = 0; k < count; ++k) {
      const size_t i = static_cast<size_t>(static_cast<std::ptrdiff_t>(first) + static_cast<std::ptrdiff_t>(k) * step);
      const double dt = light.sigma * density[i] * hv;
      es += src * density[i] * ed[i] * hv * std::exp(-(tau + 0.5 * dt));
      tau += dt;
    }
    // Image index: the line's coordinates on the other axes.
    size_t img = 0;
    for (size_t a = 0; a < 3; ++a)
      if (a != light.view_axis) img += ((first / st[a]) % cells[a]) * ist[a];
    out.airlight[img] = es;
    out.transmittance[img] = std::exp(-tau);
  });
  return out;
}

}  // namespace procam::legendre
