// SPDX-License-Identifier: MIT
// Per-pixel decode with validity rules (thesis §3.2; see decode.hpp).
#include "decode.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace procam::sl {

void decode_pixels(const BitAccumulator& acc, const StripeCode& code, const float* white,
                   const float* black, size_t begin, size_t end, const DecodeThresholds& t,
                   float* coord, uint8_t* valid, float* confidence) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (size_t i = begin; i < end; ++i) {
    const float contrast = white[i] - black[i];
    const float margin = acc.min_margin[i];
    const bool finite = std::isfinite(contrast) && std::isfinite(white[i]) &&
                        std::isfinite(black[i]) && (acc.flags[i] & kFlagNonFinite) == 0;
    float conf = 0.0f;
    if (finite && contrast > 0.0f && std::isfinite(margin)) conf = std::min(margin / contrast, 1.0f);
    confidence[i] = conf;
    bool ok = finite && contrast > 0.0f && contrast >= t.min_contrast_abs &&
              (acc.flags[i] & kFlagSaturated) == 0 && margin > t.min_bit_margin * contrast;
    uint32_t c = StripeCode::kInvalid;
    if (ok) {
      c = code.decode(acc.word[i]);
      ok = c != StripeCode::kInvalid;
    }
    coord[i] = ok ? static_cast<float>(c) : nan;
    valid[i] = ok ? 255 : 0;
  }
}

}  // namespace procam::sl
