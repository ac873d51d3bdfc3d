// SPDX-License-Identifier: MIT
// Error-correction rounds (thesis §3.4; see correction.hpp).
#include "correction.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "procam/base/calibration.hpp"

namespace procam::sl {

CorrectionDecision decide_correction(const CorrectionProgress& p) {
  const auto stop = [](const char* why) { return CorrectionDecision{false, why}; };
  if (!p.ensemble || p.max_rounds == 0) return {};
  if (p.rounds_done >= p.max_rounds) return stop("round limit");
  if (!p.can_triangulate) return stop("rig not calibrated: cannot locate resolved projector pixels");
  if (p.errors == 0) return stop("no flagged pixels left");
  const double min_count = p.min_progress * static_cast<double>(p.lit);
  if (static_cast<double>(p.errors) < min_count)
    return stop("flagged pixels below min_progress of lit pixels");
  if (p.rounds_done > 0 && static_cast<double>(p.resolved_last) < min_count)
    return stop("last round resolved fewer than min_progress of lit pixels");
  if (p.rounds_done > 0 && p.acceptance_last < p.min_acceptance)
    return stop("last round's acceptance rate below min_acceptance");
  return {true, nullptr};
}

namespace {

// The conflict rule for one voted pixel (correction.hpp label_conflicts):
// agree(a, b) says whether codes a and b agree, has(k) whether code k is valid.
template <class Agree, class Has>
bool conflict_pixel(Agree&& agree, Has&& has) {
  uint32_t pairs = 0;
  for (uint32_t a = 0; a < kEnsembleCodes; ++a)
    for (uint32_t b = a + 1; b < kEnsembleCodes; ++b) pairs += agree(a, b) ? 1u : 0u;
  if (pairs != 1) return false;
  uint32_t x = kEnsembleCodes;  // the XOR code agreeing with gray, if that is the pair
  if (agree(kGray, kXor02)) x = kXor02;
  if (agree(kGray, kXor04)) x = kXor04;
  if (x == kEnsembleCodes) return false;
  for (uint32_t k = 0; k < kEnsembleCodes; ++k)  // a third valid code (it disagrees: the pair is the only one)
    if (k != kGray && k != x && has(k)) return true;
  return false;
}

// Pixels [begin, end) of the vote's maps: conflict(i) -> kConflict, invalid.
template <class Conflict>
size_t label_range(size_t begin, size_t end, float* coord, uint8_t* valid, float* confidence,
                   uint8_t* cls, Conflict&& conflict) {
  size_t n = 0;
  // Issue 17: most pixels are invalid or unanimous, and the rule skips
  // them; a 64-pixel chunk where every pixel is one of those is skipped
  // after one branch-free (vectorizable) test instead of 64 branches.
  constexpr size_t kChunk = 64;
  for (size_t c0 = begin; c0 < end; c0 += kChunk) {
    const size_t c1 = std::min(end, c0 + kChunk);
    uint8_t candidates = 0;
    for (size_t i = c0; i < c1; ++i)
      candidates |= static_cast<uint8_t>((valid[i] != 0) & (cls[i] != kAllAgree));
    if (candidates == 0) continue;
    for (size_t i = c0; i < c1; ++i) {
      if (valid[i] == 0 || cls[i] == kAllAgree || !conflict(i)) continue;
      coord[i] = std::numeric_limits<float>::quiet_NaN();
      valid[i] = 0;
      confidence[i] = 0.0f;
      cls[i] = kConflict;
      ++n;
    }
  }
  return n;
}

}  // namespace

size_t label_conflicts(const float* const code[kEnsembleCodes], float agree_px, size_t begin,
                       size_t end, float* coord, uint8_t* valid, float* confidence, uint8_t* cls) {
  return label_range(begin, end, coord, valid, confidence, cls, [&](size_t i) {
    float v[kEnsembleCodes];
    for (uint32_t k = 0; k < kEnsembleCodes; ++k) v[k] = code[k][i];
    return conflict_pixel([&](uint32_t a, uint32_t b) { return std::fabs(v[a] - v[b]) <= agree_px; },
                          [&](uint32_t k) { return !std::isnan(v[k]); });
  });
}

size_t label_conflicts_keys(const int32_t* const key[kEnsembleCodes], int32_t agree2, size_t n,
                            float* coord, uint8_t* valid, float* confidence, uint8_t* cls) {
  return label_range(0, n, coord, valid, confidence, cls, [&](size_t i) {
    int32_t v[kEnsembleCodes];
    for (uint32_t k = 0; k < kEnsembleCodes; ++k) v[k] = key[k][i];
    return conflict_pixel(
        [&](uint32_t a, uint32_t b) { return v[a] >= 0 && v[b] >= 0 && std::abs(v[a] - v[b]) <= agree2; },
        [&](uint32_t k) { return v[k] >= 0; });
  });
}

bool fixable_pixel(float masked_white, float round1_white) {
  return masked_white > 0.0f && masked_white >= kCorrectionMinLight * round1_white &&
         masked_white <= (1.0f - kCorrectionMinDrop) * round1_white;
}

float row_column_estimate(const std::vector<float>& coord, size_t width, size_t i, uint32_t reach) {
  const size_t x = i % width, row = i - x;
  float left = std::numeric_limits<float>::quiet_NaN(), right = left;
  size_t dl = 0, dr = 0;
  for (size_t d = 1; d <= reach && d <= x; ++d)
    if (!std::isnan(coord[row + x - d])) {
      left = coord[row + x - d];
      dl = d;
      break;
    }
  for (size_t d = 1; d <= reach && x + d < width; ++d)
    if (!std::isnan(coord[row + x + d])) {
      right = coord[row + x + d];
      dr = d;
      break;
    }
  if (std::isnan(left)) return right;
  if (std::isnan(right)) return left;
  const float t = static_cast<float>(dl) / static_cast<float>(dl + dr);
  return left + t * (right - left);
}

RoundForecast forecast_round(const sdk::Rig& rig, const std::vector<uint8_t>& mask,
                             const std::vector<float>& coord,
                             const std::vector<uint8_t>& cls, const std::vector<uint8_t>& lit,
                             const std::vector<float>& masked_white,
                             const std::vector<float>& round1_white,
                             const std::vector<float>& masked_plane,
                             const std::vector<float>& masked_inverse, float min_margin,
                             float min_contrast, bool black_frame, std::vector<uint8_t>* per_pixel) {
  RoundForecast f;
  if (per_pixel != nullptr) per_pixel->assign(cls.size(), 0);
  for (size_t i = 0; i < cls.size(); ++i) {
    f.lit += lit[i] != 0 ? 1u : 0u;
    if (!flagged(cls[i])) continue;
    ++f.flagged;
    const float m = masked_white[i], w = round1_white[i];
    uint8_t k = 4;
    float col = std::numeric_limits<float>::quiet_NaN();
    if (!mask.empty()) col = row_column_estimate(coord, rig.cameras.at(0).width, i, 6);
    if (!(m >= kCorrectionMinLight * w) || !(m > 0.0f)) k = 1;  // NaN or black: off
    else if (!std::isnan(col) && !clear_of_mask(rig, mask, i, col)) k = 1;
    else if (!(m - (black_frame ? std::max(0.0f, masked_plane[i] + masked_inverse[i] - m) : 0.0f) >= min_contrast))
      k = 5;  // the masked round's decoder leaves it unlit (decode.hpp rule 1)
    else if (m > (1.0f - kCorrectionMinDrop) * w) k = 2;
    else if (!(std::fabs(masked_plane[i] - masked_inverse[i]) >= min_margin * m)) k = 3;
    f.own_light_off += k == 1;
    f.unchanged += k == 2;
    f.blurred += k == 3;
    f.fixable += k == 4;
    f.too_dark += k == 5;
    if (per_pixel != nullptr) (*per_pixel)[i] = k;
  }
  return f;
}

std::vector<uint8_t> near_flagged(const std::vector<uint8_t>& cls, size_t w, size_t h, uint32_t radius) {
  std::vector<uint8_t> err(w * h), out(w * h);
  for (size_t i = 0; i < w * h; ++i) err[i] = flagged(cls[i]) ? 1 : 0;
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
  const std::vector<uint8_t> guard = near_flagged(cls, cam.width, cam.height, guard_px);
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
                        std::vector<uint8_t>& cls, bool recheck_claims, MergeCounts* counts,
                        std::vector<MergeUndo>* undo) {
  const size_t n = cls.size();
  const size_t width = rig.cameras.at(0).width;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const auto remember = [&](size_t i, bool was_flagged) {
    if (undo != nullptr) undo->push_back({i, coord[i], confidence[i], valid[i], cls[i], was_flagged});
  };
  MergeCounts c;
  // 1. Refuted claims, decided on the first-pass maps.
  std::vector<size_t> refuted;
  if (recheck_claims && !mask.empty())
    for (size_t i = 0; i < n; ++i)
      if (valid[i] != 0 && !flagged(cls[i]) && v.valid[i] != 0 && v.cls[i] == kAllAgree &&
          std::fabs(v.coord[i] - coord[i]) > kRefutedMovePx)
        refuted.push_back(i);
  if (!refuted.empty()) {
    // Their neighbour test reads the row's valid pixels that are not refuted.
    std::vector<float> kept = coord;
    for (size_t i : refuted) kept[i] = nan;
    std::vector<uint8_t> moves(refuted.size(), 0);
    for (size_t k = 0; k < refuted.size(); ++k) {
      const size_t i = refuted[k];
      if (!clear_of_mask(rig, mask, i, v.coord[i])) continue;
      const float est = row_column_estimate(kept, width, i, kCorrectionNeighbourReachPx);
      moves[k] = std::isnan(est) || std::fabs(v.coord[i] - est) <= kCorrectionNeighbourPx;
    }
    for (size_t k = 0; k < refuted.size(); ++k) {
      const size_t i = refuted[k];
      remember(i, false);
      if (moves[k] != 0) {
        coord[i] = v.coord[i];
        confidence[i] = v.confidence[i];
        cls[i] = v.cls[i];
        ++c.refuted_moved;
      } else {  // the claim is a mirror's, the new column unconfirmed: no answer
        coord[i] = nan;
        valid[i] = 0;
        confidence[i] = 0.0f;
        cls[i] = kError;
      }
    }
    c.refuted = refuted.size();
  }
  // 2. Flagged pixels (not the ones step 1 just made invalid), their
  // neighbour test on the maps step 1 corrected.
  std::vector<uint8_t> was_refuted;
  if (!refuted.empty()) {
    was_refuted.assign(n, 0);
    for (size_t i : refuted) was_refuted[i] = 1;
  }
  std::vector<size_t> take;  // decided on the maps as step 1 left them, then written
  for (size_t i = 0; i < n; ++i) {
    if (!(flagged(cls[i]) && v.valid[i] != 0 && v.cls[i] == kAllAgree && masked_white.size() == n &&
          (was_refuted.empty() || was_refuted[i] == 0) &&
          fixable_pixel(masked_white[i], round1_white[i]) && clear_of_mask(rig, mask, i, v.coord[i])))
      continue;
    const float est = row_column_estimate(coord, width, i, kCorrectionNeighbourReachPx);
    if (!std::isnan(est) && std::fabs(v.coord[i] - est) > kCorrectionNeighbourPx) continue;
    take.push_back(i);
  }
  for (size_t i : take) {
    remember(i, true);
    coord[i] = v.coord[i];
    valid[i] = 255;
    confidence[i] = v.confidence[i];
    cls[i] = v.cls[i];
  }
  c.resolved = take.size();
  if (counts != nullptr) *counts = c;
  return take.size();
}

}  // namespace procam::sl
