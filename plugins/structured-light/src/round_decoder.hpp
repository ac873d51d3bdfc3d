// SPDX-License-Identifier: MIT
// BinaryRoundDecoder: streams the captured frames of one binary-code round
// (layout from plan_layout.hpp) through binarization as they arrive, then
// decodes every pixel when the round ends.
//
// Streaming, frame bookkeeping and the per-pixel state are the shared engine
// of bitplane_stream.hpp (the same as MultiCodeDecoder's): a plane is folded
// as soon as both it and its reference are present — its inverse frame
// (binarize "inverse") or the white and black frames (binarize "white") —
// and a waiting frame is copied in its own pixel format until then. In plan
// order at most one frame waits at a time, so end of round only runs the
// per-pixel decode. Frames may arrive in any order.
//
// Inputs: one-channel U8, U16 (any bit_depth 1..16) or F32 frames, all of a
// round in the same format; full scale = 2^bit_depth - 1 (F32: 1.0), which
// is also the saturation level.
// Output maps are allocated and touched by the constructor (while frames are
// still being captured) and moved out by finish().
// Thread-safety: thread-bound (docs/threading.md) (one session); uses `threads` worker threads
// (a WorkPool owned by the decoder) for per-pixel loops.
#pragma once

#include <cstdint>
#include <vector>

#include "bitplane_stream.hpp"
#include "decode.hpp"
#include "neighbour_fill.hpp"
#include "plan_layout.hpp"
#include "procam/plugin_sdk.hpp"
#include "stripe_average.hpp"
#include "stripe_code.hpp"

namespace procam::sl {

// Decoded maps of one axis (width * height, row-major).
struct AxisMaps {
  std::vector<float> coord;       // projector column/row, NaN where invalid
  std::vector<uint8_t> valid;     // 255 valid, 0 invalid
  std::vector<float> confidence;  // [0, 1], see decode.hpp
  // Columns with set_uncertain_output(true): half-width of the interval the
  // uncertain tolerable planes allow (decode_uncertain), 0 where exact, NaN
  // where invalid; empty otherwise.
  std::vector<float> uncertainty;
};

struct RoundResult {
  AxisMaps cols;
  AxisMaps rows;                  // coord only (NaN = invalid; valid and confidence
                                  // empty); all empty when the layout has no row code
  std::vector<float> intensity;   // white image / full scale, clipped to [0, 1] (0 if not finite)
  double full_scale = 0;          // of the input frames
  size_t cols_weak = 0, rows_weak = 0;  // valid pixels kept through a tolerated weak plane
                                        // (with uncertain output: given an interval)
  size_t cols_filled = 0, rows_filled = 0;  // of those, given by the neighbour fill
  StripeAverageReport stripe;           // columns' stripe-averaged rule (stripe_average.hpp)
  NoiseFit noise;                       // the capture's noise model (bitplane_stream.hpp)
  double noise_k = 0;                   // the noise rule's k (0: off or not measured)
};

class BinaryRoundDecoder {
 public:
  // `cols` (and `rows` when non-null) are copied. Frames must be
  // width x height. threads >= 1. max_weak_error_px: tolerated weak planes
  // (decode.hpp; 0 = every plane strict).
  BinaryRoundDecoder(Layout layout, const StripeCode& cols, const StripeCode* rows,
                     uint32_t width, uint32_t height, uint32_t threads,
                     uint32_t max_weak_error_px = 0);

  // Frame `index` of the layout (each once). BAD_FRAME for a wrong size,
  // channel count or a format that differs from earlier frames of the round;
  // nothing changes on error. The image is read during the call only.
  sdk::Error add_frame(uint32_t index, const procam_image& frame) {
    return stream_.add_frame(index, frame);
  }

  // True when every frame of the layout was added.
  bool complete() const { return stream_.complete(); }

  // Decodes all pixels (requires complete(); throws std::logic_error if not).
  // min_contrast is a fraction of full scale; see decode.hpp for the rules.
  // Moves the pre-allocated maps out (a second call allocates new ones).
  // noise_k > 0 adds the noise rule (decode.hpp) with the noise fitted to
  // this capture's pattern/inverse pairs; without pairs ("white" mode) it
  // has nothing to measure and only min_bit_margin applies.
  RoundResult finish(double min_contrast, double min_bit_margin, double noise_k = 0);

  // With true, pixels with uncertain planes whose candidate coordinates
  // span a narrow interval get its centre and cols.uncertainty
  // (decode_uncertain) instead of the tolerated bit or nothing (rows: the
  // centre; coord only). Call before the first frame. Also tracks the
  // uncertain strict planes (BitPlaneStream::track_single_planes).
  // max_half: the widest half-interval reported, projector pixels; ties:
  // exactly tied planes enumerated too (UncertainRule).
  void set_uncertain_output(bool on, float max_half = 1.5f, bool ties = false) {
    uncertain_ = on;
    max_uncertainty_ = max_half;
    ties_ = ties;
    stream_.track_single_planes(on);
  }

  // Neighbour-consistent candidate selection (neighbour_fill.hpp) for the
  // pixels the uncertain output rejects, on both axes; needs
  // set_uncertain_output(true). rule.passes 0 (the default) = off. The
  // filled pixels count in cols_weak / rows_weak and in cols_filled /
  // rows_filled.
  // fill_ties: exact ties enumerated for the fill's candidates (white unclipped).
  void set_neighbour_fill(const NeighbourFillRule& rule, bool fill_ties = true) {
    fill_ = rule;
    fill_ties_ = fill_ties;
  }

  // Stripe-averaged margins behind the image-level gate for the columns
  // (stripe_average.hpp); needs set_uncertain_output(true) and binarize
  // "inverse" (the pairs are kept from the first frame on unless the mode
  // is off: call before the first frame). Default off here; method "gray"
  // sets its parameters (automatic by default).
  void set_stripe_average(const StripeAverageParams& p) {
    stripe_ = p;
    stream_.keep_pairs(p.mode == StripeAverageMode::off ? -1 : 0);
  }

  const Layout& layout() const { return layout_; }

 private:
  void allocate_result();

  Layout layout_;
  StripeCode cols_, rows_;
  bool has_rows_ = false;
  bool uncertain_ = false;
  float max_uncertainty_ = 1.5f;
  bool ties_ = false;
  NeighbourFillRule fill_;
  bool fill_ties_ = true;
  StripeAverageParams stripe_{StripeAverageMode::off};
  std::vector<uint8_t> tolerable_[2];
  uint32_t width_, height_;
  BitPlaneStream stream_;
  RoundResult result_;
};

// Gives every map of `r` to the map cache (map_cache.hpp), as the session
// does when it ends, so the next decoder of the same size reuses the pages.
void recycle_maps(RoundResult&& r) noexcept;

// The engine layout of a Layout (code 0 = columns, 1 = rows), with tolerable
// planes for max_weak_error_px.
StreamLayout stream_layout(const Layout& layout, const StripeCode& cols, const StripeCode* rows,
                           uint32_t max_weak_error_px);

}  // namespace procam::sl
