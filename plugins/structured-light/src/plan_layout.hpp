// SPDX-License-Identifier: MIT
// Frame layout of a binary-code round: which frame is white, black, which bit
// plane (and its inverse) of which axis — and rendering it into a Plan.
//
// The layout is the single source of truth for the plan's frame order, for
// routing captured frames in the decoder, and for the order of files in an
// offline folder (plugins/structured-light/README.md "Frame order"):
//   0 "white", 1 "black", then per column plane from the most significant bit
//   k = bits-1 .. 0: "col bit k" [, "col bit k inverse"], then rows likewise.
// Thread-safety: immutable values; functions are reentrant.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "procam/plugin_sdk.hpp"
#include "stripe_code.hpp"

namespace procam::sl {

enum class Axis : uint8_t { col, row };
enum class FrameKind : uint8_t { white, black, plane, inverse };

struct FrameRole {
  FrameKind kind = FrameKind::white;
  Axis axis = Axis::col;      // plane / inverse only
  uint32_t plane = 0;         // plane index (0 = most significant bit), plane / inverse only
  int32_t partner = -1;       // plane <-> inverse frame index, -1 when none
  std::string label;          // "white", "col bit 10", "col bit 10 inverse", ...
};

struct Layout {
  bool inverse = true;        // inverse frames projected (binarize "inverse")
  uint32_t col_bits = 0;
  uint32_t row_bits = 0;      // 0 = no row code
  std::vector<FrameRole> frames;

  int32_t white_index() const { return 0; }
  int32_t black_index() const { return 1; }
};

// "col bit 10", "row bit 0 inverse"; bit_position counts from the LSB.
std::string plane_label(Axis axis, uint32_t bit_position, bool inverse);

// The layout for a column code (and optionally a row code), with or without
// projected inverses. Frame count = 2 + (col_bits + row_bits) * (inverse ? 2 : 1).
Layout make_layout(const StripeCode& cols, const StripeCode* rows, bool inverse);

// Appends the layout's frames to `plan`: projector-sized (width x height) U8
// patterns, 255 = lit, 0 = dark; column planes are vertical stripes
// (pattern(x, y) = plane bit of column x), row planes horizontal stripes.
// `cols.length` must equal width and `rows->length` height.
void render_plan(const Layout& layout, const StripeCode& cols, const StripeCode* rows,
                 uint32_t width, uint32_t height, sdk::Plan& plan);

}  // namespace procam::sl
