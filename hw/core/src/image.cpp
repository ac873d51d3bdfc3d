// SPDX-License-Identifier: MIT
// Image buffer and ABI view conversions.
#include "procam/core/image.hpp"

namespace procam {

Image::Image(uint32_t width, uint32_t height, PixelType type, uint32_t channels,
             uint32_t bit_depth)
    : width_(width), height_(height), channels_(channels), type_(type) {
  uint32_t full = static_cast<uint32_t>(bytes_per_sample(type) * 8);
  bit_depth_ = bit_depth == 0 ? full : bit_depth;
  data_.assign(size_t{width} * height * channels * bytes_per_sample(type), 0);
}

double Image::max_value() const {
  if (type_ == PixelType::f32) return 1.0;
  return static_cast<double>((uint64_t{1} << bit_depth_) - 1);
}

procam_image Image::view() const {
  procam_image v{};
  v.width = width_;
  v.height = height_;
  v.channels = channels_;
  v.pixel_type = static_cast<uint32_t>(type_);
  v.bit_depth = bit_depth_;
  v.stride_bytes = stride_bytes();
  v.data = data_.data();
  return v;
}

const char* validate_view(const procam_image& v) {
  if (v.pixel_type != PROCAM_PIXEL_U8 && v.pixel_type != PROCAM_PIXEL_U16 &&
      v.pixel_type != PROCAM_PIXEL_F32)
    return "unknown pixel type";
  if (v.width == 0 || v.height == 0) return "empty image";
  if (v.width > 65536 || v.height > 65536) return "image larger than 65536 pixels on a side";
  if (v.channels == 0 || v.channels > 4) return "channel count must be 1..4";
  if (v.data == nullptr) return "null pixel data";
  size_t bps = bytes_per_sample(static_cast<PixelType>(v.pixel_type));
  if (v.stride_bytes < size_t{v.width} * v.channels * bps) return "row stride smaller than a row";
  if (v.pixel_type == PROCAM_PIXEL_U8 && (v.bit_depth == 0 || v.bit_depth > 8))
    return "8-bit storage needs bit_depth 1..8";
  if (v.pixel_type == PROCAM_PIXEL_U16 && (v.bit_depth == 0 || v.bit_depth > 16))
    return "16-bit storage needs bit_depth 1..16";
  return nullptr;
}

Image Image::copy_of(const procam_image& v) {
  if (validate_view(v) != nullptr) return {};
  auto type = static_cast<PixelType>(v.pixel_type);
  Image img(v.width, v.height, type, v.channels,
            type == PixelType::f32 ? 32 : v.bit_depth);
  const size_t row = img.stride_bytes();
  const auto* src = static_cast<const uint8_t*>(v.data);
  for (uint32_t y = 0; y < v.height; ++y)
    std::memcpy(img.data() + y * row, src + y * v.stride_bytes, row);
  return img;
}

}  // namespace procam
