// SPDX-License-Identifier: MIT
// The placement curve as a PNG (see placement.hpp): a minimal encoder (one
// IDAT of stored deflate blocks: no compression library needed) and a line plot.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "placement.hpp"

namespace procam::polarized_striping {
namespace {

uint32_t crc32(const unsigned char* p, size_t n, uint32_t c = 0xffffffffu) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t v = i;
      for (int k = 0; k < 8; ++k) v = (v & 1) ? 0xedb88320u ^ (v >> 1) : v >> 1;
      t[i] = v;
    }
    return t;
  }();
  for (size_t i = 0; i < n; ++i) c = table[(c ^ p[i]) & 0xffu] ^ (c >> 8);
  return c;
}

void put32(std::vector<unsigned char>& o, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) o.push_back(static_cast<unsigned char>(v >> s));
}

void chunk(std::vector<unsigned char>& o, const char* type, const std::vector<unsigned char>& data) {
  put32(o, static_cast<uint32_t>(data.size()));
  const size_t start = o.size();
  o.insert(o.end(), type, type + 4);
  o.insert(o.end(), data.begin(), data.end());
  put32(o, crc32(o.data() + start, o.size() - start) ^ 0xffffffffu);
}

std::vector<unsigned char> encode_png(const std::vector<unsigned char>& rgb, int w, int h) {
  std::vector<unsigned char> raw;  // filter byte 0 + row
  for (int y = 0; y < h; ++y) {
    raw.push_back(0);
    raw.insert(raw.end(), rgb.begin() + std::ptrdiff_t(y) * w * 3, rgb.begin() + std::ptrdiff_t(y + 1) * w * 3);
  }
  std::vector<unsigned char> z = {0x78, 0x01};  // zlib, stored blocks
  uint32_t a = 1, b = 0;
  for (unsigned char c : raw) a = (a + c) % 65521, b = (b + a) % 65521;
  for (size_t i = 0; i < raw.size(); i += 65535) {
    const size_t n = std::min<size_t>(65535, raw.size() - i);
    z.push_back(i + n == raw.size() ? 1 : 0);
    z.push_back(static_cast<unsigned char>(n & 0xff));
    z.push_back(static_cast<unsigned char>(n >> 8));
    z.push_back(static_cast<unsigned char>(~n & 0xff));
    z.push_back(static_cast<unsigned char>((~n >> 8) & 0xff));
    z.insert(z.end(), raw.begin() + std::ptrdiff_t(i), raw.begin() + std::ptrdiff_t(i + n));
  }
  put32(z, (b << 16) | a);
  std::vector<unsigned char> o = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<unsigned char> ihdr;
  put32(ihdr, uint32_t(w));
  put32(ihdr, uint32_t(h));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8-bit RGB
  chunk(o, "IHDR", ihdr);
  chunk(o, "IDAT", z);
  chunk(o, "IEND", {});
  return o;
}

}  // namespace

std::vector<unsigned char> placement_png(const PlacementResult& r, int w, int h) {
  std::vector<unsigned char> img(size_t(w) * size_t(h) * 3, 255);
  auto set = [&](int x, int y, std::array<unsigned char, 3> c) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    std::copy(c.begin(), c.end(), img.begin() + (std::ptrdiff_t(y) * w + x) * 3);
  };
  const int m = 30;  // margin: axes at the left and bottom
  for (int x = m; x < w - m; ++x) set(x, h - m, {0, 0, 0});
  for (int y = m; y < h - m; ++y) set(m, y, {0, 0, 0});
  if (r.curve.size() < 2) return encode_png(img, w, h);
  const double x0 = r.curve.front().separation_mm, x1 = r.curve.back().separation_mm;
  auto px = [&](double s) { return m + int(std::lround((s - x0) / (x1 - x0) * (w - 2 * m))); };
  auto plot = [&](double PlacementSample::*f, std::array<unsigned char, 3> c, double best) {
    double top = 0;
    for (const auto& s : r.curve) top = std::max(top, s.*f);
    if (!(top > 0)) return;
    auto py = [&](double v) { return h - m - int(std::lround(v / top * (h - 2 * m))); };
    for (size_t i = 0; i + 1 < r.curve.size(); ++i) {
      const int xa = px(r.curve[i].separation_mm), xb = px(r.curve[i + 1].separation_mm);
      const int ya = py(r.curve[i].*f), yb = py(r.curve[i + 1].*f);
      const int n = std::max({std::abs(xb - xa), std::abs(yb - ya), 1});
      for (int k = 0; k <= n; ++k)
        for (int t = -1; t <= 1; ++t) set(xa + (xb - xa) * k / n, ya + (yb - ya) * k / n + t, c);
    }
    for (int y = m; y < h - m; y += 3) set(px(best), y, c);  // dotted: the optimum
  };
  plot(&PlacementSample::cqm_w, {30, 60, 200}, r.best_flood_mm);
  plot(&PlacementSample::gqm_w, {200, 40, 40}, r.best_sheet_mm);
  return encode_png(img, w, h);
}

}  // namespace procam::polarized_striping
