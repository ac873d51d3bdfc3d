// SPDX-License-Identifier: MIT
// Albedo textures of scene objects (SCENES.md "texture"): a procedural
// chessboard, or a greyscale bitmap (e.g. a ChArUco board drawn by OpenCV),
// printed on a plane, for geometric calibration against known truth
// (docs/calibration-geometry.md).
//
// Board frame: origin at the plane's point_mm (the rectangle's centre), a
// along the plane's u_axis, b along its v_axis (= normal x u_axis), mm. The
// board has (cols + 1) x (rows + 1) squares of square_mm centred on the
// origin; square (i, j) (i along a, j along b, from 0 at the -a/-b corner)
// is dark when i + j is even. Inner corner (c, r), c < cols, r < rows, lies at
// a = (c - (cols - 1)/2) square_mm, b = (r - (rows - 1)/2) square_mm
// (board_corner()). border_squares squares of `light` surround the checker;
// beyond them the material's own albedo applies.
//
// Anti-aliasing: footprint_albedo() is the mean albedo over a camera pixel's
// footprint on the plane (box filter over the pixel, as a sensor integrates),
// so a rendered edge sits where the geometry puts it to a small fraction of
// a pixel and corner detection is sub-pixel faithful.
//
// Image textures: the bitmap covers image_width_mm x image_height_mm centred
// on the origin, column 0 at -a, row 0 at +b, so it reads unmirrored from the
// side the plane's normal faces (a right, b up there); each bitmap pixel is a uniform
// patch of albedo dark + (light - dark) * value / 255 (nearest neighbour, so
// edges that fall on bitmap pixel boundaries are exact); beyond it the
// material's albedo. The bitmap is shared, immutable after loading.
//
// Threads: plain data and pure functions. Units: mm, albedo 0..1.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "procam/base/calibration.hpp"
#include "procam/base/geometry.hpp"
#include "procam/core/status.hpp"

namespace procam::sim {

struct Plane;

// 8-bit greyscale bitmap, row-major, width * height bytes.
struct GreyBitmap {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> pixels;
};

// Reads a binary PGM (P5, maxval 255). invalid_argument / not_found saying
// what was wrong.
Result<GreyBitmap> read_pgm(const std::string& path);

struct ChessboardTexture {
  int cols = 9, rows = 7;   // inner corners along a (u_axis) and b (v_axis)
  double square_mm = 30;    // edge of one square
  double dark = 0.05, light = 0.9;  // albedo of the dark / light squares
  int border_squares = 1;   // light squares around the checker
  // Set: an image texture (cols, rows, square_mm, border_squares unused).
  std::shared_ptr<const GreyBitmap> image;
  double image_width_mm = 0, image_height_mm = 0;  // printed size of the bitmap

  // Half extents of the textured area (checker + border, or the bitmap), mm.
  double half_width_mm() const {
    return image ? 0.5 * image_width_mm : 0.5 * (cols + 1 + 2 * border_squares) * square_mm;
  }
  double half_height_mm() const {
    return image ? 0.5 * image_height_mm : 0.5 * (rows + 1 + 2 * border_squares) * square_mm;
  }
  // Albedo at board coordinates (a, b) mm; `outside` beyond the border.
  double albedo_at(double a_mm, double b_mm, double outside) const;
  // Inner corner (c, r) in board coordinates (a, b), mm.
  void board_corner(int c, int r, double& a_mm, double& b_mm) const {
    a_mm = (c - 0.5 * (cols - 1)) * square_mm;
    b_mm = (r - 0.5 * (rows - 1)) * square_mm;
  }
};

// World position of inner corner (c, r) of `tex` printed on `plane`.
Vec3 board_corner_world(const ChessboardTexture& tex, const Plane& plane, int c, int r);

// Mean albedo of `tex` on `plane` over camera pixel (col, row): pixel-centre
// convention, the pixel covers [col - 0.5, col + 0.5] x [row - 0.5, row + 0.5]
// in the (distorted) image; each sample is a camera ray (K.ray() at the
// pixel's corners, lens distortion included, blended bilinearly inside it)
// intersected with the plane. The pixel's corners and centre decide whether
// it is uniform (then that value, exactly: squares must be wider than a
// pixel); otherwise the mean of 377 samples inside it on a Fibonacci lattice
// (a straight edge's area fraction, of any direction, to ~1/377 of the
// contrast). `outside` = the material's albedo.
double footprint_albedo(const ChessboardTexture& tex, const Plane& plane, double outside, const Intrinsics& K,
                        const Rigid3& world_from_cam, double col, double row);

}  // namespace procam::sim
