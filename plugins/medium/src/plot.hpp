// SPDX-License-Identifier: MIT
// A small grayscale line/dot plot rendered into a U8 image (the host writes
// U8 outputs as PNG): measured vs fitted radial profiles (thesis Fig. 4.10)
// and sigma-hat vs volume (Fig. 4.7). White background, black axes with tick
// marks at every decade (log) or at 5 divisions (linear); no text (the
// report carries the numbers and axis ranges).
// Threads: pure function. Units: whatever the caller plots.
#pragma once

#include <cstdint>
#include <vector>

namespace procam::medium {

struct Series {
  std::vector<double> x, y;  // same length; non-finite (or <= 0 on a log axis) points are skipped
  bool line = true;          // line through the points, else 3x3 dots
  uint8_t gray = 0;          // 0 black .. 255 white
};

struct PlotRange {
  double x0 = 0, x1 = 1, y0 = 0, y1 = 1;  // data range drawn (y in log10 when log_y)
};

// Renders the series; `range` receives the axis ranges used (for the report).
std::vector<uint8_t> plot_series(const std::vector<Series>& series, uint32_t width, uint32_t height, bool log_y,
                                 PlotRange* range = nullptr);

}  // namespace procam::medium
