// SPDX-License-Identifier: MIT
// End-of-scan estimates of every method: from the captured frames (flood
// maps or StripeStacks) to the signal S^, backscatter B^, DOP p, stripe map
// and the per-pixel quality measures (Eq. 5.6–5.10). How each term comes
// from the data is written beside each function and in the report's "model".
// Units: DN (frame units). Pure functions of their inputs; O(pixels).
#pragma once

#include <algorithm>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "params.hpp"
#include "stripe_stack.hpp"

namespace procam::polarized_striping {

struct Maps {
  uint32_t width = 0, height = 0;
  // Outputs (NaN: invalid). image: what the method shows (flood image, E_b,
  // composite CI); enhanced: S^; backscatter: B^.
  // cqm, gqm, weight: only with Config::all_maps (empty otherwise; the
  // report's means are computed either way). image_u8: the composite of a
  // packed (8-bit) striping scan, whose values are frame values; `image` is
  // empty then.
  std::vector<float> image, enhanced, backscatter, cqm, gqm, weight;
  std::vector<uint8_t> image_u8;
  std::vector<float> stripe, col;  // striping: fractional stripe index, projector column (col: see estimate_striping)
  size_t valid = 0;                // pixels with a valid enhanced value (striping: a valid stripe)
  double p = 0;                    // DOP used in Eq. 5.6–5.9 (0: unpolarised or not separable)
  nlohmann::json dop;              // how p was found
  nlohmann::json notes = nlohmann::json::array();
  // Image-level summaries for the report: means over valid pixels of CQM,
  // GQM (null where not estimable), W, CQM x W, GQM x W; mean and RMS
  // contrast (std / mean) of `image` and `enhanced`; the p used. Striping
  // scans take the means of Eq. 5.8-5.10 and of `enhanced` on every
  // quality_row_stride-th row (means_row_stride, means_pixels say which).
  nlohmann::json quality;
};

// flood: B^ = the backscatter_percentile quantile of E over unclipped pixels,
// taken as uniform (flood backscatter varies slowly; the darkest pixels see
// medium only); S^ = max(0, E - B^); p = 0. Clipped pixels are invalid.
Maps estimate_flood(std::vector<float> e, const Config& cfg, const Levels& lv, uint32_t w, uint32_t h);

// polarized-flood: p given or estimate_dop(E_b, E_w) clamped to [0, 1]; for
// p >= p_min, Eq. 5.6 per pixel (S^, B^ = (E_w - E_b) / p); for p < p_min,
// S^ = E_b + E_w and B^ unknown (NaN). Pixels with E_b or E_w clipped are invalid.
Maps estimate_polarized_flood(std::vector<float> eb, const std::vector<float>& ew, const Config& cfg,
                              const Levels& lv, uint32_t w, uint32_t h);

// striping (worst == nullptr) and polarized-striping. From each pixel's stack:
// rise = top1 - background, background = mean of the other K - 2 frames.
//  striping:  D^ = rise, B^ = background (indirect light A of other sheets
//             cannot be told from backscatter without polarisation: it is
//             counted in B^), S^ = D^, p = 0; GQM not estimable (NaN).
//  polarized: best frames E_b,k = (D + A)/2 + B(1 - p)/2 under its own sheet,
//             (A + B(1 - p))/2 under the others; worst frames with (1 + p).
//             D^ = 2 rise_b; p from estimate_dop(bg_b, bg_w) (A = 0 where the
//             pixel sees only medium); B^ = (bg_w - bg_b) / p; A^ = bg_w +
//             bg_b - B^; S^ = D^ + A^. p < p_min: B^ = bg_w + bg_b, A^ = 0.
// Stripe index -> projector column through stripe_columns(); the column map
// `col` is made only with Config::all_maps or `want_col` (triangulation).
// Which per-pixel pass runs: for packed stacks (U8 frames, K <= 256, >= 3
// frames) the one-pass kernels of striping_pass.hpp (fastest: AVX2 where the
// CPU has it, else the scalar twin); `reference` (and any stack that is not
// packed) the general double-precision pass (decode_stripe_pixel), kept as
// the packed kernels' test reference.
enum class StripingPass { fastest, avx2, scalar, reference };

// The report's quality means of a striping scan (cqm_mean, gqm_mean,
// snr_weight_mean, cqm_w_mean, gqm_w_mean, enhanced's mean and contrast) are
// taken over rows 0, s, 2s, ... with s = max(1, pixels / 262144) (every row
// below 512k pixels; 8 at 1920x1200: 150 rows, ~288k pixels), the DOP
// sample's budget: Eq. 5.8-5.10 per pixel were ~40 % of the end pass (issue 13).
// The report says so (quality.means_row_stride, quality.means_pixels).
// Sampling error: see docs/polarized-striping.md ("Quality measures").
inline uint32_t quality_row_stride(uint32_t width, uint32_t height) noexcept {
  const size_t s = std::max<size_t>(1, size_t{width} * height / 262144);
  return static_cast<uint32_t>(std::min<size_t>(s, std::max<uint32_t>(height, 1)));
}
Maps estimate_striping(const StripeStack& best, const StripeStack* worst, const Config& cfg, const Levels& lv,
                       uint32_t proj_width, StripingPass pass = StripingPass::fastest, bool want_col = false);

// Eq. 5.8–5.10 per valid pixel of a flood method (S = enhanced, B =
// backscatter; no GQM) into the maps (only when `maps`), NaN elsewhere, and
// the report's `quality` object (see Maps::quality). Rows split over
// `threads` workers.
void fill_quality(Maps& m, const Levels& lv, uint32_t threads, bool maps);

}  // namespace procam::polarized_striping
