// SPDX-License-Identifier: MIT
// Ensemble vote and classification (thesis §3.3.3, §3.4; see vote.hpp).
#include "vote.hpp"

#include <cmath>
#include <limits>

namespace procam::sl {

const char* transport_class_name(uint8_t c) {
  switch (c) {
    case kUnlit: return "unlit";
    case kAllAgree: return "all_agree";
    case kInterreflection: return "interreflection";
    case kSubsurface: return "subsurface";
    case kPartial: return "partial";
    case kError: return "error";
    default: return "unknown";
  }
}

void vote_pixels(const float* const code[kEnsembleCodes], const uint8_t* lit, size_t begin,
                 size_t end, float agree_px, float* coord, uint8_t* valid, float* confidence,
                 uint8_t* cls) {
  constexpr uint32_t kPreference[kEnsembleCodes] = {kGray, kXor04, kXor02, kMinsw};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (size_t i = begin; i < end; ++i) {
    float v[kEnsembleCodes];
    for (uint32_t k = 0; k < kEnsembleCodes; ++k) v[k] = code[k][i];
    uint32_t support[kEnsembleCodes] = {0, 0, 0, 0};
    uint32_t pairs = 0;
    bool gray_pair = false, logical_pair = false;
    for (uint32_t a = 0; a < kEnsembleCodes; ++a)
      for (uint32_t b = a + 1; b < kEnsembleCodes; ++b) {
        // NaN compares false: an invalid code never agrees.
        if (std::fabs(v[a] - v[b]) <= agree_px) {
          ++support[a];
          ++support[b];
          ++pairs;
          if (a == kGray && b == kMinsw) gray_pair = true;
          if (a == kXor02 && b == kXor04) logical_pair = true;
        }
      }
    uint32_t best = 0;
    for (uint32_t k = 0; k < kEnsembleCodes; ++k) best = support[k] > best ? support[k] : best;
    if (best == 0 || lit[i] == 0) {
      coord[i] = nan;
      valid[i] = 0;
      confidence[i] = 0.0f;
      cls[i] = lit[i] != 0 ? kError : kUnlit;
      continue;
    }
    uint32_t pick = kGray;
    uint8_t c = kPartial;
    if (pairs == 1 && gray_pair) {
      pick = kMinsw;
      c = kSubsurface;
    } else if (pairs == 1 && logical_pair) {
      pick = kXor04;
      c = kInterreflection;
    } else {
      for (uint32_t k : kPreference)
        if (support[k] == best) {
          pick = k;
          break;
        }
      c = pairs == 6 ? kAllAgree : kPartial;
    }
    coord[i] = v[pick];
    valid[i] = 255;
    confidence[i] = static_cast<float>(best + 1) / 4.0f;
    cls[i] = c;
  }
}

}  // namespace procam::sl
