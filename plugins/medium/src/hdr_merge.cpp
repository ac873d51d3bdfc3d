// SPDX-License-Identifier: MIT
// Streaming HDR merge (see hdr_merge.hpp).
#include "hdr_merge.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace procam::medium {

HdrMerge::HdrMerge(uint32_t width, uint32_t height, HdrSettings s)
    : w_(width), h_(height), s_(std::move(s)), sum_x_(size_t{width} * height, 0.0f), sum_t_(size_t{width} * height, 0.0f) {}

sdk::Error HdrMerge::prepare(const procam_image& frame) {
  if (type_ != 0) {
    if (frame.pixel_type != type_ || frame.bit_depth != bits_)
      return sdk::bad_frame("frame is " + sdk::describe_image(frame) +
                            " but earlier frames of this bracket differ: keep one camera mode for the whole bracket");
    return sdk::ok();
  }
  full_scale_ = sdk::full_scale(frame);
  if (frame.pixel_type == PROCAM_PIXEL_U16 && s_.camera_bits >= 8 && s_.camera_bits < frame.bit_depth)
    full_scale_ = double((uint32_t{1} << s_.camera_bits) - 1u);  // codes above are saturated (table below)
  if (frame.pixel_type != PROCAM_PIXEL_F32) {
    const size_t codes = size_t{1} << frame.bit_depth, used = static_cast<size_t>(full_scale_) + 1;
    if (!s_.lut.empty() && s_.lut.size() < used)
      return sdk::invalid_argument("response LUT has " + std::to_string(s_.lut.size()) + " entries but the camera's " +
                                   "codes 0.." + std::to_string(used - 1) + " need " + std::to_string(used) +
                                   ": give one linear value per DN code");
    lin_.resize(codes);
    a_.resize(codes);
    const double sat = s_.saturation * full_scale_, floor = s_.floor * full_scale_;
    for (size_t c = 0; c < codes; ++c) {
      const double dn = double(c);
      if (c >= used) {  // above the camera's full scale: saturated
        lin_[c] = 0.0f;
        a_[c] = 0.0f;
        continue;
      }
      const double lin = s_.lut.empty() ? full_scale_ * std::pow(dn / full_scale_, s_.gamma) : s_.lut[c];
      const double x = lin - s_.black_dn;  // not clipped at 0: noise around black must average out
      lin_[c] = static_cast<float>(x);
      a_[c] = dn >= sat ? 0.0f : (x >= floor ? 1.0f : -1.0f);  // -1: dark (weight set per frame)
    }
  }
  type_ = frame.pixel_type;
  bits_ = frame.bit_depth;
  return sdk::ok();
}

namespace {

// The per-pixel fold for integer frames: table lookups and two multiply-adds.
template <class T>
void fold_rows(const procam_image& f, uint32_t y0, uint32_t y1, uint32_t w, const float* wx, const float* wt,
               float* sum_x, float* sum_t) {
  for (uint32_t y = y0; y < y1; ++y) {
    const T* row = reinterpret_cast<const T*>(static_cast<const uint8_t*>(f.data) + size_t{y} * f.stride_bytes);
    float* sx = sum_x + size_t{y} * w;
    float* st = sum_t + size_t{y} * w;
    for (uint32_t x = 0; x < w; ++x) {
      const uint32_t c = row[x];
      sx[x] += wx[c];
      st[x] += wt[c];
    }
  }
}

}  // namespace

sdk::Error HdrMerge::add(const procam_image& frame, double exposure_us, uint32_t threads) {
  if (sdk::Error e = sdk::check_frame(&frame, w_, h_, 1, "bracket frame"); !e.ok()) return e;
  if (!(exposure_us > 0) || !std::isfinite(exposure_us))
    return sdk::invalid_argument("exposure " + std::to_string(exposure_us) + " us: every bracket frame needs a positive exposure");
  if (sdk::Error e = prepare(frame); !e.ok()) return e;
  const auto t = static_cast<float>(exposure_us);
  float* sx = sum_x_.data();
  float* st = sum_t_.data();
  // This frame's per-code contributions: good samples w = 1 (sum x, sum t),
  // dark ones w = kDark t (sum t x, sum t^2: least squares of x = L t for
  // read-noise-limited samples, dominated by the longest exposures).
  if (type_ != PROCAM_PIXEL_F32) {
    wx_.resize(lin_.size());
    wt_.resize(lin_.size());
    for (size_t c = 0; c < lin_.size(); ++c) {
      const float w = a_[c] < 0.0f ? kDark * t : a_[c];
      wx_[c] = w * lin_[c];
      wt_[c] = w * t;
    }
  }
  const float* wx = wx_.data();
  const float* wt = wt_.data();
  if (type_ == PROCAM_PIXEL_U8) {
    sdk::parallel_rows(h_, threads, [&](uint32_t y0, uint32_t y1) {
      fold_rows<uint8_t>(frame, y0, y1, w_, wx, wt, sx, st);
    });
  } else if (type_ == PROCAM_PIXEL_U16) {
    if (frame.bit_depth < 16) {
      // Codes above full scale (a sensor's stray high bits) clamp to full scale: saturated.
      const auto top = static_cast<uint32_t>(full_scale_);
      sdk::parallel_rows(h_, threads, [&](uint32_t y0, uint32_t y1) {
        for (uint32_t y = y0; y < y1; ++y) {
          const auto* row = reinterpret_cast<const uint16_t*>(static_cast<const uint8_t*>(frame.data) + size_t{y} * frame.stride_bytes);
          float* rx = sx + size_t{y} * w_;
          float* rt = st + size_t{y} * w_;
          for (uint32_t x = 0; x < w_; ++x) {
            const uint32_t c = std::min<uint32_t>(row[x], top);
            rx[x] += wx[c];
            rt[x] += wt[c];
          }
        }
      });
    } else {
      sdk::parallel_rows(h_, threads, [&](uint32_t y0, uint32_t y1) {
        fold_rows<uint16_t>(frame, y0, y1, w_, wx, wt, sx, st);
      });
    }
  } else {  // F32 in [0, 1] (full scale 1): response applied per value
    const double sat = s_.saturation, floor = s_.floor;
    sdk::parallel_rows(h_, threads, [&](uint32_t y0, uint32_t y1) {
      std::vector<float> row(w_);
      for (uint32_t y = y0; y < y1; ++y) {
        sdk::read_row(frame, y, row.data());
        for (uint32_t x = 0; x < w_; ++x) {
          const double v = std::isfinite(row[x]) ? std::clamp(double(row[x]), 0.0, 1.0) : 1.0;  // NaN/inf: unusable
          const double xv = std::pow(v, s_.gamma) - s_.black_dn;
          const double a = v >= sat ? 0.0 : (xv >= floor ? 1.0 : double(kDark) * double(t));
          sx[size_t{y} * w_ + x] += static_cast<float>(a * xv);
          st[size_t{y} * w_ + x] += static_cast<float>(a * double(t));
        }
      }
    });
  }
  ++frames_;
  return sdk::ok();
}

std::vector<float> HdrMerge::radiance() const {
  std::vector<float> r(sum_x_.size());
  for (size_t i = 0; i < r.size(); ++i)
    r[i] = sum_t_[i] > 0.0f ? sum_x_[i] / sum_t_[i] : std::numeric_limits<float>::quiet_NaN();
  return r;
}

uint64_t HdrMerge::saturated_pixels() const {
  return static_cast<uint64_t>(std::count_if(sum_t_.begin(), sum_t_.end(), [](float v) { return !(v > 0.0f); }));
}

}  // namespace procam::medium
