// SPDX-License-Identifier: MIT
// Streaming HDR merge of an exposure bracket into a linear radiance map
// (thesis §4.2.1: ~25 exposures, 1/500 s … 10 s; TECHNIQUES M4).
//
// Per pixel, over the frames where it is neither saturated nor dark,
//   radiance = sum_k w_k x_k / t_k / sum_k w_k,   x_k = response(DN_k) - black,
// with w_k = t_k (exposure-proportional weights): under shot noise
// var(x_k / t_k) ∝ 1 / t_k, so w = t is the inverse-variance (noise-optimal)
// weight, and the estimate is simply sum x_k / sum t_k (total signal over
// total time). Not a hat: the top of the range is excluded outright
// (DN >= saturation x full scale). Samples below the floor are read-noise
// limited (constant variance): for them the noise-optimal estimate of
// x = L t is least squares, sum t x / sum t^2, i.e. weight w = t^2 on x / t;
// they get w = kDark t^2 (kDark = 1e-12 /us), so a pixel dark in every frame
// (a black tank corner, an absorber's background) still gets a finite
// estimate dominated by its longest exposures, while any above-floor sample
// (w = t >= 1 us) outweighs them by > 1000x up to t = 1e9 us. A pixel
// saturated in every frame has no estimate: NaN, counted in saturated_pixels().
// x is not clipped at 0: below the black level, read noise must average out
// (clipping would bias dark pixels up by ~0.4 noise sigma), so a pixel with
// no signal may get a slightly negative radiance.
//
// Streaming: add() folds one frame into two float accumulators per pixel and
// keeps nothing else, so frames may come in any order.
// Camera response: `linear_from_dn` maps each integer DN code to linear
// units (identity for a linear camera; gamma or a measured LUT otherwise).
// Units: DN in, DN per microsecond out. Threads: add() splits rows over
// `threads` workers (sdk::parallel_rows); an HdrMerge is used by one thread
// at a time. Errors: add() returns sdk::bad_frame for a wrong size or a
// frame whose type differs from the first.
#pragma once

#include <cstdint>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace procam::medium {

constexpr float kDark = 1e-12f;  // weight of a below-floor sample: kDark t (per us), see above

struct HdrSettings {
  double black_dn = 0;          // subtracted after linearisation
  double saturation = 0.98;     // DN >= this fraction of full scale: excluded
  double floor = 0.02;          // x below this fraction of full scale: weight 1e-6 t
  double gamma = 1.0;           // response: linear = full_scale (DN / full_scale)^gamma (1 = linear)
  std::vector<double> lut;      // if not empty: linear value per DN code (overrides gamma)
  uint32_t camera_bits = 16;    // the rig's camera bit depth: U16 frames that claim more (a 12-bit
                                // camera saved as 16-bit PNG) are read with this full scale
};

class HdrMerge {
 public:
  HdrMerge(uint32_t width, uint32_t height, HdrSettings s);

  // Folds `frame` (1 channel, width x height, U8/U16/F32) taken at
  // `exposure_us` > 0 into the sums. Leaves the state unchanged on error.
  sdk::Error add(const procam_image& frame, double exposure_us, uint32_t threads);

  // The radiance map (DN/us; NaN where saturated in every frame).
  std::vector<float> radiance() const;
  uint64_t saturated_pixels() const;
  uint32_t frames() const noexcept { return frames_; }
  double full_scale() const noexcept { return full_scale_; }

 private:
  sdk::Error prepare(const procam_image& frame);
  uint32_t w_, h_;
  HdrSettings s_;
  std::vector<float> sum_x_, sum_t_;  // sum w x / t and sum w, per pixel (w in units of t)
  std::vector<float> lin_;            // integer frames: linear value x per code (black removed)
  std::vector<float> a_;              // per code: 0 saturated, 1 good, -1 dark
  std::vector<float> wx_, wt_;        // per code, this frame: w x and w t
  uint32_t type_ = 0, bits_ = 0, frames_ = 0;
  double full_scale_ = 0;
};

}  // namespace procam::medium
