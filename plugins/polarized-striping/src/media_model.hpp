// SPDX-License-Identifier: MIT
// Light transport in a scattering medium as the polarized-striping plugin
// estimates it from frames (thesis §5.1–5.3): the signal S = D + A (direct +
// indirect, Eq. 5.1–5.2), the backscatter B with degree of polarization p,
// Eq. 5.6 signal recovery from the best/worst analyser images, the DOP
// estimate, and the image-quality measures CQM, GQM and the SNR weight W
// (Eq. 5.8–5.10) with their image-level summaries.
//
// Units: DN of the frames (any bit depth; callers pass the frame's full
// scale where a noise level is a fraction of it). Pure functions: reentrant,
// no state, no exceptions except std::bad_alloc.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <nlohmann/json.hpp>

namespace procam::polarized_striping {

inline constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Eq. 5.6 with its guards. E_b (analyser crossed to the source polariser) and
// E_w (parallel) per Eq. 5.4–5.5:
//   S^ = E_b (1 + 1/p) + E_w (1 - 1/p)  ==  (E_b + E_w) - (E_w - E_b) / p
//   B^ = (E_w - E_b) / p
// p is clamped to [p_min, 1] by the caller (p -> 0 divides noise by p; p -> 1
// is regular: S^ = 2 E_b). Noise can make E_w < E_b or S^ < 0: both results
// are clamped to [0, E_b + E_w], so S^ + B^ = E_b + E_w always holds.
struct SignalBackscatter {
  float signal, backscatter;
};
SignalBackscatter signal_from_polarized(float e_best, float e_worst, double p) noexcept;

// Degree of polarization of the backscatter from a best/worst pair of maps
// (Eq. 5.4–5.5): r = (E_w - E_b) / (E_w + E_b) = B p / (S + B) <= p, with
// equality exactly where the pixel sees no object (S = 0). Assumption: some
// pixels see only medium (water beyond the object, gaps); p^ is the
// `percentile` quantile of r over pixels whose E_w + E_b exceeds `min_sum`
// (so r's noise, ~ sigma sqrt(2) / (E_w + E_b), is small). A high quantile
// rather than the maximum: robust to noise outliers. With fewer than
// `min_pixels` such pixels the result is NaN (the caller says why).
// `best`/`worst` are equal-sized; NaN entries are skipped. Large maps are
// sampled on an even stride (at most ~256k pixels).
double estimate_dop(std::span<const float> best, std::span<const float> worst, double min_sum, double percentile,
                    size_t min_pixels = 16);

// The q-quantile (0..1, linear interpolation) of the finite values; NaN when
// there are none. Reorders a copy, O(n).
double quantile(std::vector<float> values, double q);

// Order-preserving unsigned key of a finite float (negatives flipped; a < b
// <=> key(a) < key(b)), and back: quantiles by radix selection on the keys.
uint32_t key_from_float(float v) noexcept;
float float_from_key(uint32_t k) noexcept;

// Eq. 5.8: CQM = S / (S + B (1 - p)); 0 where the denominator is not positive.
double cqm(double s, double b, double p) noexcept;
// Eq. 5.9: GQM = (D + B (1 - p)) / (D + A + B (1 - p)); 0 where the
// denominator is not positive.
double gqm(double d, double a, double b, double p) noexcept;
// Eq. 5.10: W = 1 / (1 + exp(-(S - mu) / z)); z > 0 (z = 0: a step at mu).
double snr_weight(double s, double mu, double z) noexcept;

// Image-level summary of a map over its finite pixels: count, mean, and the
// RMS contrast std / mean (0 when the mean is not positive).
struct Summary {
  size_t pixels = 0;
  double mean = 0, rms_contrast = 0;
};
Summary summarize(std::span<const float> map);
// The same from running sums of the finite values, their squares and count.
Summary summary_from_sums(double sum, double sum2, size_t n);
nlohmann::json to_json(const Summary& s);

}  // namespace procam::polarized_striping
