// SPDX-License-Identifier: MIT
// Streaming per-pixel maximum and minimum over a series of frames: the
// max-image e⁺ and min-image e⁻ of thesis §2.5 (Eq. 2.11–2.14), taken over
// the shifted checkerboards of one focus setting.
//
// State is two camera-sized maps in the frames' own sample type (U8, U16 or
// F32), so memory is O(pixels) per focus setting whatever the frame count,
// and an 8-bit frame costs one SIMD max/min pass (AVX2 where the CPU has it,
// chosen at run time; a scalar twin gives identical results).
//
// Units: the frames' own (DN for integer data). F32 samples that are NaN
// make the pixel's max and min NaN from then on (the pixel becomes invalid
// downstream), never silently skipped.
// Errors: add() returns BAD_FRAME when a frame's pixel type differs from the
// first frame's, and leaves the state unchanged.
// Threads: thread-bound (docs/threading.md); add() splits rows over
// sdk::parallel_rows workers internally.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace procam::separation {

class Extrema {
 public:
  Extrema() = default;
  Extrema(uint32_t width, uint32_t height) : width_(width), height_(height) {}

  // Folds `frame` (already checked for size: sdk::check_frame) into the running
  // max and min. The first frame sets the sample type.
  sdk::Error add(const procam_image& frame, uint32_t threads);

  uint32_t count() const noexcept { return count_; }
  uint32_t width() const noexcept { return width_; }
  uint32_t height() const noexcept { return height_; }
  uint32_t pixel_type() const noexcept { return type_; }

  // Row y of the max (or min) map as floats in frame units. count() > 0.
  void max_row(uint32_t y, float* dst) const noexcept { row(max_, y, dst); }
  void min_row(uint32_t y, float* dst) const noexcept { row(min_, y, dst); }
  // Row y of the max (min) map in its own sample type (pixel_type()). count() > 0.
  template <class T>
  const T* max_data(uint32_t y) const noexcept {
    return reinterpret_cast<const T*>(max_.data()) + size_t{y} * width_;
  }
  template <class T>
  const T* min_data(uint32_t y) const noexcept {
    return reinterpret_cast<const T*>(min_.data()) + size_t{y} * width_;
  }

 private:
  void row(const std::vector<uint8_t>& m, uint32_t y, float* dst) const noexcept;

  uint32_t width_ = 0, height_ = 0;
  uint32_t type_ = 0;  // procam_pixel_type of the first frame
  uint32_t count_ = 0;
  std::vector<uint8_t> max_, min_;  // width*height samples of type_, packed
};

// The kernels, exposed for the SIMD-vs-scalar test: m = max(m, v), n = min(n, v)
// over `count` samples.
void fold_u8_scalar(const uint8_t* v, uint8_t* m, uint8_t* n, size_t count) noexcept;
void fold_u8(const uint8_t* v, uint8_t* m, uint8_t* n, size_t count) noexcept;  // dispatched
void fold_u16_scalar(const uint16_t* v, uint16_t* m, uint16_t* n, size_t count) noexcept;
void fold_u16(const uint16_t* v, uint16_t* m, uint16_t* n, size_t count) noexcept;
void fold_f32(const float* v, float* m, float* n, size_t count) noexcept;  // NaN propagates

}  // namespace procam::separation
