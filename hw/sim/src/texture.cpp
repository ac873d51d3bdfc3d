// SPDX-License-Identifier: MIT
// Procedural chessboard albedo and its pixel-footprint average
// (procam/hw/sim/texture.hpp).
#include "procam/hw/sim/texture.hpp"

#include <cmath>

#include "procam/hw/sim/scene.hpp"

namespace procam::sim {

double ChessboardTexture::albedo_at(double a_mm, double b_mm, double outside) const {
  const double nx = cols + 1, ny = rows + 1;  // squares
  const double i = std::floor(a_mm / square_mm + 0.5 * nx);
  const double j = std::floor(b_mm / square_mm + 0.5 * ny);
  if (!std::isfinite(i) || !std::isfinite(j)) return outside;
  if (i >= 0 && i < nx && j >= 0 && j < ny) return std::fmod(i + j, 2.0) == 0.0 ? dark : light;
  const double bs = border_squares;
  if (i >= -bs && i < nx + bs && j >= -bs && j < ny + bs) return light;
  return outside;
}

Vec3 board_corner_world(const ChessboardTexture& tex, const Plane& plane, int c, int r) {
  double a = 0, b = 0;
  tex.board_corner(c, r, a, b);
  return plane.point_mm + plane.u_axis * a + plane.v_axis * b;
}

double footprint_albedo(const ChessboardTexture& tex, const Plane& plane, double outside, const Intrinsics& K,
                        const Rigid3& world_from_cam, double col, double row) {
  const Vec3& origin = world_from_cam.translation_mm;
  const double n_dot_p0 = dot(plane.normal, plane.point_mm - origin);
  auto sample = [&](double u, double v) {
    const Vec3 d = world_from_cam.rotation * K.ray(u, v);
    const double denom = dot(plane.normal, d);
    if (std::abs(denom) < 1e-12) return outside;  // ray along the plane: no footprint there
    const double t = n_dot_p0 / denom;
    if (!(t > 0)) return outside;
    const Vec3 x = origin + d * t - plane.point_mm;
    return tex.albedo_at(dot(x, plane.u_axis), dot(x, plane.v_axis), outside);
  };
  // Uniform pixel? 5 x 5 grid over the closed pixel (edges included).
  const double first = sample(col, row);
  bool uniform = true;
  for (int j = 0; j <= 4 && uniform; ++j)
    for (int i = 0; i <= 4 && uniform; ++i)
      if (sample(col - 0.5 + 0.25 * i, row - 0.5 + 0.25 * j) != first) uniform = false;
  if (uniform) return first;
  // Box filter: mean over a Fibonacci lattice of n = 377 samples, sample k
  // at ((k + 0.5)/n, frac((233 k + 0.5)/n)) (233, 377: consecutive Fibonacci
  // numbers). Its n columns and n rows of width 1/n each hold one sample, and
  // it has the lowest discrepancy of rank-1 lattices for edges of any
  // direction, so an edge's area fraction is right to ~1/n of the contrast.
  constexpr int kN = 377, kG = 233;
  double sum = 0;
  for (int k = 0; k < kN; ++k) {
    const double x = (k + 0.5) / kN;
    const double y = static_cast<double>((kG * k) % kN) / kN + 0.5 / kN;
    sum += sample(col - 0.5 + x, row - 0.5 + y);
  }
  return sum / kN;
}

}  // namespace procam::sim
