// SPDX-License-Identifier: MIT
// BinaryRoundDecoder: streams the captured frames of one binary-code round
// (layout from plan_layout.hpp) through binarization as they arrive, then
// decodes every pixel when the round ends.
//
// Streaming: a plane is folded into its accumulator as soon as both it and
// its reference are present — its inverse frame (binarize "inverse") or the
// white and black frames (binarize "white"). Until then a copy of the frame
// is kept in its own pixel format; once folded, the copy is released. In plan
// order at most one frame waits at a time, so end of round only runs the
// per-pixel decode. Frames may arrive in any order. White and black are kept
// as float for the whole round (references and contrast).
//
// Inputs: one-channel U8, U16 (any bit_depth 1..16) or F32 frames, all of a
// round in the same format; full scale = 2^bit_depth - 1 (F32: 1.0), which
// is also the saturation level.
// Thread-safety: thread-bound (one session); uses `threads` worker threads
// internally for per-pixel loops (sdk::parallel_rows).
#pragma once

#include <cstdint>
#include <vector>

#include "binarize.hpp"
#include "decode.hpp"
#include "plan_layout.hpp"
#include "procam/plugin_sdk.hpp"
#include "stripe_code.hpp"

namespace procam::sl {

// Decoded maps of one axis (width * height, row-major).
struct AxisMaps {
  std::vector<float> coord;       // projector column/row, NaN where invalid
  std::vector<uint8_t> valid;     // 255 valid, 0 invalid
  std::vector<float> confidence;  // [0, 1], see decode.hpp
};

struct RoundResult {
  AxisMaps cols;
  AxisMaps rows;                  // empty when the layout has no row code
  std::vector<float> intensity;   // white image / full scale, clipped to [0, 1] (0 if not finite)
  double full_scale = 0;          // of the input frames
};

class BinaryRoundDecoder {
 public:
  // `cols` (and `rows` when non-null) are copied. Frames must be
  // width x height. threads >= 1.
  BinaryRoundDecoder(Layout layout, const StripeCode& cols, const StripeCode* rows,
                     uint32_t width, uint32_t height, uint32_t threads);

  // Frame `index` of the layout (each once). BAD_FRAME for a wrong size,
  // channel count or a format that differs from earlier frames of the round;
  // nothing changes on error. The image is read during the call only.
  sdk::Error add_frame(uint32_t index, const procam_image& frame);

  // True when every frame of the layout was added.
  bool complete() const { return added_count_ == layout_.frames.size(); }

  // Decodes all pixels (requires complete(); throws std::logic_error if not).
  // min_contrast is a fraction of full scale; see decode.hpp for the rules.
  RoundResult finish(double min_contrast, double min_bit_margin);

  const Layout& layout() const { return layout_; }

 private:
  struct Copy {  // a waiting frame, copied in its own format (the host's memory is call-scoped)
    std::vector<uint8_t> u8;
    std::vector<uint16_t> u16;
    std::vector<float> f32;
    procam_image view{};
  };
  void fold(const FrameRole& role, const procam_image& plane, const procam_image* inverse);
  void fold_waiting_planes();  // binarize "white": planes that arrived before W and B
  void keep(uint32_t index, const procam_image& frame);
  void to_float(const procam_image& frame, std::vector<float>& out) const;

  Layout layout_;
  StripeCode cols_, rows_;
  bool has_rows_ = false;
  uint32_t width_, height_, threads_;
  BitAccumulator col_acc_, row_acc_;
  std::vector<float> white_, black_;        // float copies once added
  std::vector<Copy> waiting_;               // per layout frame: copy while it waits (or empty)
  std::vector<uint8_t> added_;
  size_t added_count_ = 0;
  bool have_format_ = false;
  uint32_t pixel_type_ = 0, bit_depth_ = 0;
  float full_scale_ = 0;
};

}  // namespace procam::sl
