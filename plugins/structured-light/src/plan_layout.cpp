// SPDX-License-Identifier: MIT
// Frame layout and pattern rendering of binary-code rounds.
#include "plan_layout.hpp"

#include <algorithm>
#include <stdexcept>

namespace procam::sl {

std::string plane_label(Axis axis, uint32_t bit_position, bool inverse) {
  return std::string(axis == Axis::col ? "col" : "row") + " bit " +
         std::to_string(bit_position) + (inverse ? " inverse" : "");
}

namespace {
void add_axis(Layout& layout, Axis axis, uint32_t bits) {
  for (uint32_t p = 0; p < bits; ++p) {
    const uint32_t position = bits - 1 - p;
    FrameRole plane{FrameKind::plane, axis, p, -1, plane_label(axis, position, false)};
    const auto plane_index = static_cast<int32_t>(layout.frames.size());
    layout.frames.push_back(plane);
    if (layout.inverse) {
      FrameRole inv{FrameKind::inverse, axis, p, plane_index, plane_label(axis, position, true)};
      layout.frames.push_back(inv);
      layout.frames[static_cast<size_t>(plane_index)].partner = plane_index + 1;
    }
  }
}
}  // namespace

Layout make_layout(const StripeCode& cols, const StripeCode* rows, bool inverse) {
  Layout layout;
  layout.inverse = inverse;
  layout.col_bits = cols.bits;
  layout.row_bits = rows != nullptr ? rows->bits : 0;
  layout.frames.push_back({FrameKind::white, Axis::col, 0, -1, "white"});
  layout.frames.push_back({FrameKind::black, Axis::col, 0, -1, "black"});
  add_axis(layout, Axis::col, layout.col_bits);
  if (rows != nullptr) add_axis(layout, Axis::row, layout.row_bits);
  return layout;
}

void render_plan(const Layout& layout, const StripeCode& cols, const StripeCode* rows,
                 uint32_t width, uint32_t height, sdk::Plan& plan) {
  if (cols.length != width || (rows != nullptr && rows->length != height))
    throw std::invalid_argument("render_plan: code lengths do not match the projector size");
  for (const FrameRole& role : layout.frames) {
    const uint32_t i = plan.add_frame(role.label, width, height, PROCAM_PIXEL_U8);
    std::span<uint8_t> px = plan.pattern_u8(i);
    switch (role.kind) {
      case FrameKind::white: std::fill(px.begin(), px.end(), uint8_t{255}); break;
      case FrameKind::black: break;  // zero-filled
      case FrameKind::plane:
      case FrameKind::inverse: {
        const uint8_t on = role.kind == FrameKind::plane ? 255 : 0;
        const uint8_t off = role.kind == FrameKind::plane ? 0 : 255;
        if (role.axis == Axis::col) {
          std::vector<uint8_t> line(width);
          for (uint32_t x = 0; x < width; ++x) line[x] = cols.bit(role.plane, x) ? on : off;
          for (uint32_t y = 0; y < height; ++y)
            std::copy(line.begin(), line.end(), px.begin() + std::ptrdiff_t{y} * width);
        } else {
          for (uint32_t y = 0; y < height; ++y)
            std::fill_n(px.begin() + std::ptrdiff_t{y} * width, width,
                        rows->bit(role.plane, y) ? on : off);
        }
        break;
      }
    }
  }
}

}  // namespace procam::sl
