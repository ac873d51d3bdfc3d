// SPDX-License-Identifier: MIT
// Multi-code binary round: layout, pattern rendering, streaming binarization
// and per-code decode (thesis §3.2–3.3; see multi_round.hpp).
#include "multi_round.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <utility>

#include "decode.hpp"

namespace procam::sl {

MultiLayout make_multi_layout(const std::vector<ProjectedCode>& codes, bool inverse, bool black) {
  MultiLayout l;
  l.inverse = inverse;
  l.black = black;
  l.frames.push_back({FrameKind::white, 0, 0, -1, "white"});
  if (black) l.frames.push_back({FrameKind::black, 0, 0, -1, "black"});
  for (uint32_t c = 0; c < codes.size(); ++c) {
    const uint32_t bits = codes[c].bits();
    l.bits.push_back(bits);
    for (uint32_t p = 0; p < bits; ++p) {
      const std::string base = codes[c].id + " bit " + std::to_string(bits - 1 - p);
      const auto idx = static_cast<int32_t>(l.frames.size());
      l.frames.push_back({FrameKind::plane, c, p, -1, base});
      if (inverse) {
        l.frames.push_back({FrameKind::inverse, c, p, idx, base + " inverse"});
        l.frames[static_cast<size_t>(idx)].partner = idx + 1;
      }
    }
  }
  return l;
}

void render_multi_plan(const MultiLayout& layout, const std::vector<ProjectedCode>& codes,
                       uint32_t width, uint32_t height, const std::vector<uint8_t>* mask,
                       sdk::Plan& plan) {
  for (const ProjectedCode& c : codes)
    if (c.length() != width)
      throw std::invalid_argument("render_multi_plan: code length differs from projector width");
  if (mask != nullptr && mask->size() != size_t{width} * height)
    throw std::invalid_argument("render_multi_plan: mask size differs from projector size");
  std::vector<uint8_t> line(width);
  for (const MultiFrame& f : layout.frames) {
    const uint32_t i = plan.add_frame(f.label, width, height, PROCAM_PIXEL_U8);
    std::span<uint8_t> px = plan.pattern_u8(i);
    switch (f.kind) {
      case FrameKind::white: std::fill(line.begin(), line.end(), uint8_t{255}); break;
      case FrameKind::black: std::fill(line.begin(), line.end(), uint8_t{0}); break;
      case FrameKind::plane:
      case FrameKind::inverse: {
        const bool inv = f.kind == FrameKind::inverse;
        for (uint32_t x = 0; x < width; ++x)
          line[x] = codes[f.code].bit(f.plane, x) != inv ? 255 : 0;
        break;
      }
    }
    for (uint32_t y = 0; y < height; ++y) {
      uint8_t* row = px.data() + size_t{y} * width;
      if (mask == nullptr) {
        std::memcpy(row, line.data(), width);
      } else {
        const uint8_t* m = mask->data() + size_t{y} * width;
        for (uint32_t x = 0; x < width; ++x) row[x] = m[x] != 0 ? line[x] : uint8_t{0};
      }
    }
  }
}

MultiCodeDecoder::MultiCodeDecoder(MultiLayout layout, const std::vector<ProjectedCode>& codes,
                                   uint32_t width, uint32_t height, uint32_t threads)
    : layout_(std::move(layout)),
      codes_(codes),
      width_(width),
      height_(height),
      threads_(std::max(1u, threads)) {
  const size_t n = size_t{width_} * height_;
  acc_.resize(codes_.size());
  for (size_t c = 0; c < codes_.size(); ++c) acc_[c].reset(n, codes_[c].bits());
  waiting_.resize(layout_.frames.size());
  added_.assign(layout_.frames.size(), 0);
  if (!layout_.black) black_.assign(n, 0.0f);  // B = 0: footnote 2's L̄ = W − L
  allocate_result();
}

void MultiCodeDecoder::allocate_result() {
  const size_t n = size_t{width_} * height_;
  result_.codes.resize(codes_.size());
  for (AxisMaps& m : result_.codes) {  // assign() writes every page now, not after the last frame
    if (m.coord.size() != n) m.coord.assign(n, 0.0f);
    if (m.valid.size() != n) m.valid.assign(n, 0);
    if (m.confidence.size() != n) m.confidence.assign(n, 0.0f);
  }
  if (result_.lit.size() != n) result_.lit.assign(n, 0);
  if (result_.intensity.size() != n) result_.intensity.assign(n, 0.0f);
}

void MultiCodeDecoder::keep(uint32_t index, const procam_image& frame) {
  Copy& c = waiting_[index];
  c.view = frame;
  const size_t n = size_t{width_} * height_;
  const size_t row_bytes = size_t{width_} * sdk::bytes_per_sample(frame.pixel_type);
  void* dst = nullptr;
  switch (frame.pixel_type) {
    case PROCAM_PIXEL_U8: c.u8.resize(n); dst = c.u8.data(); break;
    case PROCAM_PIXEL_U16: c.u16.resize(n); dst = c.u16.data(); break;
    default: c.f32.resize(n); dst = c.f32.data(); break;
  }
  for (uint32_t y = 0; y < height_; ++y)
    std::memcpy(static_cast<uint8_t*>(dst) + y * row_bytes, sdk::row_bytes(frame, y), row_bytes);
  c.view.data = dst;
  c.view.stride_bytes = row_bytes;
}

void MultiCodeDecoder::to_float(const procam_image& frame, std::vector<float>& out) const {
  out.resize(size_t{width_} * height_);
  sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
    for (uint32_t y = y0; y < y1; ++y) sdk::read_row(frame, y, out.data() + size_t{y} * width_);
  });
}

bool MultiCodeDecoder::have_reference() const {
  return added_[0] != 0 && (!layout_.black || added_[1] != 0);
}

void MultiCodeDecoder::fold(const MultiFrame& role, const procam_image& plane,
                            const procam_image* inverse) {
  BitAccumulator& acc = acc_[role.code];
  const uint32_t position = acc.bits - 1 - role.plane;
  const size_t w = width_;
  if (inverse == nullptr && plane.pixel_type == PROCAM_PIXEL_U8) {  // 8-bit fast path
    if (sum_u16_.empty()) {
      sum_u16_.resize(white_.size());
      for (size_t i = 0; i < white_.size(); ++i)
        sum_u16_[i] = static_cast<uint16_t>(white_[i] + black_[i]);  // exact: integers <= 510
    }
    const auto sat = static_cast<int32_t>(full_scale_);
    sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
      for (uint32_t y = y0; y < y1; ++y) {
        const size_t off = size_t{y} * w;
        fold_plane_u8_synthetic(sdk::row_bytes(plane, y),
                                sum_u16_.data() + off, w, position, sat, acc.word.data() + off,
                                acc.min_margin.data() + off, acc.flags.data() + off);
      }
    });
    acc.plane_done[role.plane] = 1;
    return;
  }
  sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
    std::vector<float> row_l(w), row_lb(w);
    for (uint32_t y = y0; y < y1; ++y) {
      const size_t off = size_t{y} * w;
      sdk::read_row(plane, y, row_l.data());
      if (inverse != nullptr)
        sdk::read_row(*inverse, y, row_lb.data());
      else
        synthesize_inverse(row_l.data(), white_.data() + off, black_.data() + off, w,
                           row_lb.data());
      fold_plane(row_l.data(), row_lb.data(), w, position, full_scale_, acc.word.data() + off,
                 acc.min_margin.data() + off, acc.flags.data() + off);
    }
  });
  acc.plane_done[role.plane] = 1;
}

void MultiCodeDecoder::fold_waiting_planes() {
  for (size_t i = 0; i < layout_.frames.size(); ++i) {
    const MultiFrame& role = layout_.frames[i];
    if (role.kind != FrameKind::plane || waiting_[i].view.data == nullptr) continue;
    fold(role, waiting_[i].view, nullptr);
    waiting_[i] = Copy{};
  }
}

sdk::Error MultiCodeDecoder::add_frame(uint32_t index, const procam_image& frame) {
  if (index >= layout_.frames.size())
    return sdk::invalid_argument("frame index " + std::to_string(index) + " is out of range (" +
                                 std::to_string(layout_.frames.size()) + " frames)");
  const MultiFrame& role = layout_.frames[index];
  const std::string what = "frame " + std::to_string(index) + " (" + role.label + ")";
  if (added_[index]) return sdk::state_error(what + " was already added");
  if (sdk::Error e = sdk::check_frame(&frame, width_, height_, 1, what); !e.ok()) return e;
  if (have_format_ && (frame.pixel_type != pixel_type_ ||
                       (pixel_type_ != PROCAM_PIXEL_F32 && frame.bit_depth != bit_depth_))) {
    procam_image first{};
    first.width = width_;
    first.height = height_;
    first.channels = 1;
    first.pixel_type = pixel_type_;
    first.bit_depth = bit_depth_;
    return sdk::bad_frame(what + " is " + sdk::describe_image(frame) +
                          " but earlier frames of this round are " + sdk::describe_image(first) +
                          "; all frames of a round must share one format");
  }
  if (!have_format_) {
    pixel_type_ = frame.pixel_type;
    bit_depth_ = frame.bit_depth;
    full_scale_ = static_cast<float>(sdk::full_scale(frame));
    have_format_ = true;
  }
  switch (role.kind) {
    case FrameKind::white: to_float(frame, white_); break;
    case FrameKind::black: to_float(frame, black_); break;
    case FrameKind::plane:
    case FrameKind::inverse:
      if (layout_.inverse) {
        const auto partner = static_cast<size_t>(role.partner);
        if (added_[partner]) {
          const procam_image& other = waiting_[partner].view;
          if (role.kind == FrameKind::plane)
            fold(role, frame, &other);
          else
            fold(layout_.frames[partner], other, &frame);
          waiting_[partner] = Copy{};
        } else {
          keep(index, frame);
        }
      } else if (have_reference()) {
        fold(role, frame, nullptr);
      } else {
        keep(index, frame);
      }
      break;
  }
  added_[index] = 1;
  ++added_count_;
  if (!layout_.inverse && (role.kind == FrameKind::white || role.kind == FrameKind::black) &&
      have_reference())
    fold_waiting_planes();
  return sdk::ok();
}

MultiResult& MultiCodeDecoder::finish(double min_contrast, double min_bit_margin) {
  if (!complete()) throw std::logic_error("MultiCodeDecoder::finish before all frames added");
  for (const BitAccumulator& a : acc_)
    for (uint8_t done : a.plane_done)
      if (!done) throw std::logic_error("MultiCodeDecoder: a plane was never folded");
  allocate_result();  // no-op unless a caller moved maps out
  MultiResult& r = result_;
  r.full_scale = static_cast<double>(full_scale_);
  DecodeThresholds t;
  t.min_contrast_abs = static_cast<float>(min_contrast * static_cast<double>(full_scale_));
  t.min_bit_margin = static_cast<float>(min_bit_margin);
  const float inv_scale = 1.0f / full_scale_;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const bool synthetic = !layout_.inverse;
  // The rules of decode.hpp (same results as decode_pixels), restructured for
  // speed: the per-pixel terms shared by all codes (contrast rule, 1/C, the
  // margin threshold, clipped white) are computed once, then each code is a
  // short branch-free loop (lookup table + span-centre table).
  sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
    const size_t b = size_t{y0} * width_, e = size_t{y1} * width_, len = e - b;
    std::vector<uint8_t> base(len);
    std::vector<float> inv_c(len), thr(len);
    for (size_t k = 0; k < len; ++k) {
      const size_t i = b + k;
      const float w = white_[i], bl = black_[i], contrast = w - bl;
      const bool finite = std::isfinite(w) && std::isfinite(bl) && std::isfinite(contrast);
      const bool pos = finite && contrast > 0.0f;
      base[k] = pos && contrast >= t.min_contrast_abs && (!synthetic || w < full_scale_);
      inv_c[k] = pos ? 1.0f / contrast : 0.0f;
      thr[k] = t.min_bit_margin * contrast;
      r.lit[i] = pos && contrast >= t.min_contrast_abs ? 255 : 0;
      const float v = w * inv_scale;
      r.intensity[i] = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
    }
    for (size_t c = 0; c < codes_.size(); ++c) {
      AxisMaps& m = r.codes[c];
      const BitAccumulator& a = acc_[c];
      const uint32_t* lut = codes_[c].code.lut.data();
      const float* coord_of = codes_[c].coord_of.data();
      for (size_t k = 0; k < len; ++k) {
        const size_t i = b + k;
        const float margin = a.min_margin[i];
        const uint8_t fl = a.flags[i];
        const bool margin_finite = margin <= std::numeric_limits<float>::max();
        const bool nonfinite = (fl & kFlagNonFinite) != 0;
        m.confidence[i] = !nonfinite && margin_finite ? std::min(margin * inv_c[k], 1.0f) : 0.0f;
        const uint32_t idx = lut[a.word[i]];
        const bool ok = base[k] != 0 && !nonfinite && (fl & kFlagSaturated) == 0 &&
                        margin > thr[k] && idx != StripeCode::kInvalid;
        m.coord[i] = ok ? coord_of[ok ? idx : 0] : nan;
        m.valid[i] = ok ? 255 : 0;
      }
    }
  });
  return r;
}

}  // namespace procam::sl
