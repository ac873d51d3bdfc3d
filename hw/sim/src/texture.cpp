// SPDX-License-Identifier: MIT
// Procedural chessboard albedo and its pixel-footprint average
// (procam/hw/sim/texture.hpp).
#include "procam/hw/sim/texture.hpp"

#include <cmath>
#include <fstream>

#include "procam/hw/sim/scene.hpp"

namespace procam::sim {

double ChessboardTexture::albedo_at(double a_mm, double b_mm, double outside) const {
  if (image) {
    const double x = std::floor((a_mm / image_width_mm + 0.5) * image->width);
    const double y = std::floor((0.5 - b_mm / image_height_mm) * image->height);  // row 0 at +b
    if (!(x >= 0 && x < image->width && y >= 0 && y < image->height)) return outside;  // NaN lands here too
    const uint8_t v = image->pixels[static_cast<size_t>(y) * image->width + static_cast<size_t>(x)];
    return dark + (light - dark) * (v / 255.0);
  }
  const double nx = cols + 1, ny = rows + 1;  // squares
  const double i = std::floor(a_mm / square_mm + 0.5 * nx);
  const double j = std::floor(b_mm / square_mm + 0.5 * ny);
  if (!std::isfinite(i) || !std::isfinite(j)) return outside;
  if (i >= 0 && i < nx && j >= 0 && j < ny) return std::fmod(i + j, 2.0) == 0.0 ? dark : light;
  const double bs = border_squares;
  if (i >= -bs && i < nx + bs && j >= -bs && j < ny + bs) return light;
  return outside;
}

Result<GreyBitmap> read_pgm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error(Code::not_found, "texture image '" + path + "' cannot be opened", "check the path");
  const std::string hint = "write an 8-bit binary PGM (P5, maxval 255), e.g. cv::imwrite(\"board.pgm\", grey)";
  std::string magic;
  in >> magic;
  // Header tokens, skipping # comments.
  auto next = [&in](long& v) {
    while (in >> std::ws && in.peek() == '#') in.ignore(1 << 20, '\n');
    return static_cast<bool>(in >> v);
  };
  long w = 0, h = 0, maxval = 0;
  if (magic != "P5" || !next(w) || !next(h) || !next(maxval))
    return Error(Code::invalid_argument, "texture image '" + path + "' is not a binary PGM", hint);
  if (maxval != 255 || w < 1 || h < 1 || w > 65536 || h > 65536)
    return Error(Code::invalid_argument,
                 "texture image '" + path + "': need 1..65536 px each way and maxval 255, got " + std::to_string(w) +
                     " x " + std::to_string(h) + " maxval " + std::to_string(maxval),
                 hint);
  in.get();  // the single whitespace after maxval
  GreyBitmap b;
  b.width = static_cast<uint32_t>(w);
  b.height = static_cast<uint32_t>(h);
  b.pixels.resize(static_cast<size_t>(w) * static_cast<size_t>(h));
  if (!in.read(reinterpret_cast<char*>(b.pixels.data()), static_cast<std::streamsize>(b.pixels.size())))
    return Error(Code::invalid_argument, "texture image '" + path + "' is truncated", hint);
  return b;
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
  // Rays through the pixel's four corners (lens distortion included); inside
  // the pixel the ray is their bilinear blend. Exact for a pinhole (rays are
  // affine in pixel coordinates); with distortion the error is second order
  // in the pixel size (< 1e-4 px for |k1| <= 1), and one undistortion per
  // corner replaces one per sample.
  const Vec3 d00 = K.ray(col - 0.5, row - 0.5), d10 = K.ray(col + 0.5, row - 0.5);
  const Vec3 d01 = K.ray(col - 0.5, row + 0.5), d11 = K.ray(col + 0.5, row + 0.5);
  auto sample = [&](double x, double y) {  // x, y in [0, 1] across the pixel
    const Vec3 d_cam = (d00 * (1 - x) + d10 * x) * (1 - y) + (d01 * (1 - x) + d11 * x) * y;
    const Vec3 d = world_from_cam.rotation * d_cam;
    const double denom = dot(plane.normal, d);
    if (std::abs(denom) < 1e-12) return outside;  // ray along the plane: no footprint there
    const double t = n_dot_p0 / denom;
    if (!(t > 0)) return outside;
    const Vec3 p = origin + d * t - plane.point_mm;
    return tex.albedo_at(dot(p, plane.u_axis), dot(p, plane.v_axis), outside);
  };
  // Uniform pixel? A straight edge through the pixel separates its corners,
  // so four corners and the centre of one colour mean the texture is uniform
  // over it (for squares wider than a pixel).
  const double first = sample(0.5, 0.5);
  if (sample(0, 0) == first && sample(1, 0) == first && sample(0, 1) == first && sample(1, 1) == first) return first;
  // Box filter: mean over a Fibonacci lattice of n = 377 samples, sample k
  // at ((k + 0.5)/n, frac((233 k + 0.5)/n)) (233, 377: consecutive Fibonacci
  // numbers). Its n columns and n rows of width 1/n each hold one sample, and
  // it has the lowest discrepancy of rank-1 lattices for edges of any
  // direction, so an edge's area fraction is right to ~1/n of the contrast.
  constexpr int kN = 377, kG = 233;
  double sum = 0;
  for (int k = 0; k < kN; ++k)
    sum += sample((k + 0.5) / kN, static_cast<double>((kG * k) % kN) / kN + 0.5 / kN);
  return sum / kN;
}

}  // namespace procam::sim
