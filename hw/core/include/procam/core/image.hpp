// SPDX-License-Identifier: MIT
// Image: an owning, contiguous, single- or multi-channel pixel buffer, and
// conversions to/from the plugin ABI's procam_image view.
//
// Contract: rows are tightly packed (stride = width * channels * bytes per
// sample). Integer images carry `bit_depth` significant, right-aligned bits.
// Not thread-safe for concurrent mutation; const access is safe from any thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "procam/pixel.h"

namespace procam {

enum class PixelType : uint32_t {
  u8 = PROCAM_PIXEL_U8,
  u16 = PROCAM_PIXEL_U16,
  f32 = PROCAM_PIXEL_F32,
};

constexpr size_t bytes_per_sample(PixelType t) {
  return t == PixelType::u8 ? 1 : t == PixelType::u16 ? 2 : 4;
}

class Image {
public:
  Image() = default;
  // Zero-filled. bit_depth 0 means "full width of the type" (8, 16, 32).
  Image(uint32_t width, uint32_t height, PixelType type, uint32_t channels = 1,
        uint32_t bit_depth = 0);

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  uint32_t channels() const { return channels_; }
  PixelType type() const { return type_; }
  uint32_t bit_depth() const { return bit_depth_; }
  void set_bit_depth(uint32_t bits) { bit_depth_ = bits; }
  bool empty() const { return data_.empty(); }
  size_t stride_bytes() const { return size_t{width_} * channels_ * bytes_per_sample(type_); }
  size_t size_bytes() const { return data_.size(); }
  size_t pixel_count() const { return size_t{width_} * height_; }

  uint8_t* data() { return data_.data(); }
  const uint8_t* data() const { return data_.data(); }
  template <typename T> T* ptr() { return reinterpret_cast<T*>(data_.data()); }
  template <typename T> const T* ptr() const { return reinterpret_cast<const T*>(data_.data()); }
  template <typename T> T* row(uint32_t y) { return ptr<T>() + size_t{y} * width_ * channels_; }
  template <typename T> const T* row(uint32_t y) const { return ptr<T>() + size_t{y} * width_ * channels_; }
  template <typename T> T& at(uint32_t x, uint32_t y, uint32_t c = 0) {
    return ptr<T>()[(size_t{y} * width_ + x) * channels_ + c];
  }
  template <typename T> const T& at(uint32_t x, uint32_t y, uint32_t c = 0) const {
    return ptr<T>()[(size_t{y} * width_ + x) * channels_ + c];
  }

  // Largest integer value (2^bit_depth - 1); 1.0 for f32.
  double max_value() const;

  // Non-owning ABI view; valid while this Image lives and is not resized.
  procam_image view() const;
  // Deep copy of any view (any stride); fails (returns empty) on a bad view.
  static Image copy_of(const procam_image& v);

private:
  uint32_t width_ = 0, height_ = 0, channels_ = 1;
  PixelType type_ = PixelType::u8;
  uint32_t bit_depth_ = 8;
  std::vector<uint8_t> data_;
};

// Validates a view from outside (plugin or file): known type, sane bit depth,
// non-null data, stride >= packed row size. Returns nullptr if fine, else a
// static message naming the problem.
const char* validate_view(const procam_image& v);

}  // namespace procam
