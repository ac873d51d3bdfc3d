// SPDX-License-Identifier: MIT
// One capture round of several column codes sharing a white (and optionally a
// black) frame — the form of the single XOR / min-SW methods (one code) and of
// the ensemble (four codes, thesis §3.3.3) — streamed through binarization as
// frames arrive (thesis §3.2, Eq. 3.5; binarize.hpp) and decoded per code.
//
// Frame order (plan order and offline file order):
//   0 "white"; 1 "black" (when the layout has a black frame); then per code in
//   the given order, per plane from the most significant bit k = bits-1 .. 0:
//   "<code> bit k" [, "<code> bit k inverse"].
// Binarization: with inverses, bit = L > L̄ (Eq. 3.5); without, L̄ = W + B − L
// (§3.2 footnote 2, generalised; B = 0 when no black frame is projected — the
// thesis's 41-image ensemble), i.e. L is compared with (W + B) / 2.
// Pixels whose white frame is clipped (W >= full scale) are invalid in that
// mode: W + B − L is then not the inverse image.
// Masked rounds (error correction, §3.4): every pattern, white included, is
// ANDed with a projector mask, so decoding needs no change — pixels lit only
// by switched-off projector pixels fail the contrast rule and stay invalid.
// Inputs: one-channel U8 / U16 (bit_depth 1..16) / F32 frames of one format.
// Thread-safety: thread-bound; uses `threads` workers for per-pixel loops.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "binarize.hpp"
#include "codes.hpp"
#include "plan_layout.hpp"
#include "procam/plugin_sdk.hpp"
#include "round_decoder.hpp"

namespace procam::sl {

struct MultiFrame {
  FrameKind kind = FrameKind::white;
  uint32_t code = 0;     // index into the code list (plane / inverse)
  uint32_t plane = 0;    // 0 = most significant
  int32_t partner = -1;  // plane <-> inverse
  std::string label;
};

struct MultiLayout {
  bool inverse = false;
  bool black = true;
  std::vector<uint32_t> bits;  // per code
  std::vector<MultiFrame> frames;
  int32_t black_index() const { return black ? 1 : -1; }
};

MultiLayout make_multi_layout(const std::vector<ProjectedCode>& codes, bool inverse, bool black);

// Appends the layout's patterns (projector W x H, U8 0/255, vertical stripes)
// to `plan`. `mask` (W*H, nonzero = may be lit) switches projector pixels off
// in every pattern, white included; null = all on.
void render_multi_plan(const MultiLayout& layout, const std::vector<ProjectedCode>& codes,
                       uint32_t width, uint32_t height, const std::vector<uint8_t>* mask,
                       sdk::Plan& plan);

struct MultiResult {
  std::vector<AxisMaps> codes;   // per code: projector column (span centre), valid, confidence
  std::vector<uint8_t> lit;      // 255 where W - B passes the contrast rule (decode.hpp rule 1)
  std::vector<float> intensity;  // white / full scale in [0, 1]
  double full_scale = 0;
};

class MultiCodeDecoder {
 public:
  MultiCodeDecoder(MultiLayout layout, const std::vector<ProjectedCode>& codes, uint32_t width,
                   uint32_t height, uint32_t threads);

  // Frame `index` of the layout, each once; BAD_FRAME / STATE errors as
  // BinaryRoundDecoder. The image is only read during the call.
  sdk::Error add_frame(uint32_t index, const procam_image& frame);
  bool complete() const { return added_count_ == layout_.frames.size(); }

  // Decode rules of decode.hpp per code (min_contrast: fraction of full scale).
  // Requires complete() (std::logic_error otherwise). The maps live in the
  // decoder: they are allocated and touched by the constructor (while frames
  // are still being captured), so the work after the last frame does not pay
  // for page faults. Callers may move the maps out; a later call re-allocates.
  MultiResult& finish(double min_contrast, double min_bit_margin);

  const MultiLayout& layout() const { return layout_; }

 private:
  struct Copy {
    std::vector<uint8_t> u8;
    std::vector<uint16_t> u16;
    std::vector<float> f32;
    procam_image view{};
  };
  void fold(const MultiFrame& role, const procam_image& plane, const procam_image* inverse);
  void fold_waiting_planes();
  void keep(uint32_t index, const procam_image& frame);
  void to_float(const procam_image& frame, std::vector<float>& out) const;
  bool have_reference() const;

  MultiLayout layout_;
  std::vector<ProjectedCode> codes_;
  uint32_t width_, height_, threads_;
  std::vector<BitAccumulator> acc_;
  std::vector<float> white_, black_;
  std::vector<uint16_t> sum_u16_;
  MultiResult result_;  // pre-allocated output maps
  void allocate_result();  // W + B of 8-bit rounds (synthetic-inverse fast path)
  std::vector<Copy> waiting_;
  std::vector<uint8_t> added_;
  size_t added_count_ = 0;
  bool have_format_ = false;
  uint32_t pixel_type_ = 0, bit_depth_ = 0;
  float full_scale_ = 0;
};

}  // namespace procam::sl
