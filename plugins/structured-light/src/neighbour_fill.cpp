// SPDX-License-Identifier: MIT
// Neighbour-consistent candidate selection (neighbour_fill.hpp).
#include "neighbour_fill.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>

namespace procam::sl {

namespace {

struct Decision {
  uint32_t entry;  // index into the row's FillRow
  float centre, half;
};

// The rule of neighbour_fill.hpp for one pixel; false when it does not hold.
bool choose(const float* coord, uint32_t w, uint32_t h, uint32_t x, uint32_t y,
            const int32_t* v, uint32_t nv, float inv_scale, int32_t scale,
            const NeighbourFillRule& rule, float& centre, float& half) {
  const size_t i = size_t{y} * w + x;
  float n[4];
  uint32_t nn = 0;
  // The neighbour at distance 1 (steps > 0 of them in that direction), its
  // value continued by the one at distance 2 where that one is decoded and
  // close (the coordinate's slope across the pixel, not its lag).
  auto add = [&](size_t n1, bool far_ok, size_t n2) {
    const float c1 = coord[n1];
    if (std::isnan(c1)) return;
    float pred = c1;
    if (rule.extrapolate && far_ok) {
      const float c2 = coord[n2];
      if (!std::isnan(c2) && std::fabs(c1 - c2) <= rule.max_spread) pred = 2 * c1 - c2;
    }
    n[nn++] = pred;
  };
  if (x > 0) add(i - 1, x > 1, i - 2);
  if (x + 1 < w) add(i + 1, x + 2 < w, i + 2);
  if (y > 0) add(i - w, y > 1, i - 2 * size_t{w});
  if (y + 1 < h) add(i + w, y + 2 < h, i + 2 * size_t{w});
  if (nn == 0 || nn < rule.min_neighbours) return false;
  for (uint32_t a = 1; a < nn; ++a)  // insertion sort of <= 4 values
    for (uint32_t b = a; b > 0 && n[b] < n[b - 1]; --b) std::swap(n[b], n[b - 1]);
  const float m = nn % 2 == 1 ? n[nn / 2] : 0.5f * (n[nn / 2 - 1] + n[nn / 2]);
  if (m - n[0] > rule.max_spread || n[nn - 1] - m > rule.max_spread) return false;
  int32_t lo = 0, hi = 0;
  bool any = false;
  for (uint32_t j = 0; j < nv; ++j) {  // ascending values
    const float c = static_cast<float>(v[j]) * inv_scale;
    if (std::fabs(c - m) > rule.window) continue;
    if (!any) {
      lo = hi = v[j];
      any = true;
    } else {
      if (v[j] - hi != scale) return false;  // a gap: not adjacent coordinates
      hi = v[j];
    }
  }
  if (!any) return false;
  half = 0.5f * static_cast<float>(hi - lo) * inv_scale;
  if (half > rule.max_half) return false;
  centre = 0.5f * static_cast<float>(lo + hi) * inv_scale;
  return true;
}

}  // namespace

size_t fill_from_neighbours(WorkPool& pool, uint32_t width, uint32_t height, int32_t scale,
                            const NeighbourFillRule& rule, const std::vector<FillRow>& rows,
                            float* coord, uint8_t* valid, float* uncertainty, float* confidence) {
  if (rule.passes == 0 || rows.size() != height) return 0;
  scale = std::max(scale, 1);
  const float inv_scale = 1.0f / static_cast<float>(scale);
  std::vector<std::vector<uint8_t>> done(height);
  std::vector<std::vector<Decision>> decided(height);
  for (uint32_t y = 0; y < height; ++y) done[y].assign(rows[y].x.size(), 0);
  size_t filled = 0;
  for (uint32_t pass = 0; pass < rule.passes; ++pass) {
    std::atomic<size_t> added{0};
    // Decide from the maps as they are (nothing written during this job).
    pool.run(height, [&](uint32_t y0, uint32_t y1) {
      size_t band = 0;
      for (uint32_t y = y0; y < y1; ++y) {
        const FillRow& r = rows[y];
        std::vector<Decision>& d = decided[y];
        d.clear();
        for (uint32_t j = 0; j < r.x.size(); ++j) {
          // Decoded since the candidates were listed (stripe_average.hpp): kept.
          if (done[y][j] != 0 || !std::isnan(coord[size_t{y} * width + r.x[j]])) continue;
          float centre = 0, half = 0;
          if (choose(coord, width, height, r.x[j], y, r.v.data() + r.begin[j],
                     r.begin[j + 1] - r.begin[j], inv_scale, scale, rule, centre, half))
            d.push_back({j, centre, half});
        }
        band += d.size();
      }
      added.fetch_add(band, std::memory_order_relaxed);
    });
    const size_t n = added.load();
    if (n == 0) break;
    filled += n;
    pool.run(height, [&](uint32_t y0, uint32_t y1) {
      for (uint32_t y = y0; y < y1; ++y)
        for (const Decision& d : decided[y]) {
          const size_t i = size_t{y} * width + rows[y].x[d.entry];
          done[y][d.entry] = 1;
          coord[i] = d.centre;
          uncertainty[i] = std::max(d.half, rule.min_half);
          if (valid != nullptr) valid[i] = 255;
          if (confidence != nullptr) confidence[i] *= rule.confidence_scale;
        }
    });
  }
  return filled;
}

}  // namespace procam::sl
