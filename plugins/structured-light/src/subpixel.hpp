// SPDX-License-Identifier: MIT
// Sub-pixel refinement of binary-code correspondences (issue 4 item 7),
// reported separately from the integer decode (output `proj_col_subpx`).
//
// A binary code gives each camera pixel the integer column c whose stripe
// contains it: the true column lies in [c - 0.5, c + 0.5] (uniform error,
// RMS 1/sqrt(12) = 0.29 px). Along a camera row the projector column is a
// smooth, monotone function of x wherever the surface is continuous, and the
// positions where the decoded column steps from c to c + 1 are the stripe
// edges (projector column c + 0.5). Refinement localizes those edges
// implicitly: a least-squares line c(x) = a + b (x - x0) through the decoded
// columns of the 2r + 1 pixels around x0 (same row) puts the line through the
// step positions, so a (the refined column) averages the quantization error
// of all the steps in the window. Neighbours are used only when consistent
// with a continuous surface: valid and |c_j - c_0| <= max_slope * |j| + 1;
// at least 3 such pixels spanning at least 2 distinct columns are required,
// else the integer column is kept. The refined value is clamped to
// [c0 - 1, c0 + 1] so refinement never turns a correct pixel into a gross
// error. Thread-safety: reentrant; callers partition rows.
#pragma once

#include <cstdint>

namespace procam::sl {

struct SubpixelOptions {
  uint32_t radius = 5;     // window half-width in camera pixels (11 px)
  float max_slope = 4.0f;  // projector columns per camera pixel still "continuous"
};

// Which kernel refine_columns runs: `best` the fastest the CPU has (AVX-512
// where available), `scalar` the definition; results are bit-identical
// (subpixel_test.cpp). Tests and benches pick; callers use the default.
enum class SubpixelKernel { best, scalar };

// Rows [y0, y1) of width-w maps: col (NaN = invalid) -> out (NaN where col is NaN).
void refine_columns(const float* col, uint32_t w, uint32_t y0, uint32_t y1,
                    const SubpixelOptions& opt, float* out,
                    SubpixelKernel kernel = SubpixelKernel::best);

}  // namespace procam::sl
