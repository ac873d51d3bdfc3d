// SPDX-License-Identifier: MIT
// Reading procam_image views (U8 / U16 / F32, any bit depth) as float, and
// checking a frame the host handed in before touching its pixels.
//
// Values are returned in the frame's own units: digital numbers (DN) for
// integer data (a 12-bit frame in U16 ranges 0..4095), the stored value for
// F32. full_scale() gives the value that means "white": 2^bit_depth - 1 for
// integer data, 1.0 for F32. Divide by it to normalise.
// Thread-safety: all functions are reentrant; they only read the image.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "procam/plugin_abi.h"
#include "procam/sdk/error.hpp"

namespace procam::sdk {

// A one-channel, tightly packed view of width × height samples at `data`
// (borrowed: the caller keeps the buffer alive while the view is used).
// bit_depth: significant bits of U8/U16 samples (default: all); F32 views
// report 32.
inline procam_image gray_view(const uint8_t* data, uint32_t width, uint32_t height, uint32_t bit_depth = 8) noexcept {
  procam_image v{};
  v.width = width;
  v.height = height;
  v.channels = 1;
  v.pixel_type = PROCAM_PIXEL_U8;
  v.bit_depth = bit_depth;
  v.stride_bytes = width;
  v.data = data;
  return v;
}
inline procam_image gray_view(const uint16_t* data, uint32_t width, uint32_t height, uint32_t bit_depth = 16) noexcept {
  procam_image v = gray_view(static_cast<const uint8_t*>(nullptr), width, height, bit_depth);
  v.pixel_type = PROCAM_PIXEL_U16;
  v.stride_bytes = size_t{width} * 2;
  v.data = data;
  return v;
}
inline procam_image gray_view(const float* data, uint32_t width, uint32_t height) noexcept {
  procam_image v = gray_view(static_cast<const uint8_t*>(nullptr), width, height, 32);
  v.pixel_type = PROCAM_PIXEL_F32;
  v.stride_bytes = size_t{width} * 4;
  v.data = data;
  return v;
}

// Bytes of one sample of `pixel_type`; 0 for an unknown type.
inline size_t bytes_per_sample(uint32_t pixel_type) noexcept {
  switch (pixel_type) {
    case PROCAM_PIXEL_U8: return 1;
    case PROCAM_PIXEL_U16: return 2;
    case PROCAM_PIXEL_F32: return 4;
    default: return 0;
  }
}

inline const char* pixel_type_name(uint32_t pixel_type) noexcept {
  switch (pixel_type) {
    case PROCAM_PIXEL_U8: return "U8";
    case PROCAM_PIXEL_U16: return "U16";
    case PROCAM_PIXEL_F32: return "F32";
    default: return "unknown-type";
  }
}

// "1280x800 U16/12-bit 1ch" — for error messages.
inline std::string describe_image(const procam_image& img) {
  std::string s = std::to_string(img.width) + "x" + std::to_string(img.height) + " " +
                  pixel_type_name(img.pixel_type);
  if (img.pixel_type != PROCAM_PIXEL_F32) s += "/" + std::to_string(img.bit_depth) + "-bit";
  s += " " + std::to_string(img.channels) + "ch";
  return s;
}

// Value meaning full white: 2^bit_depth - 1 for U8/U16, 1.0 for F32. The image
// must have passed check_image().
inline double full_scale(const procam_image& img) noexcept {
  if (img.pixel_type == PROCAM_PIXEL_F32) return 1.0;
  return static_cast<double>((uint32_t{1} << img.bit_depth) - 1u);
}

// Structural check of a host-supplied image: non-null data, known pixel type,
// bit_depth within the storage (U8: 1..8, U16: 1..16; ignored for F32), at
// least one channel, a stride that holds a row, and sample alignment.
// Returns PROCAM_ERR_BAD_FRAME with `what` ("frame 3") in the message.
inline Error check_image(const procam_image* img, const std::string& what) {
  if (img == nullptr) return bad_frame(what + ": image pointer is NULL");
  const size_t bps = bytes_per_sample(img->pixel_type);
  if (bps == 0)
    return bad_frame(what + ": unknown pixel_type " + std::to_string(img->pixel_type) +
                     " (expected 1=U8, 2=U16 or 3=F32)");
  if (img->width == 0 || img->height == 0)
    return bad_frame(what + ": empty image (" + describe_image(*img) + ")");
  if (img->channels == 0) return bad_frame(what + ": channels is 0");
  if (img->data == nullptr) return bad_frame(what + ": data pointer is NULL");
  if (img->pixel_type != PROCAM_PIXEL_F32 &&
      (img->bit_depth == 0 || img->bit_depth > 8 * bps))
    return bad_frame(what + ": bit_depth " + std::to_string(img->bit_depth) + " does not fit " +
                     pixel_type_name(img->pixel_type) + " storage (1.." +
                     std::to_string(8 * bps) + ")");
  const size_t row_bytes = size_t{img->width} * img->channels * bps;
  if (img->stride_bytes < row_bytes)
    return bad_frame(what + ": stride_bytes " + std::to_string(img->stride_bytes) +
                     " is smaller than a row (" + std::to_string(row_bytes) + " bytes)");
  const auto addr = reinterpret_cast<uintptr_t>(img->data);
  if (addr % bps != 0 || img->stride_bytes % bps != 0)
    return bad_frame(what + ": data or stride not aligned to " + std::to_string(bps) +
                     "-byte samples");
  return ok();
}

// check_image() plus the size and channel count the caller expects, e.g.
// "frame 3 (col bit 9): expected 1280x800 1ch, got 640x480 U8/8-bit 1ch".
inline Error check_frame(const procam_image* img, uint32_t width, uint32_t height,
                         uint32_t channels, const std::string& what) {
  if (Error e = check_image(img, what); !e.ok()) return e;
  if (img->width != width || img->height != height || img->channels != channels)
    return bad_frame(what + ": expected " + std::to_string(width) + "x" + std::to_string(height) +
                     " " + std::to_string(channels) + "ch, got " + describe_image(*img));
  return ok();
}

// Pointer to the first byte of row y. The image must have passed check_image().
inline const uint8_t* row_bytes(const procam_image& img, uint32_t y) noexcept {
  return static_cast<const uint8_t*>(img.data) + size_t{y} * img.stride_bytes;
}

// Value of channel c of pixel (x, y) as float (DN for integer data). The
// image must have passed check_image() and x, y, c must be in range.
inline float pixel_value(const procam_image& img, uint32_t x, uint32_t y, uint32_t c = 0) noexcept {
  const size_t i = size_t{x} * img.channels + c;
  const uint8_t* row = row_bytes(img, y);
  switch (img.pixel_type) {
    case PROCAM_PIXEL_U8: return static_cast<float>(row[i]);
    case PROCAM_PIXEL_U16: {
      uint16_t v;
      std::memcpy(&v, row + 2 * i, sizeof v);
      return static_cast<float>(v);
    }
    default: {
      float v;
      std::memcpy(&v, row + 4 * i, sizeof v);
      return v;
    }
  }
}

// Channel c of row y as `img.width` floats into dst (DN for integer data).
// The fast path for per-pixel loops; same preconditions as pixel_value().
inline void read_row(const procam_image& img, uint32_t y, float* dst, uint32_t c = 0) noexcept {
  const uint8_t* row = row_bytes(img, y);
  const size_t n = img.width;
  const size_t step = img.channels;
  switch (img.pixel_type) {
    case PROCAM_PIXEL_U8:
      if (step == 1) {  // contiguous: a loop the compiler vectorizes
        for (size_t x = 0; x < n; ++x) dst[x] = static_cast<float>(row[x]);
      } else {
        for (size_t x = 0; x < n; ++x) dst[x] = static_cast<float>(row[x * step + c]);
      }
      break;
    case PROCAM_PIXEL_U16: {
      const auto* p = static_cast<const uint16_t*>(static_cast<const void*>(row));
      if (step == 1) {
        for (size_t x = 0; x < n; ++x) dst[x] = static_cast<float>(p[x]);
      } else {
        for (size_t x = 0; x < n; ++x) dst[x] = static_cast<float>(p[x * step + c]);
      }
      break;
    }
    default: {
      const auto* p = static_cast<const float*>(static_cast<const void*>(row));
      if (step == 1) {
        std::memcpy(dst, p, n * sizeof(float));
      } else {
        for (size_t x = 0; x < n; ++x) dst[x] = p[x * step + c];
      }
      break;
    }
  }
}

}  // namespace procam::sdk
