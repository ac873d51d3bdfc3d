// SPDX-License-Identifier: MIT
// Column-plane triangulation over a whole correspondence map (TECHNIQUES.md C9).
#include "triangulate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "procam/sdk/parallel.hpp"

namespace procam::sl {

DepthResult triangulate_columns(const CameraCalibration& cam, const Intrinsics& projector,
                                uint32_t width, uint32_t height, const float* col,
                                const float* intensity, uint32_t threads) {
  DepthResult r;
  const size_t n = size_t{width} * height;
  r.depth_mm.assign(n, std::numeric_limits<float>::quiet_NaN());
  const uint32_t bands = std::max(1u, std::min(threads, height));
  std::vector<std::vector<float>> band_points(bands);
  // One band per thread so each band's points stay in row-major order.
  sdk::parallel_rows(bands, bands, [&](uint32_t b0, uint32_t b1) {
    for (uint32_t b = b0; b < b1; ++b) {
      const uint32_t y0 = static_cast<uint32_t>(uint64_t{height} * b / bands);
      const uint32_t y1 = static_cast<uint32_t>(uint64_t{height} * (b + 1) / bands);
      std::vector<float>& pts = band_points[b];
      for (uint32_t y = y0; y < y1; ++y) {
        for (uint32_t x = 0; x < width; ++x) {
          const size_t i = size_t{y} * width + x;
          if (!std::isfinite(col[i])) continue;
          const auto p = triangulate_column(cam, projector, x, y, static_cast<double>(col[i]));
          if (!p) continue;
          const auto X = static_cast<float>(p->x), Y = static_cast<float>(p->y),
                     Z = static_cast<float>(p->z);
          if (!std::isfinite(X) || !std::isfinite(Y) || !std::isfinite(Z)) continue;
          r.depth_mm[i] = Z;
          pts.insert(pts.end(), {X, Y, Z, intensity != nullptr ? intensity[i] : 0.0f});
        }
      }
    }
  });
  size_t total = 0;
  for (const auto& p : band_points) total += p.size();
  r.points.reserve(total);
  for (const auto& p : band_points) r.points.insert(r.points.end(), p.begin(), p.end());
  r.point_count = total / 4;
  return r;
}

}  // namespace procam::sl
