// SPDX-License-Identifier: MIT
// Error-correction rounds (thesis §3.4; see correction.hpp).
#include "correction.hpp"

#include <algorithm>
#include <cmath>

#include "procam/base/calibration.hpp"

namespace procam::sl {

CorrectionDecision decide_correction(const CorrectionProgress& p) {
  const auto stop = [](const char* why) { return CorrectionDecision{false, why}; };
  if (!p.ensemble || p.max_rounds == 0) return {};
  if (p.rounds_done >= p.max_rounds) return stop("round limit");
  if (!p.can_triangulate) return stop("rig not calibrated: cannot locate resolved projector pixels");
  if (p.errors == 0) return stop("no error pixels left");
  const double min_count = p.min_progress * static_cast<double>(p.lit);
  if (static_cast<double>(p.errors) < min_count)
    return stop("error pixels below min_progress of lit pixels");
  if (p.rounds_done > 0 && static_cast<double>(p.resolved_last) < min_count)
    return stop("last round resolved fewer than min_progress of lit pixels");
  return {true, nullptr};
}

std::vector<uint8_t> near_error(const std::vector<uint8_t>& cls, size_t w, size_t h, uint32_t radius) {
  std::vector<uint8_t> err(w * h), out(w * h);
  for (size_t i = 0; i < w * h; ++i) err[i] = cls[i] == kError ? 1 : 0;
  if (radius == 0) return err;
  std::vector<uint8_t> tmp(w * h, 0);
  const auto rr = static_cast<size_t>(radius);
  for (size_t y = 0; y < h; ++y)
    for (size_t x = 0; x < w; ++x) {
      uint8_t m = 0;
      for (size_t xx = x > rr ? x - rr : 0; xx <= std::min(w - 1, x + rr); ++xx) m |= err[y * w + xx];
      tmp[y * w + x] = m;
    }
  for (size_t y = 0; y < h; ++y)
    for (size_t x = 0; x < w; ++x) {
      uint8_t m = 0;
      for (size_t yy = y > rr ? y - rr : 0; yy <= std::min(h - 1, y + rr); ++yy) m |= tmp[yy * w + x];
      out[y * w + x] = m;
    }
  return out;
}

std::vector<uint8_t> correction_mask(const sdk::Rig& rig, const std::vector<float>& coord,
                                     const std::vector<uint8_t>& valid,
                                     const std::vector<uint8_t>& cls, uint32_t dilate_px,
                                     uint32_t guard_px) {
  const uint32_t pw = rig.projector_width, ph = rig.projector_height;
  std::vector<uint8_t> mask(size_t{pw} * ph, 255);
  const sdk::RigCamera& cam = rig.cameras.at(0);
  const Rigid3 proj_from_cam = cam.calibration.cam_from_proj.inverse();
  const auto r = static_cast<int64_t>(dilate_px);
  const std::vector<uint8_t> guard = near_error(cls, cam.width, cam.height, guard_px);
  for (uint32_t v = 0; v < cam.height; ++v)
    for (uint32_t u = 0; u < cam.width; ++u) {
      const size_t i = size_t{v} * cam.width + u;
      if (valid[i] == 0 || guard[i] != 0) continue;
      const auto x = triangulate_column(cam.calibration, rig.projector, u, v, coord[i]);
      if (!x) continue;
      const Vec3 xp = proj_from_cam * *x;
      double pu = 0, pv = 0;
      rig.projector.project(xp, pu, pv);
      if (!std::isfinite(pu) || !std::isfinite(pv)) continue;
      const auto cu = static_cast<int64_t>(std::lround(pu));
      const auto cv = static_cast<int64_t>(std::lround(pv));
      for (int64_t yy = std::max<int64_t>(0, cv - r); yy <= std::min<int64_t>(ph - 1, cv + r); ++yy)
        for (int64_t xx = std::max<int64_t>(0, cu - r); xx <= std::min<int64_t>(pw - 1, cu + r); ++xx)
          mask[static_cast<size_t>(yy) * pw + static_cast<size_t>(xx)] = 0;
    }
  return mask;
}

bool clear_of_mask(const sdk::Rig& rig, const std::vector<uint8_t>& mask, size_t i, float col) {
  const sdk::RigCamera& cam = rig.cameras.at(0);
  const uint32_t pw = rig.projector_width, ph = rig.projector_height;
  const auto u = static_cast<uint32_t>(i % cam.width), v = static_cast<uint32_t>(i / cam.width);
  const auto x = triangulate_column(cam.calibration, rig.projector, u, v, col);
  if (!x) return false;
  double pu = 0, pv = 0;
  rig.projector.project(cam.calibration.cam_from_proj.inverse() * *x, pu, pv);
  if (!std::isfinite(pu) || !std::isfinite(pv)) return false;
  const auto cu = static_cast<int64_t>(std::lround(pu)), cv = static_cast<int64_t>(std::lround(pv));
  const int64_t m = kCorrectionEdgeMarginPx;
  for (int64_t yy = std::max<int64_t>(0, cv - m); yy <= std::min<int64_t>(ph - 1, cv + m); ++yy)
    for (int64_t xx = std::max<int64_t>(0, cu - m); xx <= std::min<int64_t>(pw - 1, cu + m); ++xx)
      if (mask[static_cast<size_t>(yy) * pw + static_cast<size_t>(xx)] == 0) return false;
  return true;
}

size_t merge_correction(const sdk::Rig& rig, const std::vector<uint8_t>& mask, const VoteMaps& v,
                        const std::vector<float>& masked_white,
                        const std::vector<float>& round1_white, std::vector<float>& coord,
                        std::vector<uint8_t>& valid, std::vector<float>& confidence,
                        std::vector<uint8_t>& cls) {
  const size_t n = cls.size();
  size_t resolved = 0;
  for (size_t i = 0; i < n; ++i)
    if (cls[i] == kError && v.valid[i] != 0 && masked_white.size() == n &&
        masked_white[i] >= kCorrectionMinLight * round1_white[i] && clear_of_mask(rig, mask, i, v.coord[i])) {
      coord[i] = v.coord[i];
      valid[i] = 255;
      confidence[i] = v.confidence[i];
      cls[i] = v.cls[i];
      ++resolved;
    }
  return resolved;
}

}  // namespace procam::sl
