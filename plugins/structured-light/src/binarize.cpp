// SPDX-License-Identifier: MIT
// Bit-plane binarization kernels (thesis Eq. 3.5 and §3.2 footnote 2).
#include "binarize.hpp"

#include <cmath>
#include <limits>

namespace procam::sl {

void fold_plane(const float* __restrict L, const float* __restrict L_bar, size_t n,
                uint32_t position, float saturation, uint16_t* __restrict word,
                float* __restrict min_margin, uint8_t* __restrict flags) {
  const auto bit = static_cast<uint16_t>(1u << position);
  // Branch-free so the compiler can vectorize; NaN/inf are caught by the
  // flag (a NaN margin never lowers min_margin: the comparison is false).
  for (size_t i = 0; i < n; ++i) {
    const float l = L[i], lb = L_bar[i];
    const float d = l - lb;
    const float margin = std::fabs(d);
    word[i] = static_cast<uint16_t>(word[i] | (d > 0.0f ? bit : 0));  // Eq. 3.5: lit when L > L̄
    min_margin[i] = margin < min_margin[i] ? margin : min_margin[i];
    const int saturated = (l >= saturation) & (lb >= saturation);
    const int non_finite = !(margin <= std::numeric_limits<float>::max());
    flags[i] = static_cast<uint8_t>(flags[i] | saturated * kFlagSaturated |
                                    non_finite * kFlagNonFinite);
  }
}

void fold_plane_u8_synthetic(const uint8_t* __restrict L, const uint16_t* __restrict sum, size_t n,
                             uint32_t position, int32_t saturation, uint16_t* __restrict word,
                             float* __restrict min_margin, uint8_t* __restrict flags) {
  const auto bit = static_cast<uint16_t>(1u << position);
  for (size_t i = 0; i < n; ++i) {
    const int32_t l = L[i], s = sum[i];
    const int32_t d = 2 * l - s;  // L - L̄ with L̄ = S - L
    const auto margin = static_cast<float>(d < 0 ? -d : d);
    word[i] = static_cast<uint16_t>(word[i] | (d > 0 ? bit : 0));
    min_margin[i] = margin < min_margin[i] ? margin : min_margin[i];
    const int saturated = (l >= saturation) & (s - l >= saturation);
    flags[i] = static_cast<uint8_t>(flags[i] | saturated * kFlagSaturated);
  }
}

void synthesize_inverse(const float* L, const float* white, const float* black, size_t n,
                        float* L_bar) {
  for (size_t i = 0; i < n; ++i) L_bar[i] = white[i] + black[i] - L[i];
}

}  // namespace procam::sl
