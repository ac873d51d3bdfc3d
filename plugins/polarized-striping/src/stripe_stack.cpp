// SPDX-License-Identifier: MIT
// Streaming top-2 / sum state of a light-stripe scan (see stripe_stack.hpp).
#include "stripe_stack.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace procam::polarized_striping {

StripeStack::StripeStack(uint32_t width, uint32_t height) : width_(width), height_(height) {
  const size_t n = size_t{width} * height;
  top1.assign(n, -std::numeric_limits<float>::infinity());
  top2.assign(n, -std::numeric_limits<float>::infinity());
  sum.assign(n, 0.0f);
  idx1.assign(n, 0);
  idx2.assign(n, 0);
}

namespace {

// One row, branch-free so the compiler can vectorise it. Ties: the lower
// stripe index ranks higher, so the result does not depend on frame order.
void fold_row(const float* v, size_t n, uint16_t k, float* t1, float* t2, float* sm, uint16_t* i1, uint16_t* i2) {
  for (size_t x = 0; x < n; ++x) {
    const float a = v[x], o1 = t1[x], o2 = t2[x];
    const uint16_t j1 = i1[x], j2 = i2[x];
    const bool above1 = a > o1 || (a == o1 && k < j1);
    const bool above2 = a > o2 || (a == o2 && k < j2);
    t2[x] = above1 ? o1 : (above2 ? a : o2);
    i2[x] = above1 ? j1 : (above2 ? k : j2);
    t1[x] = above1 ? a : o1;
    i1[x] = above1 ? k : j1;
    sm[x] += a;
  }
}

}  // namespace

void StripeStack::add(const procam_image& frame, uint16_t k, uint32_t threads) {
  const uint32_t w = width_;
  sdk::parallel_rows(height_, threads, [&](uint32_t y0, uint32_t y1) {
    std::vector<float> row(w);
    for (uint32_t y = y0; y < y1; ++y) {
      sdk::read_row(frame, y, row.data());
      const size_t o = size_t{y} * w;
      fold_row(row.data(), w, k, top1.data() + o, top2.data() + o, sum.data() + o, idx1.data() + o, idx2.data() + o);
    }
  });
  ++frames_;
}

StripePixel decode_stripe_pixel(const StripeStack& st, size_t i, const StripeDecodeSettings& s) noexcept {
  StripePixel p;
  const double k = st.frames();
  if (k < 3) return p;
  const double t1 = st.top1[i], t2 = st.top2[i];
  const double bg = (double(st.sum[i]) - t1 - t2) / (k - 2.0);
  p.background = static_cast<float>(std::max(0.0, bg));
  p.rise = static_cast<float>(std::max(0.0, t1 - bg));
  if (t2 >= s.saturation_dn || bg >= s.saturation_dn) return p;  // saturated backscatter: no stripe
  const double margin = s.margin_sigma * s.noise_dn * std::sqrt(1.0 + 1.0 / (k - 2.0));
  if (!(t1 - bg > margin)) return p;  // nothing above the background (zero signal under the stripe)
  const int d = int(st.idx1[i]) - int(st.idx2[i]);
  const bool adjacent = d == 1 || d == -1;
  if (adjacent && t2 - bg > margin) {  // straddles a stripe edge: weighted centre
    const double w1 = t1 - bg, w2 = t2 - bg;
    p.stripe = static_cast<float>((w1 * st.idx1[i] + w2 * st.idx2[i]) / (w1 + w2));
  } else if (t1 - t2 > margin) {
    p.stripe = static_cast<float>(st.idx1[i]);
  } else {
    return p;  // two far-apart stripes tie: ambiguous
  }
  p.valid = true;
  return p;
}

}  // namespace procam::polarized_striping
