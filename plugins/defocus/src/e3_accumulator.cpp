// SPDX-License-Identifier: MIT
// Streaming E(3, f) accumulation (see e3_accumulator.hpp for the model).
#include "e3_accumulator.hpp"

#include <cmath>
#include <string>
#include <type_traits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace procam::defocus {

// The four buckets D_0..D_3 of one focus setting, in the accumulator type of
// the frames: int16 (8-bit: |D| <= 6·255), int32 (<= 16-bit: |D| <= 6·65535)
// or float.
struct E3Accumulator::Buckets {
  std::vector<int16_t> i16;
  std::vector<int32_t> i32;
  std::vector<float> f32;
  // Sized for 4 buckets of n pixels. Not cleared: the first frame of each
  // bucket overwrites it (add_rows' `first`), which saves a 4n-element
  // memset per focus setting and one read per pixel of those frames.
  void size_for(uint32_t type, size_t n) {
    if (type == PROCAM_PIXEL_U8) i16.resize(4 * n);
    else if (type == PROCAM_PIXEL_U16) i32.resize(4 * n);
    else f32.resize(4 * n);
  }
};

namespace {

// Saturation bits of one row: bit x of `bits` is set where row[x] >= sat
// (for F32 also where it is NaN or inf: !(v < sat)).
template <class In>
void saturation_bits(const In* row, uint32_t w, In sat, uint8_t* bits) {
  uint32_t x = 0;
#if defined(__SSE2__)
  if constexpr (std::is_same_v<In, uint8_t>) {
    // 16 pixels per step: v >= sat  <=>  max(v, sat) == v (SSE2 is baseline on x86-64).
    const __m128i s = _mm_set1_epi8(static_cast<char>(sat));
    for (; x + 16 <= w; x += 16) {
      const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + x));
      const auto m = static_cast<uint32_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(v, s), v)));
      if (m == 0) continue;
      // x is a multiple of 16 here: bytes x/8 and x/8 + 1 hold these 16 bits.
      bits[x / 8] |= static_cast<uint8_t>(m & 0xffu);
      bits[x / 8 + 1] |= static_cast<uint8_t>(m >> 8);
    }
  }
#endif
  for (; x < w; ++x)
    if (!(row[x] < sat)) bits[x / 8] |= static_cast<uint8_t>(1u << (x % 8));
}

// One band of rows of a frame into bucket `d` (+ or - by `negative`; the
// bucket's first frame, `first`, overwrites it), the DC sum (when
// dc != nullptr; `dc_first` overwrites) and the saturation bits (`bit_stride`
// bytes per row). Separate simple loops per row so each vectorises.
template <class In, class Acc>
void add_rows(const procam_image& frame, Acc* d, bool negative, bool first, float* dc, bool dc_first, uint8_t* bits,
              size_t bit_stride, In saturated_at, uint32_t y0, uint32_t y1) {
  const uint32_t w = frame.width;
  for (uint32_t y = y0; y < y1; ++y) {
    const In* row = reinterpret_cast<const In*>(sdk::row_bytes(frame, y));
    Acc* b = d + size_t{y} * w;
    if (first && negative)
      for (uint32_t x = 0; x < w; ++x) b[x] = static_cast<Acc>(-static_cast<Acc>(row[x]));
    else if (first)
      for (uint32_t x = 0; x < w; ++x) b[x] = static_cast<Acc>(row[x]);
    else if (negative)
      for (uint32_t x = 0; x < w; ++x) b[x] = static_cast<Acc>(b[x] - static_cast<Acc>(row[x]));
    else
      for (uint32_t x = 0; x < w; ++x) b[x] = static_cast<Acc>(b[x] + static_cast<Acc>(row[x]));
    if (dc != nullptr) {
      float* s = dc + size_t{y} * w;
      if (dc_first)
        for (uint32_t x = 0; x < w; ++x) s[x] = static_cast<float>(row[x]);
      else
        for (uint32_t x = 0; x < w; ++x) s[x] += static_cast<float>(row[x]);
    }
    saturation_bits(row, w, saturated_at, bits + size_t{y} * bit_stride);
  }
}

// E3 of pixels [b, e) from the four buckets (e3_from_buckets).
template <class Acc>
void fold_rows(const Acc* d, size_t n, float* e3, size_t b, size_t e) {
  const Acc* d0 = d;
  const Acc* d1 = d + n;
  const Acc* d2 = d + 2 * n;
  const Acc* d3 = d + 3 * n;
  for (size_t i = b; i < e; ++i)
    e3[i] = e3_from_buckets(static_cast<float>(d0[i]), static_cast<float>(d1[i]), static_cast<float>(d2[i]),
                            static_cast<float>(d3[i]));
}

}  // namespace

E3Accumulator::E3Accumulator(uint32_t width, uint32_t height, uint32_t focus_count, uint32_t pixel_type,
                             double full_scale, uint32_t threads)
    : width_(width),
      height_(height),
      focus_count_(focus_count),
      pixel_type_(pixel_type),
      threads_(threads < 1 ? 1 : threads),
      full_scale_(full_scale),
      e3_(focus_count),
      seen_(focus_count, 0),
      active_(focus_count) {
  const size_t n = size_t{width} * height;
  for (auto& m : e3_) m.assign(n, 0.f);
  mean_.assign(n, 0.f);
  dc_.assign(n, 0.f);
  bit_stride_ = (size_t{width} + 7) / 8;
  sat_bits_.assign(bit_stride_ * height, 0);
}

E3Accumulator::~E3Accumulator() = default;
E3Accumulator::E3Accumulator(E3Accumulator&&) noexcept = default;
E3Accumulator& E3Accumulator::operator=(E3Accumulator&&) noexcept = default;

bool E3Accumulator::complete() const noexcept {
  constexpr uint32_t all = (1u << kPeriodPx) - 1u;
  for (uint32_t s : seen_)
    if (s != all) return false;
  return true;
}

sdk::Error E3Accumulator::add(uint32_t focus, uint32_t shift, const procam_image& frame) {
  if (focus >= focus_count_ || shift >= kPeriodPx)
    return sdk::invalid_argument("defocus: frame (focus " + std::to_string(focus) + ", shift " +
                                 std::to_string(shift) + ") is outside the sweep of " +
                                 std::to_string(focus_count_) + " focus settings x 24 shifts");
  if (seen_[focus] & (1u << shift))
    return sdk::invalid_argument("defocus: frame (focus " + std::to_string(focus) + ", shift " +
                                 std::to_string(shift) + ") was already added");
  if (frame.pixel_type != pixel_type_ || frame.width != width_ || frame.height != height_ || frame.channels != 1)
    return sdk::bad_frame("defocus: frame (focus " + std::to_string(focus) + ", shift " + std::to_string(shift) +
                          ") is " + sdk::describe_image(frame) + "; expected " + std::to_string(width_) + "x" +
                          std::to_string(height_) + " 1-channel " + sdk::pixel_type_name(pixel_type_) +
                          " like the first frame (the camera's format)");
  const size_t n = size_t{width_} * height_;
  if (!active_[focus]) {
    if (!spare_.empty()) {
      active_[focus] = std::move(spare_.back());
      spare_.pop_back();
    } else {
      active_[focus] = std::make_unique<Buckets>();
    }
    active_[focus]->size_for(pixel_type_, n);
  }
  Buckets& bk = *active_[focus];
  const uint32_t b = shift % 4;
  const bool negative = (shift % 8) >= 4;
  // Bucket b takes shifts b, b + 4, ..., b + 20: the first of them to arrive overwrites it.
  const bool first = (seen_[focus] & (0x111111u << b)) == 0;
  float* dc = focus == 0 ? dc_.data() : nullptr;
  const bool dc_first = seen_[focus] == 0;
  uint8_t* bits = sat_bits_.data();
  sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
    if (pixel_type_ == PROCAM_PIXEL_U8) {
      const auto sat = static_cast<uint8_t>(std::min(255.0, full_scale_));
      add_rows<uint8_t, int16_t>(frame, bk.i16.data() + b * n, negative, first, dc, dc_first, bits, bit_stride_, sat, y0, y1);
    } else if (pixel_type_ == PROCAM_PIXEL_U16) {
      const auto sat = static_cast<uint16_t>(std::min(65535.0, full_scale_));
      add_rows<uint16_t, int32_t>(frame, bk.i32.data() + b * n, negative, first, dc, dc_first, bits, bit_stride_, sat, y0, y1);
    } else {
      add_rows<float, float>(frame, bk.f32.data() + b * n, negative, first, dc, dc_first, bits, bit_stride_,
                              static_cast<float>(full_scale_), y0, y1);
    }
  });
  seen_[focus] |= 1u << shift;
  if (seen_[focus] == (1u << kPeriodPx) - 1u) {
    if (defer_final_fold_ && focus != 0 && pixel_type_ == PROCAM_PIXEL_U8 && complete())
      pending_ = focus;  // folded inside fbar_depth_map's pass, or by fold_pending()
    else
      fold(focus);
  }
  return sdk::ok();
}

E3Accumulator::PendingBuckets E3Accumulator::pending_buckets() const noexcept {
  if (pending_ < 0) return {};
  return {active_[static_cast<size_t>(pending_)]->i16.data(), static_cast<uint32_t>(pending_)};
}

void E3Accumulator::fold_pending() {
  if (pending_ < 0) return;
  const auto focus = static_cast<uint32_t>(pending_);
  pending_ = -1;
  fold(focus);
}

void E3Accumulator::fold(uint32_t focus) {
  const size_t n = size_t{width_} * height_;
  Buckets& bk = *active_[focus];
  float* out = e3_[focus].data();
  sdk::parallel_rows(height_, threads_, [&](uint32_t y0, uint32_t y1) {
    const size_t b = size_t{y0} * width_, e = size_t{y1} * width_;
    if (pixel_type_ == PROCAM_PIXEL_U8) fold_rows(bk.i16.data(), n, out, b, e);
    else if (pixel_type_ == PROCAM_PIXEL_U16) fold_rows(bk.i32.data(), n, out, b, e);
    else fold_rows(bk.f32.data(), n, out, b, e);
    if (focus == 0)
      for (size_t i = b; i < e; ++i) mean_[i] = dc_[i] / static_cast<float>(kPeriodPx);
  });
  spare_.push_back(std::move(active_[focus]));
}

}  // namespace procam::defocus
