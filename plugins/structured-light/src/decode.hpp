// SPDX-License-Identifier: MIT
// Per-pixel decode of an accumulated code (bitplane_stream.hpp): binarized
// word -> code index -> projector coordinate, with the validity rules and a
// confidence per pixel.
//
// A pixel is valid only when all of these hold (otherwise it is reported
// invalid rather than guessed):
//   1. white W and black B are finite and the contrast C = W - B is positive
//      and at least min_contrast_abs (shadowed / unlit / low-albedo pixels);
//      with the synthetic inverse of MultiCodeDecoder also W < full scale
//      (a clipped white is not a usable reference);
//   2. no plane was saturated (L and L̄ both clipped) or non-finite;
//   3. every *strict* plane's margin |L - L̄| exceeds the pixel's threshold
//        thr = max(min_bit_margin * C, noise_k * sigma_d),
//      sigma_d the measured noise of the margin (noise rule, below; under
//      direct light the margin equals C, Eq. 3.3–3.5 with α = 1, L_g = 0). A
//      *tolerable* plane (below) may fail this rule, but its margin must be
//      > 0 (an exact tie or a clipped pair carries no sign);
//   4. the word is a code word of a coordinate < length (e.g. column < W).
// confidence = min over all planes of |L - L̄| / C, clipped to [0, 1] (0 where
// C <= 0 or values are not finite), reported for every pixel — so a pixel
// kept through a weak tolerable plane shows that plane's margin / C.
//
// Tolerated weak planes (max_weak_error_px): error_bound[k] of bit position k
// is the largest coordinate error one flipped bit k can cause, over all
// coordinates whose flipped word is still a code word (plane_error_bounds).
// Planes with error_bound <= max_weak_error_px are tolerable; 0 disables the
// rule (every plane strict: the rule before issue 4). For the
// Gray code bit 0 (stripe width 2) has bound 1 and bit k 2^(k+1) - 1, so
// max_weak_error_px = 1 tolerates only the finest plane — the one sub-surface
// scattering blurs first (thesis §3.2, Fig. 3.3). The bound assumes one weak
// plane is wrong at a time.
//
// Noise rule (issue 16): a margin d = L - L̄ whose sign is decided by noise
// alone has |d| of the order of sigma_d, the standard deviation of d. With a
// camera whose per-frame noise is sigma^2(I) = a + b I (read noise a, shot
// noise b I, in input units) and independent frames,
//   sigma_d^2 = sigma^2(L) + sigma^2(L̄) = 2a + b (L + L̄) = noise_a + noise_b * S,
// S = L + L̄ = W + B per pixel (linear light transport: a pattern and its
// inverse add up to the white pattern, binarize.hpp), so the threshold is a
// function of W + B, computed once per pixel (decode_base), not per plane.
// noise_a / noise_b come from the capture itself (NoiseFit, bitplane_stream.hpp).
// noise_k = 3: a bit with no signal (true margin 0) passes with probability
// 2 (1 - Phi(3)) = 0.27 % under Gaussian noise. noise_k = 0 turns the rule off.
// Thread-safety: reentrant; callers partition pixels by band.
#pragma once

#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "bitplane_stream.hpp"
#include "codes.hpp"
#include "stripe_code.hpp"

namespace procam::sl {

// Help text of the methods' max_weak_error_px parameter.
inline constexpr const char* kMaxWeakErrorHelp =
    "tolerated weak planes: a plane whose single wrong bit moves the decoded column by at most "
    "this many projector columns (error_bound_px in the report; Gray/XOR-04: the stripe-width-2 "
    "plane for 1) may fail the min_bit_margin rule without invalidating the pixel (its margin "
    "must still be > 0; confidence then shows that plane's margin); sub-surface scattering "
    "blurs exactly these planes first (thesis §3.2, Fig. 3.3). 0 = every plane strict";

struct DecodeThresholds {
  float min_contrast_abs = 0.0f;  // rule 1, in input units (min_contrast * full scale)
  float min_bit_margin = 0.1f;    // rule 3, fraction of the contrast
  bool clipped_white_invalid = false;  // rule 1, synthetic inverse of MultiCodeDecoder
  // Noise rule (above): sigma_d^2 = noise_a + noise_b * (W + B), input units^2.
  float noise_k = 0.0f;
  float noise_a = 0.0f, noise_b = 0.0f;
};

// noise_k * sigma_d for S = W + B (0 where the rule is off or the variance is <= 0).
float noise_threshold(const DecodeThresholds& t, float S);
// Fits the capture's noise (BitPlaneStream::fit_noise) when noise_k > 0 and
// turns the noise rule on in `t` when it was measured; returns the fit and
// sets k_used to noise_k then, else to 0 (rule off).
NoiseFit apply_noise_rule(const BitPlaneStream& s, double noise_k, DecodeThresholds& t, double& k_used);

// error_bound[k] per bit position k (k = 0: least significant): max over
// projector coordinates x whose projected word w(x) XOR (1 << k) is a code
// word of |x - coord(w(x) XOR (1 << k))| in projector coordinates, rounded
// up; 0 where no flip of bit k gives a code word. For XOR codes the projected
// word is what the camera sees, so flipping the base plane flips every
// decoded Gray bit above it (a huge bound) while any other plane behaves like
// a Gray plane. The StripeCode form uses coordinate = code index.
std::vector<uint32_t> plane_error_bounds(const StripeCode& code);
std::vector<uint32_t> plane_error_bounds(const ProjectedCode& code);

// Per plane p (0 = first projected = most significant): 1 where
// error_bound[bits - 1 - p] <= max_weak_error_px (all 0 when it is 0).
std::vector<uint8_t> tolerable_planes(const std::vector<uint32_t>& error_bounds,
                                      uint32_t max_weak_error_px);

// out -> coord (float(out), NaN where out < 0) and valid (255 / 0; may be
// null), n pixels.
void index_maps(const int32_t* out, size_t n, float* coord, uint8_t* valid);

// Per-pixel terms shared by all codes of a round, one row-sized scratch per
// band: base_ok (rule 1), thr = min_bit_margin * C, inv_c = 1 / C (0 when
// C <= 0 or not finite) and, for 8-bit state, gate = base_ok ? min(floor(thr),
// 255) : 255 (an integer margin m passes rule 3 exactly when m > gate).
struct BaseRow {
  std::vector<uint8_t> base_ok, gate;
  std::vector<float> thr, inv_c;
  explicit BaseRow(size_t width) : base_ok(width), gate(width), thr(width), inv_c(width) {}
};

// Per-round constants of decode_base (8-bit lookup tables by contrast and
// white level), built once per finish.
struct DecodeContext {
  DecodeContext(const BitPlaneStream& stream, const DecodeThresholds& thresholds);
  const BitPlaneStream& s;
  DecodeThresholds t;
  float inv_scale = 1;
  // 8-bit state only, indexed by C = W - B in 1..255 / by W:
  float inv_c8[256] = {}, thr_f8[256] = {}, intensity8[256] = {};
  uint8_t thr8[256] = {}, lit8[256] = {};
  // Noise rule, 8-bit state: noise_threshold by S = W + B in 0..510; `noise`
  // false when the rule is off (every entry 0).
  bool noise = false;
  float noise8[512] = {};
};

// Fills `row` for pixels [b, e) (row index 0 = pixel b) and, when non-null,
// lit[i] (255 where C > 0 and C >= min_contrast_abs) and intensity[i]
// (W / full scale clipped to [0, 1], 0 if not finite), indexed by pixel.
void decode_base(const DecodeContext& ctx, size_t b, size_t e, BaseRow& row, uint8_t* lit,
                 float* intensity);

// Word -> value map of one code: `table` (2^bits int32 entries, -1 where the
// word is no code word; e.g. the code index, or 2 x column). When the code is
// the Gray code or an XOR code over identity columns and table[w] is
// scale * index, the SIMD kernel computes the same values arithmetically
// (XOR with the base, prefix-XOR Gray decode, index < length) instead of a
// table gather.
struct WordMap {
  std::vector<int32_t> table;
  bool arithmetic = false;
  int32_t xor_base = -1;    // XOR code: base bit position; -1: plain Gray
  uint32_t high_mask = 0;   // XOR code: positions above the base
  uint32_t length = 0;
  int32_t scale = 1;
};
// The StripeCode lookup table as a WordMap, values mapped through `value_of`
// (code index -> value; null: the index). Detects the arithmetic forms.
WordMap word_map(const StripeCode& code, const std::vector<int32_t>* value_of = nullptr);

// Decodes code `c` of the stream for pixels [b, e) with the terms of
// decode_base: out[k] = map value of the pixel's word where pixel b + k is
// valid, else -1; confidence[k] (may be null) as above. Returns the number of
// valid pixels kept only because a tolerable plane was tolerated. 8-bit state
// with AVX2 or AVX-512 runs a SIMD kernel with results identical to the scalar
// loop.
size_t decode_code(const DecodeContext& ctx, size_t c, const WordMap& map, size_t b, size_t e,
                   const BaseRow& row, int32_t* out, float* confidence);

// decode_code followed by index_maps(out, e - b, coord, valid) — one pass
// where the AVX-512 kernel runs (no int32 row written and re-read), the two
// calls otherwise; identical maps. scratch: e - b int32.
size_t decode_code_maps(const DecodeContext& ctx, size_t c, const WordMap& map, size_t b,
                        size_t e, const BaseRow& row, int32_t* scratch, float* coord,
                        uint8_t* valid, float* confidence);

// Uncertain planes (issue 16): instead of rejecting a pixel whose bits are
// not all certain, report the interval of coordinates its uncertain planes
// allow, when that interval is narrow. A plane is uncertain when its margin
// is not above the pixel's threshold (rule 3; a tolerable plane too, even
// when decode_code tolerated it). With at most CodeState::kTracked uncertain
// strict planes (tracked by BitPlaneStream::track_single_planes) the
// candidate words are the word with every subset of the uncertain planes'
// bits flipped (every tolerable plane's bit, when the tolerable margin is
// uncertain): at most 2^(kTracked + tolerable planes) words. Their code
// words' coordinates span [lo, hi]; when (hi - lo) / 2 <= max_half the pixel
// gets coord = (lo + hi) / 2, uncertainty = (hi - lo) / 2 and valid, so the
// interval holds every candidate — the true coordinate whenever the certain
// planes are right. For the Gray code at a stripe edge of plane k blurred
// with the finest plane the candidates are the 4 columns around the edge
// (half 1.5). Every candidate must be a code word and the candidates must
// fill [lo, hi] without a gap (a flip that jumps is no stripe edge). An
// exact tie (margin 0) is enumerated like any uncertain plane only with
// `ties` and where the white is below full scale: a clipped pair ties as
// well, and there no plane is trustworthy; without `ties` a tied pixel is
// invalid. Anything else — more than kTracked uncertain strict planes, a
// candidate that is no code word, a gap, or a wider interval — is invalid.
// Confidence stays min margin / C (below thr / C: lower than any certain
// pixel's at the same contrast). Certain pixels keep their value with
// uncertainty 0; invalid ones NaN. Returns the number given an interval.
// Scalar (the uncertain pixels are a small remainder).
struct UncertainRule {
  uint32_t weak_mask = 0;   // word bits of the tolerable planes (tolerable_mask)
  float max_half = 1.5f;    // widest half-interval reported, in coordinate units
  bool ties = false;        // enumerate exactly tied planes (white unclipped)
  bool fill_ties = true;    // the same for the neighbour fill's candidates (FillRow)
};
// Word bits (bit bits-1-p for plane p) of the planes flagged in `tolerable`.
uint32_t tolerable_mask(const std::vector<uint8_t>& tolerable, uint32_t bits);
// Candidates of the pixels decode_uncertain rejected although their own
// data names a few possible coordinates (neighbour_fill.hpp picks among
// them): one per camera row, pixel x (offset in the row) with its candidate
// table values v[begin[j] .. begin[j + 1]) in ascending order.
struct FillRow {
  std::vector<uint32_t> x;
  std::vector<uint32_t> begin{0};
  std::vector<int32_t> v;
  void clear() {
    x.clear();
    begin.assign(1, 0);
    v.clear();
  }
};
// `fill` (may be null): receives every rejected pixel that passes rule 1, is
// clean, has at most kTracked uncertain strict planes and whose white is
// unclipped where a plane ties, with the code-word values of every word its
// uncertain planes allow (ties included) — the rejected interval's
// candidates. [b, e) must be one camera row for it (x = i - b).
size_t decode_uncertain(const DecodeContext& ctx, size_t c, const WordMap& words,
                        const UncertainRule& rule, size_t b, size_t e, const BaseRow& row,
                        float* coord, uint8_t* valid, float* uncertainty,
                        FillRow* fill = nullptr);

// The per-row decode loop shared by the decoders: on the stream's pool, for
// every row, decode_base into a per-band BaseRow (lit / intensity written
// when non-null), then row_fn(b, e, base, scratch, weak) with b, e the row's
// pixels, int32 scratch for 4 rows and the band's per-code tolerated-weak
// counters (codes entries), which are summed into `weak` (resized to codes).
template <class RowFn>
void decode_rows(BitPlaneStream& s, const DecodeContext& ctx, uint8_t* lit, float* intensity,
                 size_t codes, std::vector<size_t>& weak, RowFn&& row_fn) {
  weak.assign(codes, 0);
  std::mutex mutex;
  s.pool().run(s.height(), [&](uint32_t y0, uint32_t y1) {
    const size_t w = s.width();
    BaseRow base(w);
    std::vector<int32_t> scratch(4 * w);
    std::vector<size_t> band_weak(codes, 0);
    for (uint32_t y = y0; y < y1; ++y) {
      const size_t b = size_t{y} * w;
      decode_base(ctx, b, b + w, base, lit, intensity);
      row_fn(b, b + w, base, scratch.data(), band_weak.data());
    }
    std::lock_guard<std::mutex> lock(mutex);
    for (size_t c = 0; c < codes; ++c) weak[c] += band_weak[c];
  });
}

}  // namespace procam::sl
