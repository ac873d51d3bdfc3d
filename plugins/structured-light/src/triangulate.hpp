// SPDX-License-Identifier: MIT
// Triangulation of decoded projector columns into depth maps and point clouds
// (TECHNIQUES.md C9): per camera pixel, the camera ray meets the plane of its
// projector column (procam::triangulate_column, core/calibration.hpp).
//
// Units: mm, camera frame (x right, y down, z forward). Pixel centres at
// integer coordinates; a decoded integer column c is the centre of projector
// column c, so the column plane is x_p / z_p = (c - cx_p) / fx_p.
// Thread-safety: reentrant; uses `threads` worker threads internally.
#pragma once

#include <cstdint>
#include <vector>

#include "procam/base/calibration.hpp"

namespace procam::sl {

struct DepthResult {
  std::vector<float> depth_mm;  // width*height, z of the point, NaN where no point
  std::vector<float> points;    // rows of x, y, z (mm), intensity; row-major pixel order
  uint64_t point_count = 0;
};

// `col` holds width*height projector columns (NaN = invalid pixel);
// `intensity` the per-pixel value stored as the points' 4th field (may be
// null: 0). A pixel whose ray is parallel to its column plane or whose point
// lies behind the camera or projector gets NaN depth and no point.
DepthResult triangulate_columns(const CameraCalibration& cam, const Intrinsics& projector,
                                uint32_t width, uint32_t height, const float* col,
                                const float* intensity, uint32_t threads);

}  // namespace procam::sl
