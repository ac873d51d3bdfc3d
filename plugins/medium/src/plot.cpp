// SPDX-License-Identifier: MIT
// Grayscale plots (see plot.hpp).
#include "plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace procam::medium {

std::vector<uint8_t> plot_series(const std::vector<Series>& series, uint32_t width, uint32_t height, bool log_y,
                                 PlotRange* range) {
  std::vector<uint8_t> img(size_t{width} * height, 255);
  const int w = int(width), h = int(height), m = 24;  // margin around the plot area
  auto set = [&](int x, int y, uint8_t v) {
    if (x >= 0 && y >= 0 && x < w && y < h) img[size_t(y) * width + size_t(x)] = v;
  };
  auto ok = [&](double x, double y) { return std::isfinite(x) && std::isfinite(y) && (!log_y || y > 0); };
  PlotRange r{1e300, -1e300, 1e300, -1e300};
  for (const Series& s : series)
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!ok(s.x[i], s.y[i])) continue;
      const double y = log_y ? std::log10(s.y[i]) : s.y[i];
      r.x0 = std::min(r.x0, s.x[i]), r.x1 = std::max(r.x1, s.x[i]);
      r.y0 = std::min(r.y0, y), r.y1 = std::max(r.y1, y);
    }
  if (!(r.x0 <= r.x1)) r = {0, 1, 0, 1};
  if (!log_y) r.y0 = std::min(r.y0, 0.0), r.x0 = std::min(r.x0, 0.0);  // linear plots include the origin
  if (r.x1 - r.x0 <= 0) r.x1 = r.x0 + 1;
  if (r.y1 - r.y0 <= 0) r.y1 = r.y0 + 1;
  const double pad = 0.05 * (r.y1 - r.y0);
  r.y0 -= pad, r.y1 += pad;
  if (range != nullptr) *range = r;
  if (w <= 2 * m || h <= 2 * m) return img;
  auto px = [&](double x) { return m + int(std::lround((x - r.x0) / (r.x1 - r.x0) * (w - 2 * m))); };
  auto py = [&](double y) { return h - m - int(std::lround((y - r.y0) / (r.y1 - r.y0) * (h - 2 * m))); };
  for (int x = m; x <= w - m; ++x) set(x, h - m, 0);
  for (int y = m; y <= h - m; ++y) set(m, y, 0);
  if (log_y) {
    for (double d = std::ceil(r.y0); d <= r.y1; d += 1)
      for (int x = m - 5; x < m; ++x) set(x, py(d), 0);
  } else {
    for (int k = 0; k <= 5; ++k)
      for (int x = m - 5; x < m; ++x) set(x, py(r.y0 + (r.y1 - r.y0) * k / 5), 0);
  }
  for (int k = 0; k <= 5; ++k)
    for (int y = h - m; y < h - m + 5; ++y) set(px(r.x0 + (r.x1 - r.x0) * k / 5), y, 0);
  for (const Series& s : series) {
    int lx = 0, ly = 0;
    bool have = false;
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!ok(s.x[i], s.y[i])) {
        have = false;
        continue;
      }
      const int x = px(s.x[i]), y = py(log_y ? std::log10(s.y[i]) : s.y[i]);
      if (s.line && have) {
        const int n = std::max({std::abs(x - lx), std::abs(y - ly), 1});
        for (int k = 0; k <= n; ++k) set(lx + (x - lx) * k / n, ly + (y - ly) * k / n, s.gray);
      } else if (!s.line) {
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) set(x + dx, y + dy, s.gray);
      }
      lx = x, ly = y, have = true;
    }
  }
  return img;
}

}  // namespace procam::medium
