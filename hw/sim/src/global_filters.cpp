// SPDX-License-Identifier: MIT
// Grid filters of the diffusion model: Gaussian kernels, separable blur, 2×2 pyramid down/up sampling.
#include <algorithm>
#include <cmath>
#include <vector>

#include "global_internal.hpp"
#include "parallel.hpp"

namespace procam::sim::detail {

// Gaussian of σ sampled at integers, truncated at 3σ (rounded up; at least
// 1), normalised.
std::vector<float> gaussian_kernel(double sigma) {
  if (!(sigma > 1e-3)) return {1.f};
  const int r = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
  std::vector<double> w(static_cast<size_t>(2 * r + 1));
  double sum = 0;
  for (int j = -r; j <= r; ++j) {
    w[static_cast<size_t>(j + r)] = std::exp(-0.5 * j * j / (sigma * sigma));
    sum += w[static_cast<size_t>(j + r)];
  }
  std::vector<float> out(w.size());
  for (size_t k = 0; k < w.size(); ++k) out[k] = static_cast<float>(w[k] / sum);
  return out;
}

// Separable blur of a w×h grid with `kernel` (zero outside): out = K ∗ in.
// Both passes run along rows as one saxpy per tap (vectorised), rows split
// over threads. `tmp` is scratch of w·h floats.
void blur_separable(const float* in, float* out, float* tmp, uint32_t w, uint32_t h,
                    const std::vector<float>& kernel, int threads) {
  const auto r = static_cast<int64_t>(kernel.size() / 2);
  const auto W = static_cast<int64_t>(w), H = static_cast<int64_t>(h);
  detail::parallel_rows(h, threads, [&](uint32_t b, uint32_t e) {
    for (uint32_t y = b; y < e; ++y) {
      const float* src = in + size_t{y} * w;
      float* dst = tmp + size_t{y} * w;
      std::fill(dst, dst + w, 0.f);
      for (int64_t j = -r; j <= r; ++j) {
        const float k = kernel[static_cast<size_t>(j + r)];
        const int64_t lo = std::max<int64_t>(0, -j), hi = std::min<int64_t>(W, W - j);
        for (int64_t x = lo; x < hi; ++x) dst[x] += k * src[x + j];
      }
    }
  });
  detail::parallel_rows(h, threads, [&](uint32_t b, uint32_t e) {
    for (uint32_t y = b; y < e; ++y) {
      float* dst = out + size_t{y} * w;
      std::fill(dst, dst + w, 0.f);
      for (int64_t j = -r; j <= r; ++j) {
        const int64_t yy = static_cast<int64_t>(y) + j;
        if (yy < 0 || yy >= H) continue;
        const float k = kernel[static_cast<size_t>(j + r)];
        const float* src = tmp + static_cast<size_t>(yy) * w;
        for (uint32_t x = 0; x < w; ++x) dst[x] += k * src[x];
      }
    }
  });
}

// Level l+1 of a pyramid: sums of 2×2 cells of level l (cells past the edge are 0).
void sum_2x2(const float* fine, uint32_t fw, uint32_t fh, float* coarse, uint32_t cw, uint32_t ch) {
  for (uint32_t y = 0; y < ch; ++y)
    for (uint32_t x = 0; x < cw; ++x) {
      float s = 0;
      for (uint32_t dy = 0; dy < 2; ++dy)
        for (uint32_t dx = 0; dx < 2; ++dx) {
          const uint32_t fx = 2 * x + dx, fy = 2 * y + dy;
          if (fx < fw && fy < fh) s += fine[size_t{fy} * fw + fx];
        }
      coarse[size_t{y} * cw + x] = s;
    }
}

// fine += bilinear 2× upsampling of coarse (cell centres: fine i ↔ coarse
// i/2 − ¼, i.e. weights ¾ / ¼ to the nearer / farther coarse cell; clamped).
void add_upsampled_2x(const float* coarse, uint32_t cw, uint32_t ch, float* fine, uint32_t fw, uint32_t fh) {
  auto taps = [](uint32_t i, uint32_t n, uint32_t& a, uint32_t& b) {
    const uint32_t k = i / 2;
    a = k;
    if (i % 2 == 0) b = k > 0 ? k - 1 : k;
    else b = k + 1 < n ? k + 1 : k;
  };
  for (uint32_t y = 0; y < fh; ++y) {
    uint32_t ya, yb;
    taps(y, ch, ya, yb);
    const float* ra = coarse + size_t{std::min(ya, ch - 1)} * cw;
    const float* rb = coarse + size_t{std::min(yb, ch - 1)} * cw;
    float* dst = fine + size_t{y} * fw;
    for (uint32_t x = 0; x < fw; ++x) {
      uint32_t xa, xb;
      taps(x, cw, xa, xb);
      xa = std::min(xa, cw - 1);
      xb = std::min(xb, cw - 1);
      const float top = 0.75f * ra[xa] + 0.25f * ra[xb];
      const float bot = 0.75f * rb[xa] + 0.25f * rb[xb];
      dst[x] += 0.75f * top + 0.25f * bot;
    }
  }
}

}  // namespace procam::sim::detail
