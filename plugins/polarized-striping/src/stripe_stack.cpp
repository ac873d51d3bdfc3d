// SPDX-License-Identifier: MIT
// Streaming top-2 / sum state of a light-stripe scan (see stripe_stack.hpp).
#include "stripe_stack.hpp"

#include "procam/sdk/map_cache.hpp"
#include "procam/sdk/simd.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace procam::polarized_striping {

StripeStack::StripeStack(uint32_t width, uint32_t height, bool packed, uint32_t expected_frames)
    : width_(width), height_(height), packed_(packed), expected_frames_(packed ? expected_frames : 0) {
  const size_t n = size_t{width} * height;
  // allocate_map: huge pages advised, so the first frame faults ~2 MiB pages,
  // not 4 KiB ones.
  if (packed) {
    sdk::allocate_map(key1_, n);
    sdk::allocate_map(key2_, n);
    sdk::allocate_map(sum16_, n);
    if (expected_frames_ > 0) {
      const size_t m = n == 0 ? 0 : (n - 1) / dop_sample_stride(n) + 1;
      sample_key1_.resize(m), sample_key2_.resize(m), sample_sum_.resize(m);
    }
    return;
  }
  sdk::allocate_map(top1_, n);
  sdk::allocate_map(top2_, n);
  std::fill(top1_.begin(), top1_.end(), -std::numeric_limits<float>::infinity());
  std::fill(top2_.begin(), top2_.end(), -std::numeric_limits<float>::infinity());
  sdk::allocate_map(sum_, n);
  sdk::allocate_map(idx1_, n);
  sdk::allocate_map(idx2_, n);
}

namespace {

// One row, branch-free so the compiler can vectorise it. Ties: the lower
// stripe index ranks higher, so the result does not depend on frame order.
void fold_row(const float* v, size_t n, uint16_t k, float* t1, float* t2, float* sm, uint16_t* i1, uint16_t* i2) {
  for (size_t x = 0; x < n; ++x) {
    const float a = v[x], o1 = t1[x], o2 = t2[x];
    const uint16_t j1 = i1[x], j2 = i2[x];
    const bool above1 = a > o1 || (a == o1 && k < j1);
    const bool above2 = a > o2 || (a == o2 && k < j2);
    t2[x] = above1 ? o1 : (above2 ? a : o2);
    i2[x] = above1 ? j1 : (above2 ? k : j2);
    t1[x] = above1 ? a : o1;
    i1[x] = above1 ? k : j1;
    sm[x] += a;
  }
}

// Packed U8 row: key = (value << 8) | (255 - k) orders by value, then by
// lower stripe index; top2 = max(top2, min(old top1, key)). Unsigned 16-bit
// max/min only: with AVX2 (SSE2 has no unsigned 16-bit max) 16 pixels per
// instruction; the baseline build is the same source for other CPUs.
#define PROCAM_FOLD_ROW_U8_BODY                                                  \
  for (size_t x = 0; x < n; ++x) {                                               \
    const auto key = static_cast<uint16_t>((uint16_t(v[x]) << 8) | low);        \
    const uint16_t o1 = k1[x], o2 = k2[x];                                       \
    const uint16_t lo = o1 < key ? o1 : key; /* values, not std::min's refs */   \
    k1[x] = o1 > key ? o1 : key;                                                 \
    k2[x] = o2 > lo ? o2 : lo;                                                   \
    sm[x] = static_cast<uint16_t>(sm[x] + v[x]);                                 \
  }

void fold_row_u8_base(const uint8_t* __restrict v, size_t n, uint16_t low, uint16_t* __restrict k1,
                      uint16_t* __restrict k2, uint16_t* __restrict sm) {
  PROCAM_FOLD_ROW_U8_BODY
}

#ifdef PROCAM_SDK_X86
__attribute__((target("avx2"))) void fold_row_u8_avx2(const uint8_t* __restrict v, size_t n, uint16_t low,
                                                      uint16_t* __restrict k1, uint16_t* __restrict k2,
                                                      uint16_t* __restrict sm) {
  PROCAM_FOLD_ROW_U8_BODY
}
#endif
#undef PROCAM_FOLD_ROW_U8_BODY

void fold_row_u8(const uint8_t* v, size_t n, uint16_t low, uint16_t* k1, uint16_t* k2, uint16_t* sm) {
#ifdef PROCAM_SDK_X86
  if (sdk::cpu_has_avx2()) return fold_row_u8_avx2(v, n, low, k1, k2, sm);
#endif
  fold_row_u8_base(v, n, low, k1, k2, sm);
}

}  // namespace

void StripeStack::add(const procam_image& frame, uint16_t k, uint32_t threads) {
  const uint32_t w = width_;
  if (packed_) {
    const auto low = static_cast<uint16_t>(255u - k);
    const bool sample = expected_frames_ > 0 && frames_ + 1 == expected_frames_;  // the final state: keep the DOP sample
    const size_t stride = dop_sample_stride(size_t{w} * height_);
    sdk::parallel_rows(height_, threads, [&](uint32_t y0, uint32_t y1) {
      for (uint32_t y = y0; y < y1; ++y) {
        const size_t o = size_t{y} * w;
        fold_row_u8(sdk::row_bytes(frame, y), w, low, key1_.data() + o, key2_.data() + o, sum16_.data() + o);
        if (!sample) continue;
        for (size_t i = (o + stride - 1) / stride * stride; i < o + w; i += stride) {  // rows are disjoint: so are j
          const size_t j = i / stride;
          sample_key1_[j] = key1_[i], sample_key2_[j] = key2_[i], sample_sum_[j] = sum16_[i];
        }
      }
    });
    if (sample) sample_frames_ = frames_ + 1;
  } else {
    sdk::parallel_rows(height_, threads, [&](uint32_t y0, uint32_t y1) {
      std::vector<float> row(w);
      for (uint32_t y = y0; y < y1; ++y) {
        sdk::read_row(frame, y, row.data());
        const size_t o = size_t{y} * w;
        fold_row(row.data(), w, k, top1_.data() + o, top2_.data() + o, sum_.data() + o, idx1_.data() + o,
                 idx2_.data() + o);
      }
    });
  }
  ++frames_;
}

}  // namespace procam::polarized_striping
