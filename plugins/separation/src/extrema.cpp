// SPDX-License-Identifier: MIT
// Streaming max/min images (see extrema.hpp).
#include "extrema.hpp"

#include <cstring>

#include "procam/sdk/simd.hpp"

namespace procam::separation {

void fold_u8_scalar(const uint8_t* v, uint8_t* m, uint8_t* n, size_t count) noexcept {
  for (size_t i = 0; i < count; ++i) {
    m[i] = v[i] > m[i] ? v[i] : m[i];
    n[i] = v[i] < n[i] ? v[i] : n[i];
  }
}

void fold_u16_scalar(const uint16_t* v, uint16_t* m, uint16_t* n, size_t count) noexcept {
  for (size_t i = 0; i < count; ++i) {
    m[i] = v[i] > m[i] ? v[i] : m[i];
    n[i] = v[i] < n[i] ? v[i] : n[i];
  }
}

void fold_f32(const float* v, float* m, float* n, size_t count) noexcept {
  for (size_t i = 0; i < count; ++i) {
    const float x = v[i];
    // A NaN sample (x != x) replaces the extremum; a NaN extremum stays NaN
    // because no comparison with it is true.
    m[i] = (x > m[i] || x != x) ? x : m[i];
    n[i] = (x < n[i] || x != x) ? x : n[i];
  }
}

#ifdef PROCAM_SDK_X86
namespace {
__attribute__((target("avx2"))) void fold_u8_avx2(const uint8_t* v, uint8_t* m, uint8_t* n, size_t count) noexcept {
  size_t i = 0;
  for (; i + 32 <= count; i += 32) {
    const __m256i x = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(v + i));
    const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(m + i));
    const __m256i b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(n + i));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(m + i), _mm256_max_epu8(a, x));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(n + i), _mm256_min_epu8(b, x));
  }
  fold_u8_scalar(v + i, m + i, n + i, count - i);
}
__attribute__((target("avx2"))) void fold_u16_avx2(const uint16_t* v, uint16_t* m, uint16_t* n,
                                                   size_t count) noexcept {
  size_t i = 0;
  for (; i + 16 <= count; i += 16) {
    const __m256i x = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(v + i));
    const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(m + i));
    const __m256i b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(n + i));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(m + i), _mm256_max_epu16(a, x));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(n + i), _mm256_min_epu16(b, x));
  }
  fold_u16_scalar(v + i, m + i, n + i, count - i);
}
}  // namespace
#endif

void fold_u8(const uint8_t* v, uint8_t* m, uint8_t* n, size_t count) noexcept {
#ifdef PROCAM_SDK_X86
  if (sdk::cpu_has_avx2()) return fold_u8_avx2(v, m, n, count);
#endif
  fold_u8_scalar(v, m, n, count);
}

void fold_u16(const uint16_t* v, uint16_t* m, uint16_t* n, size_t count) noexcept {
#ifdef PROCAM_SDK_X86
  if (sdk::cpu_has_avx2()) return fold_u16_avx2(v, m, n, count);
#endif
  fold_u16_scalar(v, m, n, count);
}

sdk::Error Extrema::add(const procam_image& frame, uint32_t threads) {
  if (count_ > 0 && frame.pixel_type != type_)
    return sdk::bad_frame(std::string("frame is ") + sdk::pixel_type_name(frame.pixel_type) +
                          " but the earlier frames of this series were " + sdk::pixel_type_name(type_) +
                          ": every frame of a scan must come from the same camera mode");
  const size_t bps = sdk::bytes_per_sample(frame.pixel_type);
  const size_t row_bytes = size_t{width_} * bps;
  const bool first = count_ == 0;
  if (first) {
    type_ = frame.pixel_type;
    max_.resize(row_bytes * height_);
    min_.resize(row_bytes * height_);
  }
  const uint32_t type = type_;
  sdk::parallel_rows(height_, threads, [&](uint32_t y0, uint32_t y1) {
    for (uint32_t y = y0; y < y1; ++y) {
      const uint8_t* src = sdk::row_bytes(frame, y);
      uint8_t* m = max_.data() + row_bytes * y;
      uint8_t* n = min_.data() + row_bytes * y;
      if (first) {
        std::memcpy(m, src, row_bytes);
        std::memcpy(n, src, row_bytes);
        continue;
      }
      switch (type) {
        case PROCAM_PIXEL_U8: fold_u8(src, m, n, width_); break;
        case PROCAM_PIXEL_U16:
          fold_u16(reinterpret_cast<const uint16_t*>(src), reinterpret_cast<uint16_t*>(m),
                   reinterpret_cast<uint16_t*>(n), width_);
          break;
        default:
          fold_f32(reinterpret_cast<const float*>(src), reinterpret_cast<float*>(m), reinterpret_cast<float*>(n),
                   width_);
          break;
      }
    }
  });
  ++count_;
  return sdk::ok();
}

void Extrema::row(const std::vector<uint8_t>& map, uint32_t y, float* dst) const noexcept {
  const procam_image view = [&] {
    procam_image v{};
    v.width = width_;
    v.height = height_;
    v.channels = 1;
    v.pixel_type = type_;
    v.bit_depth = type_ == PROCAM_PIXEL_U8 ? 8 : (type_ == PROCAM_PIXEL_U16 ? 16 : 32);
    v.stride_bytes = size_t{width_} * sdk::bytes_per_sample(type_);
    v.data = map.data();
    return v;
  }();
  sdk::read_row(view, y, dst);
}

}  // namespace procam::separation
