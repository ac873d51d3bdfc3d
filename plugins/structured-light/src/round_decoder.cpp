// SPDX-License-Identifier: MIT
// Streaming binary-code round decoder (thesis §3.2; see round_decoder.hpp).
#include "round_decoder.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace procam::sl {

BinaryRoundDecoder::BinaryRoundDecoder(Layout layout, const StripeCode& cols,
                                       const StripeCode* rows, uint32_t width, uint32_t height,
                                       uint32_t threads)
    : layout_(std::move(layout)),
      cols_(cols),
      has_rows_(rows != nullptr),
      width_(width),
      height_(height),
      threads_(std::max(1u, threads)) {
  if (rows != nullptr) rows_ = *rows;
  const size_t n = size_t{width_} * height_;
  col_acc_.reset(n, cols_.bits);
  if (has_rows_) row_acc_.reset(n, rows_.bits);
  waiting_.resize(layout_.frames.size());
  added_.assign(layout_.frames.size(), 0);
}

void BinaryRoundDecoder::keep(uint32_t index, const procam_image& frame) {
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

void BinaryRoundDecoder::to_float(const procam_image& frame, std::vector<float>& out) const {
  out.resize(size_t{width_} * height_);
  sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
    for (uint32_t y = y0; y < y1; ++y) sdk::read_row(frame, y, out.data() + size_t{y} * width_);
  });
}

void BinaryRoundDecoder::fold(const FrameRole& role, const procam_image& plane,
                              const procam_image* inverse) {
  BitAccumulator& acc = role.axis == Axis::col ? col_acc_ : row_acc_;
  const uint32_t position = acc.bits - 1 - role.plane;
  const size_t w = width_;
  sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
    std::vector<float> row_l(w), row_lb(w);
    for (uint32_t y = y0; y < y1; ++y) {
      const size_t off = size_t{y} * w;
      sdk::read_row(plane, y, row_l.data());
      if (inverse != nullptr)
        sdk::read_row(*inverse, y, row_lb.data());
      else  // binarize "white": footnote 2, generalised (binarize.hpp)
        synthesize_inverse(row_l.data(), white_.data() + off, black_.data() + off, w,
                           row_lb.data());
      fold_plane(row_l.data(), row_lb.data(), w, position, full_scale_, acc.word.data() + off,
                 acc.min_margin.data() + off, acc.flags.data() + off);
    }
  });
  acc.plane_done[role.plane] = 1;
}

void BinaryRoundDecoder::fold_waiting_planes() {
  for (size_t i = 0; i < layout_.frames.size(); ++i) {
    const FrameRole& role = layout_.frames[i];
    if (role.kind != FrameKind::plane || waiting_[i].view.data == nullptr) continue;
    fold(role, waiting_[i].view, nullptr);
    waiting_[i] = Copy{};  // release
  }
}

sdk::Error BinaryRoundDecoder::add_frame(uint32_t index, const procam_image& frame) {
  if (index >= layout_.frames.size())
    return sdk::invalid_argument("frame index " + std::to_string(index) + " is out of range (" +
                                 std::to_string(layout_.frames.size()) + " frames)");
  const FrameRole& role = layout_.frames[index];
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
          waiting_[partner] = Copy{};  // release the partner's copy
        } else {
          keep(index, frame);
        }
      } else {
        const bool have_reference = added_[static_cast<size_t>(layout_.white_index())] &&
                                    added_[static_cast<size_t>(layout_.black_index())];
        if (have_reference)
          fold(role, frame, nullptr);
        else
          keep(index, frame);
      }
      break;
  }
  added_[index] = 1;
  ++added_count_;
  if (!layout_.inverse && (role.kind == FrameKind::white || role.kind == FrameKind::black) &&
      added_[static_cast<size_t>(layout_.white_index())] &&
      added_[static_cast<size_t>(layout_.black_index())])
    fold_waiting_planes();
  return sdk::ok();
}

RoundResult BinaryRoundDecoder::finish(double min_contrast, double min_bit_margin) {
  if (!complete()) throw std::logic_error("BinaryRoundDecoder::finish before all frames added");
  for (uint8_t done : col_acc_.plane_done)
    if (!done) throw std::logic_error("BinaryRoundDecoder: a column plane was never folded");
  if (has_rows_)
    for (uint8_t done : row_acc_.plane_done)
      if (!done) throw std::logic_error("BinaryRoundDecoder: a row plane was never folded");

  const size_t n = size_t{width_} * height_;
  RoundResult r;
  r.full_scale = static_cast<double>(full_scale_);
  DecodeThresholds t;
  t.min_contrast_abs = static_cast<float>(min_contrast * static_cast<double>(full_scale_));
  t.min_bit_margin = static_cast<float>(min_bit_margin);
  auto alloc = [n](AxisMaps& m) {
    m.coord.resize(n);
    m.valid.resize(n);
    m.confidence.resize(n);
  };
  alloc(r.cols);
  if (has_rows_) alloc(r.rows);
  r.intensity.resize(n);
  const float* white = white_.data();
  const float* black = black_.data();
  const float inv_scale = 1.0f / full_scale_;
  sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
    const size_t b = size_t{y0} * width_, e = size_t{y1} * width_;
    decode_pixels(col_acc_, cols_, white, black, b, e, t, r.cols.coord.data(),
                  r.cols.valid.data(), r.cols.confidence.data());
    if (has_rows_)
      decode_pixels(row_acc_, rows_, white, black, b, e, t, r.rows.coord.data(),
                    r.rows.valid.data(), r.rows.confidence.data());
    for (size_t i = b; i < e; ++i) {
      const float v = white[i] * inv_scale;
      r.intensity[i] = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
    }
  });
  return r;
}

}  // namespace procam::sl
