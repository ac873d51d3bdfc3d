// SPDX-License-Identifier: MIT
// Streaming state of a light-stripe scan (thesis §5.2, Eq. 5.7): per pixel
// the largest and second-largest value over the stripe images SI_k with their
// stripe indices, and the sum of all of them. That is enough for
//   CI = max_k SI_k                                  (Eq. 5.7, the composite)
//   stripe map = argmax_k SI_k                       (which sheet lit the pixel)
//   background = (sum - top1 - top2) / (K - 2)        (what the other sheets give)
// in O(pixels) memory whatever K, with each frame folded in as it arrives
// (add_frame may come in any order: ties go to the lower stripe index, so the
// state does not depend on the order).
//
// Why top-2 and not the median the thesis's argument suggests: a pixel is lit
// directly by at most two sheets (its own and, when it straddles a stripe
// edge, a neighbour), so the mean of the remaining K - 2 frames estimates the
// light a pixel gets when its surface point is not lit: indirect light A and
// backscatter B of the other sheets. A median would need every frame kept
// (K x pixels); this needs 5 values per pixel.
//
// Units: frame units (DN; F32 frames as stored). Threads: add() splits rows
// over `threads` workers (sdk::parallel_rows); one StripeStack is used by one
// session thread at a time. Errors: none (the caller checks the frame first).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace procam::polarized_striping {

// The pixel stride of the DOP sample (estimate_dop's rule: at most ~256k
// pixels, evenly spread): pixels 0, s, 2s, ... of the image.
inline size_t dop_sample_stride(size_t pixels) noexcept { return std::max<size_t>(1, pixels / 262144); }

// One pixel's state: the two largest values, their stripes, the sum.
struct StripeEntry {
  float top1 = 0, top2 = 0, sum = 0;
  uint32_t idx1 = 0, idx2 = 0;
};

class StripeStack {
 public:
  StripeStack() = default;
  // packed: the frames will be U8 and stripes <= 256. Then a pixel's state is
  // 6 bytes (keys (value << 8) | (255 - k) for the top two, a 16-bit sum),
  // folded with unsigned max/min only; otherwise 20 bytes of floats/indices.
  // The fold is memory-bound, so the bytes per pixel set its speed.
  //
  // expected_frames (packed only; 0: unknown): the number of frames the scan
  // plans. The add() that brings the count to it also copies the final state
  // of the DOP sample's pixels (dop_sample_stride) into compact arrays while
  // each row is still in cache, so the end of the scan reads ~1/s of the
  // stack for its DOP instead of every cache line of it.
  StripeStack(uint32_t width, uint32_t height, bool packed, uint32_t expected_frames = 0);

  // Folds stripe image k (checked: width x height, 1 channel; U8 when packed)
  // into the state.
  void add(const procam_image& frame, uint16_t k, uint32_t threads);

  uint32_t width() const noexcept { return width_; }
  uint32_t height() const noexcept { return height_; }
  uint32_t frames() const noexcept { return frames_; }
  bool packed() const noexcept { return packed_; }

  StripeEntry at(size_t i) const noexcept {
    if (packed_)
      return {float(key1_[i] >> 8), float(key2_[i] >> 8), float(sum16_[i]), 255u - (key1_[i] & 0xffu),
              255u - (key2_[i] & 0xffu)};
    return {top1_[i], top2_[i], sum_[i], idx1_[i], idx2_[i]};
  }
  // Packed state (empty unless packed()): keys (value << 8) | (255 - k) of
  // the top two, and the 16-bit sum.
  const uint16_t* key1() const noexcept { return key1_.data(); }
  const uint16_t* key2() const noexcept { return key2_.data(); }
  const uint16_t* sum16() const noexcept { return sum16_.data(); }
  float top1(size_t i) const noexcept { return packed_ ? float(key1_[i] >> 8) : top1_[i]; }
  // The DOP sample's packed state (pixel j * dop_sample_stride() for j <
  // sample_size()), valid when sample_current(): copied at the expected
  // frame count and no frame added since (else read the full arrays).
  bool sample_current() const noexcept { return packed_ && frames_ > 0 && sample_frames_ == frames_; }
  size_t sample_size() const noexcept { return sample_sum_.size(); }
  const uint16_t* sample_key1() const noexcept { return sample_key1_.data(); }
  const uint16_t* sample_key2() const noexcept { return sample_key2_.data(); }
  const uint16_t* sample_sum16() const noexcept { return sample_sum_.data(); }
  float top2(size_t i) const noexcept { return packed_ ? float(key2_[i] >> 8) : top2_[i]; }

 private:
  uint32_t width_ = 0, height_ = 0, frames_ = 0;
  bool packed_ = false;
  uint32_t expected_frames_ = 0, sample_frames_ = 0;
  std::vector<uint16_t> key1_, key2_, sum16_;  // packed
  std::vector<uint16_t> sample_key1_, sample_key2_, sample_sum_;  // packed, the DOP sample
  std::vector<float> top1_, top2_, sum_;       // general
  std::vector<uint16_t> idx1_, idx2_;
};

// What decode_stripes() makes of a StripeStack.
struct StripeDecodeSettings {
  double margin_dn = 5.0;      // how far a stripe must rise (see decode_stripe_pixel)
  double saturation_dn = 250;  // values at or above this are clipped

  // margin = margin_sigma * noise * sqrt(1 + 1/(K-2)): the noise of top1
  // minus that of the mean of K - 2 other frames.
  static StripeDecodeSettings make(double noise_dn, double margin_sigma, double saturation_dn, uint32_t frames) {
    const double k = frames > 2 ? double(frames) : 3.0;
    return {margin_sigma * noise_dn * std::sqrt(1.0 + 1.0 / (k - 2.0)), saturation_dn};
  }
};

struct StripePixel {
  bool valid = false;
  float stripe = std::numeric_limits<float>::quiet_NaN();  // fractional stripe index (see below)
  float rise = 0;             // top1 - background (>= 0), DN
  float background = 0;       // (sum - top1 - top2) / (K - 2), DN
};

// The decision for pixel i (K = stack.frames() >= 3). Inline: called per
// pixel in the end-of-scan passes. Valid when
//  - the two largest values and the background are below saturation (two
//    clipped frames cannot be told apart: saturated backscatter is invalid,
//    never a guessed stripe); a clipped top1 alone is still its stripe;
//  - top1 rises above the background by the margin (StripeDecodeSettings::make);
//  - top2 is the adjacent stripe and also rises by the margin (the pixel
//    straddles a stripe edge): the index is the two stripe indices weighted
//    by their rises above the background; otherwise top1 must beat top2 by
//    the margin (a near-tie of far-apart stripes is ambiguous: invalid).
inline StripePixel decode_stripe_pixel(const StripeStack& st, size_t i, const StripeDecodeSettings& s) noexcept {
  StripePixel p;
  const double k = st.frames();
  if (k < 3) return p;
  const StripeEntry e = st.at(i);
  const double t1 = e.top1, t2 = e.top2;
  const double bg = (double(e.sum) - t1 - t2) / (k - 2.0);
  p.background = static_cast<float>(std::max(0.0, bg));
  p.rise = static_cast<float>(std::max(0.0, t1 - bg));
  if (t2 >= s.saturation_dn || bg >= s.saturation_dn) return p;  // saturated backscatter: no stripe
  const double margin = s.margin_dn;
  if (!(t1 - bg > margin)) return p;  // nothing above the background (zero signal under the stripe)
  const int d = int(e.idx1) - int(e.idx2);
  const bool adjacent = d == 1 || d == -1;
  if (adjacent && t2 - bg > margin) {  // straddles a stripe edge: weighted centre
    const double w1 = t1 - bg, w2 = t2 - bg;
    p.stripe = static_cast<float>((w1 * e.idx1 + w2 * e.idx2) / (w1 + w2));
  } else if (t1 - t2 > margin) {
    p.stripe = static_cast<float>(e.idx1);
  } else {
    return p;  // two far-apart stripes tie: ambiguous
  }
  p.valid = true;
  return p;
}


}  // namespace procam::polarized_striping
