// SPDX-License-Identifier: MIT
// Stripe-averaged margins behind an image-level gate (issue 16; measured in
// docs/report/real.md, "Averaging along the stripe, and an image-level
// gate"; the numpy model that defines it: docs/report/real-stripe-model/).
//
// Why: on real 8-bit captures the finest planes of a Gray code are blurred
// to margins d = L - L̄ of a few DN, within noise_k sigma_d of zero, so the
// noise rule (decode.hpp) rejects them although the stripe is there. Along a
// stripe the projected bit is constant, so averaging d over N pixels on the
// stripe's line keeps its signal and lowers its noise; across the stripe it
// would mix the two bits (which is why no isotropic average is used).
//
// Gate (image level, after the last frame): F_noise = share of lit pixels
// (rule 1 of decode.hpp) whose finest plane is uncertain (|d| <= thr, thr =
// max(min_bit_margin C, noise_k sigma_d)) AND whose threshold is set by noise
// (noise_k sigma_d >= min_bit_margin C). On the real chessboard sample it is
// 22-32 %; on every sim scene <= 1.7 % (there the fine planes are uncertain
// because two light paths mix, coherently along the stripe, so averaging
// would make a consistent wrong sign "certain": measured 30-80 % wrong).
// Counted on every kGateRowStep-th row (a share: ~1/8 of the pixels give it
// to about 0.1 point). Mode "auto" runs rule A only when F_noise >= gate.
//
// Rule A, for each pixel the default rule rejected (lit, no clipped pair):
//   1. Stripe direction: structure tensor J = sum over planes P_t of
//      grad(g) grad(g)^T, g = G_1 * (d_p / max(C, 1)) (1-pixel Gaussian),
//      central differences, J smoothed by a 3-pixel Gaussian; P_t = the
//      planes of stripe width 8..128 projector columns (coarse enough to be
//      certain, fine enough to be dense). The stripe tangent is J's
//      eigenvector of the smaller eigenvalue: phi = atan2(2 Jxy, Jxx - Jyy) / 2,
//      t = (-sin phi, cos phi).
//   2. For every uncertain plane p (|d_p| <= thr; the tolerated finest plane
//      too), d̄_p = mean of d_p over the 2h + 1 pixels x + j t, j = -h..h
//      (nearest pixel; every one lit, unclipped and inside the image, else
//      the pixel is left alone). The plane is decided by the sign of d̄_p
//      where |d̄_p| > noise_k sigma̅_d, sigma̅_d^2 = a̅ + b̅ (W + B): a̅, b̅ are
//      fitted like the decoder's noise (fit_noise_samples) to the spread,
//      across the code's planes, of the pair sums S_p = L_p + L̄_p averaged
//      along the same lines (every kGateRowStep-th row). Noise assumption:
//      the decoder's (Gaussian, sigma^2 = a + b I per frame, pattern and
//      inverse independent) — but not independent between neighbouring
//      pixels: the fit measures how much an average of 2h + 1 pixels
//      lowers the variance instead of assuming 1 / (2h + 1) (the sample's
//      JPEG-derived noise: b / 3.6 to b / 4.5 for 7 pixels).
//   3. Certain planes never change. The pixel is then decoded by the
//      normal rule with the decided planes certain (decode_uncertain:
//      <= kTracked uncertain strict planes, the tolerated planes, ties,
//      candidates contiguous, half-width <= max_half).
// Decoded pixels keep their confidence (min margin / C: below thr / C).
// Scope: the Gray columns of BinaryRoundDecoder (method "gray", binarize
// "inverse": the rule needs the pairs' sums for its noise fit; "white" mode
// measures no noise). Rows and the multi-code methods keep their rules.
// Cost: the gate reads 1/8 of the rows; rule A (only when it runs) builds
// the tensor over the whole image (~8 float images) and visits the
// rejected pixels.
// Thread-safety: reentrant; runs on the stream's pool (not with other jobs).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "bitplane_stream.hpp"
#include "decode.hpp"

namespace procam::sl {

enum class StripeAverageMode { off, automatic, on };

struct StripeAverageParams {
  StripeAverageMode mode = StripeAverageMode::automatic;
  double gate = 0.10;        // F_noise at which "auto" runs rule A
  uint32_t half_length = 3;  // h: 2h + 1 pixels along the stripe
};

struct StripeAverageReport {
  bool available = false;   // margins kept, noise measured, planes for the tensor
  std::string why_not;      // when not available
  double f_noise = 0;       // gate statistic (share of lit sampled pixels)
  size_t gate_lit = 0;      // lit pixels sampled for it
  bool fired = false;       // rule A ran
  NoiseFit averaged;        // fit of the averaged pair sums (when fired)
  size_t candidates = 0;    // rejected pixels with a complete line
  size_t planes_decided = 0;  // uncertain planes decided by their average
  size_t added = 0;         // pixels decoded by rule A
};

inline constexpr uint32_t kGateRowStep = 8;

// Fills r.available / why_not / f_noise / gate_lit for code c of ctx.s
// (requires pairs_kept(c)).
void stripe_gate(WorkPool& pool, const DecodeContext& ctx, size_t c, StripeAverageReport& r);

// Rule A over the pixels of code c whose coord is NaN (rejected), writing
// coord / valid (may be null) / uncertainty where it decodes them. Sets
// r.fired, averaged, candidates, planes_decided, added; returns added.
// `tolerable`: per plane (decode.hpp tolerable_planes).
size_t stripe_average(WorkPool& pool, const DecodeContext& ctx, size_t c, const WordMap& words,
                      const UncertainRule& rule, const std::vector<uint8_t>& tolerable,
                      uint32_t half_length, float* coord, uint8_t* valid, float* uncertainty,
                      StripeAverageReport& r);

// Separable Gaussian of standard deviation sigma (radius int(4 sigma + 0.5),
// mirrored at the border: x[-1] = x[0]) of a w x h float image; exposed for
// tests. tmp: w * h floats.
void gaussian_blur(WorkPool& pool, const float* src, float* dst, float* tmp, uint32_t w,
                   uint32_t h, float sigma);

}  // namespace procam::sl
