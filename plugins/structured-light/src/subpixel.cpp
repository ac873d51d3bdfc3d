// SPDX-License-Identifier: MIT
// Sub-pixel refinement by local line fits through stripe steps (see subpixel.hpp).
#include "subpixel.hpp"

#include <algorithm>
#include <cmath>

namespace procam::sl {

void refine_columns(const float* col, uint32_t w, uint32_t y0, uint32_t y1,
                    const SubpixelOptions& opt, float* out) {
  const auto r = static_cast<int64_t>(opt.radius);
  const auto wi = static_cast<int64_t>(w);
  for (uint32_t y = y0; y < y1; ++y) {
    const float* row = col + static_cast<size_t>(y) * w;
    float* dst = out + static_cast<size_t>(y) * w;
    for (int64_t x = 0; x < wi; ++x) {
      const float c0 = row[x];
      dst[x] = c0;
      if (!std::isfinite(c0)) continue;
      double sn = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
      float cmin = c0, cmax = c0;
      for (int64_t d = -r; d <= r; ++d) {
        const int64_t j = x + d;
        if (j < 0 || j >= wi) continue;
        const float c = row[j];
        if (!std::isfinite(c)) continue;
        const auto ad = static_cast<float>(d < 0 ? -d : d);
        if (std::fabs(c - c0) > opt.max_slope * ad + 1.0f) continue;  // other surface
        const auto xd = static_cast<double>(d), yd = static_cast<double>(c - c0);
        sn += 1;
        sx += xd;
        sy += yd;
        sxx += xd * xd;
        sxy += xd * yd;
        cmin = std::min(cmin, c);
        cmax = std::max(cmax, c);
      }
      if (sn < 3 || cmax - cmin < 1.0f) continue;  // no step in the window: nothing to localize
      const double det = sn * sxx - sx * sx;
      if (!(det > 0)) continue;
      const double a = (sy * sxx - sx * sxy) / det;  // line value at d = 0, relative to c0
      dst[x] = c0 + static_cast<float>(std::clamp(a, -1.0, 1.0));
    }
  }
}

}  // namespace procam::sl
