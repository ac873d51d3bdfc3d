// SPDX-License-Identifier: MIT
// Test-only: the synthetic stereo rigs and media of the media-stereo tests,
// and error statistics against the renderer's truth.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "synthetic.hpp"

namespace procam::media_stereo::test {

// Tank-scale medium: σ = 0.0015 /mm (1.5 /m), albedo β/σ = 0.8, g = 0.5. At the
// 500 mm scene the round trip attenuates by e^{-1.5}, and backscatter is
// comparable to the direct signal (see the tests' printed B/D ratio).
inline MediumParams tank_medium() { return {0.0015, 0.0012, 0.5}; }
constexpr double kLightIntensity = 250000.0;  // 1.0 at 500 mm in clear air
constexpr uint32_t kWidth = 128, kHeight = 96;
constexpr double kFocalPx = 170.0;

// Binocular rig: cameras 150 mm apart at z = 0 verging on (0, 0, 520); the
// light beside the left camera and raised ("light to the side", Fig. 5.13).
struct BinocularRig {
  PinholeCamera left = look_at_camera(kWidth, kHeight, kFocalPx, {-75, 0, 0}, {0, 0, 520});
  PinholeCamera right = look_at_camera(kWidth, kHeight, kFocalPx, {75, 0, 0}, {0, 0, 520});
  Vec3 light{-160, -120, 0};
};

inline SyntheticScene scene_of(SceneKind k) {
  SyntheticScene s;
  s.kind = k;
  return s;
}

inline double rms(const std::vector<double>& e) {
  double s = 0;
  for (double v : e) s += v * v;
  return e.empty() ? std::nan("") : std::sqrt(s / static_cast<double>(e.size()));
}

inline double percentile(std::vector<double> e, double q) {
  if (e.empty()) return std::nan("");
  std::sort(e.begin(), e.end());
  const double last = static_cast<double>(e.size() - 1);
  return e[static_cast<size_t>(std::min(last, q * last + 0.5))];
}

}  // namespace procam::media_stereo::test
