// SPDX-License-Identifier: MIT
// Streaming binary-code round decoder (thesis §3.2; see round_decoder.hpp).
#include "round_decoder.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <utility>

namespace procam::sl {

StreamLayout stream_layout(const Layout& layout, const StripeCode& cols, const StripeCode* rows,
                           uint32_t max_weak_error_px) {
  StreamLayout s;
  s.inverse = layout.inverse;
  s.white = layout.white_index();
  s.black = layout.black_index();
  s.bits.push_back(cols.bits);
  s.tolerable.push_back(tolerable_planes(plane_error_bounds(cols), max_weak_error_px));
  if (rows != nullptr) {
    s.bits.push_back(rows->bits);
    s.tolerable.push_back(tolerable_planes(plane_error_bounds(*rows), max_weak_error_px));
  }
  for (const FrameRole& r : layout.frames)
    s.frames.push_back({r.kind, r.axis == Axis::row ? 1u : 0u, r.plane, r.partner, r.label});
  return s;
}

BinaryRoundDecoder::BinaryRoundDecoder(Layout layout, const StripeCode& cols,
                                       const StripeCode* rows, uint32_t width, uint32_t height,
                                       uint32_t threads, uint32_t max_weak_error_px)
    : layout_(std::move(layout)),
      cols_(cols),
      has_rows_(rows != nullptr),
      width_(width),
      height_(height),
      stream_(stream_layout(layout_, cols, rows, max_weak_error_px), width, height, threads) {
  if (rows != nullptr) rows_ = *rows;
  tolerable_[0] = tolerable_planes(plane_error_bounds(cols), max_weak_error_px);
  if (rows != nullptr) tolerable_[1] = tolerable_planes(plane_error_bounds(*rows), max_weak_error_px);
  allocate_result();
  stream_.set_intensity_output(result_.intensity.data());
}

void BinaryRoundDecoder::allocate_result() {
  const size_t n = size_t{width_} * height_;
  // Every page written now, not after the last frame. Rows: coord only (no
  // method outputs a row confidence or validity map; NaN marks invalid).
  MapBatch maps;
  maps.add(result_.cols.coord, n);
  maps.add(result_.cols.valid, n);
  maps.add(result_.cols.confidence, n);
  if (has_rows_) {
    maps.add(result_.rows.coord, n);
  }
  if (result_.intensity.size() != n) {  // a new map: written at finish, not from the white frame
    stream_.set_intensity_output(nullptr);
    maps.add(result_.intensity, n);
  }
  maps.run(stream_.pool());
}

void recycle_maps(RoundResult&& r) noexcept {
  for (AxisMaps* m : {&r.cols, &r.rows}) {
    sdk::give_map(std::move(m->coord));
    sdk::give_map(std::move(m->valid));
    sdk::give_map(std::move(m->confidence));
    sdk::give_map(std::move(m->uncertainty));
  }
  sdk::give_map(std::move(r.intensity));
}

RoundResult BinaryRoundDecoder::finish(double min_contrast, double min_bit_margin,
                                       double noise_k) {
  stream_.require_complete("BinaryRoundDecoder");
  const size_t n = size_t{width_} * height_;
  if (result_.intensity.size() != n) allocate_result();
  RoundResult& r = result_;
  r.full_scale = static_cast<double>(stream_.full_scale());
  DecodeThresholds t;
  t.min_contrast_abs = static_cast<float>(min_contrast * r.full_scale);
  t.min_bit_margin = static_cast<float>(min_bit_margin);
  r.noise = apply_noise_rule(stream_, noise_k, t, r.noise_k);
  const DecodeContext ctx(stream_, t);
  const WordMap maps[2] = {word_map(cols_), has_rows_ ? word_map(rows_) : WordMap{}};
  const bool uncertain[2] = {uncertain_, uncertain_ && has_rows_};
  UncertainRule rule[2];
  rule[0] = {tolerable_mask(tolerable_[0], cols_.bits), max_uncertainty_, ties_, fill_ties_};
  if (has_rows_) rule[1] = {tolerable_mask(tolerable_[1], rows_.bits), max_uncertainty_, ties_, fill_ties_};
  if (uncertain_) sdk::take_map(r.cols.uncertainty, n);  // every element written below
  std::vector<float> row_unc;  // rows: the interval is not reported, only its centre
  if (uncertain[1]) row_unc.resize(n);
  // Rejected pixels' candidates for the neighbour fill, one FillRow per
  // camera row (each written by the band that decodes the row).
  const bool fill[2] = {uncertain[0] && fill_.passes > 0, uncertain[1] && fill_.passes > 0};
  std::vector<FillRow> fill_rows[2];
  for (size_t axis = 0; axis < 2; ++axis)
    if (fill[axis]) fill_rows[axis].resize(height_);
  std::vector<size_t> weak;
  decode_rows(stream_, ctx, nullptr, stream_.intensity_to_write(r.intensity), has_rows_ ? 2 : 1,
              weak, [&](size_t b, size_t e, const BaseRow& base, int32_t* idx, size_t* band_weak) {
                for (size_t axis = 0; axis < (has_rows_ ? 2u : 1u); ++axis) {
                  AxisMaps& m = axis == 0 ? r.cols : r.rows;
                  const size_t tolerated = decode_code_maps(
                      ctx, axis, maps[axis], b, e, base, idx, m.coord.data() + b,
                      m.valid.empty() ? nullptr : m.valid.data() + b,
                      m.confidence.empty() ? nullptr : m.confidence.data() + b);
                  if (uncertain[axis]) {
                    float* unc = axis == 0 ? r.cols.uncertainty.data() : row_unc.data();
                    band_weak[axis] += decode_uncertain(
                        ctx, axis, maps[axis], rule[axis], b, e, base, m.coord.data() + b,
                        m.valid.empty() ? nullptr : m.valid.data() + b, unc + b,
                        fill[axis] ? &fill_rows[axis][b / width_] : nullptr);
                  } else {
                    band_weak[axis] += tolerated;
                    if (axis == 0 && uncertain_)  // no tolerable planes: exact or invalid
                      for (size_t i = b; i < e; ++i)
                        r.cols.uncertainty[i] = std::isnan(m.coord[i]) ? std::numeric_limits<float>::quiet_NaN() : 0.0f;
                  }
                }
              });
  r.cols_weak = weak[0];
  r.rows_weak = has_rows_ ? weak[1] : 0;
  // Stripe averaging (stripe_average.hpp): the gate on every scan that kept
  // its pairs, rule A only when it fires (before the neighbour fill, which
  // then leaves the pixels it decoded alone).
  if (stripe_.mode != StripeAverageMode::off && uncertain_) {
    stripe_gate(stream_.pool(), ctx, 0, r.stripe);
    const bool run = stripe_.mode == StripeAverageMode::on ||
                     (r.stripe.available && r.stripe.f_noise >= stripe_.gate);
    if (run)
      stripe_average(stream_.pool(), ctx, 0, maps[0], rule[0], tolerable_[0], stripe_.half_length,
                     r.cols.coord.data(), r.cols.valid.data(), r.cols.uncertainty.data(), r.stripe);
  }
  if (fill[0]) {
    r.cols_filled = fill_from_neighbours(stream_.pool(), width_, height_, std::max(maps[0].scale, 1),
                                         fill_, fill_rows[0], r.cols.coord.data(), r.cols.valid.data(),
                                         r.cols.uncertainty.data(), r.cols.confidence.data());
    r.cols_weak += r.cols_filled;
  }
  if (fill[1]) {
    r.rows_filled = fill_from_neighbours(stream_.pool(), width_, height_, std::max(maps[1].scale, 1),
                                         fill_, fill_rows[1], r.rows.coord.data(), nullptr,
                                         row_unc.data(), nullptr);
    r.rows_weak += r.rows_filled;
  }
  RoundResult out = std::move(result_);
  result_ = RoundResult{};
  return out;
}

}  // namespace procam::sl
