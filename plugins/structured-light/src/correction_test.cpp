// SPDX-License-Identifier: MIT
// Tests of the error-correction rounds' algorithm (correction.hpp, thesis
// §3.4) on a rectified rig whose geometry the test knows in closed form:
// projector and camera share intrinsics (f = 100 px, centre (31.5, 15.5)),
// no rotation, camera 100 mm to the right of the projector. A camera pixel
// (u, v) that decodes projector column c then lies on projector row v
// (horizontal epipolar lines) at depth Z = 100 f / (c - u) mm, so the truth of
// every mask below is written down without any calibration code.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "correction.hpp"

namespace procam::sl {
namespace {

constexpr uint32_t kW = 64, kH = 32;  // camera and projector
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

sdk::Rig rectified_rig() {
  const nlohmann::json k = {{"width", kW}, {"height", kH}, {"fx", 100.0}, {"fy", 100.0},
                            {"cx", 31.5},  {"cy", 15.5}};
  const nlohmann::json j = {
      {"projector", {{"width", kW}, {"height", kH}, {"intrinsics", k}}},
      {"cameras",
       {{{"width", kW},
         {"height", kH},
         {"calibration",
          {{"intrinsics", k},
           {"cam_from_proj",
            {{"rotation", {1, 0, 0, 0, 1, 0, 0, 0, 1}}, {"translation_mm", {-100.0, 0.0, 0.0}}}}}}}}}};
  sdk::Rig rig;
  EXPECT_TRUE(sdk::parse_rig(j, rig).ok());
  return rig;
}

TEST(Correction, StopRuleFollowsThesisSection34) {
  CorrectionProgress p;
  p.ensemble = true;
  p.max_rounds = 2;
  p.can_triangulate = true;
  p.errors = 100;
  p.lit = 10000;
  p.min_progress = 0.0005;  // 5 pixels of 10000
  CorrectionDecision d = decide_correction(p);
  EXPECT_TRUE(d.more);
  EXPECT_EQ(d.stop_reason, nullptr);

  CorrectionProgress single = p;
  single.ensemble = false;  // single codes: never, and nothing to report
  EXPECT_FALSE(decide_correction(single).more);
  EXPECT_EQ(decide_correction(single).stop_reason, nullptr);
  CorrectionProgress off = p;
  off.max_rounds = 0;
  EXPECT_EQ(decide_correction(off).stop_reason, nullptr);

  const auto reason = [](const CorrectionProgress& q) {
    const CorrectionDecision r = decide_correction(q);
    EXPECT_FALSE(r.more);
    return std::string(r.stop_reason ? r.stop_reason : "(none)");
  };
  CorrectionProgress limit = p;
  limit.rounds_done = 2;
  EXPECT_EQ(reason(limit), "round limit");
  CorrectionProgress uncal = p;
  uncal.can_triangulate = false;
  EXPECT_EQ(reason(uncal), "rig not calibrated: cannot locate resolved projector pixels");
  CorrectionProgress none = p;
  none.errors = 0;
  EXPECT_EQ(reason(none), "no error pixels left");
  CorrectionProgress few = p;
  few.errors = 4;  // < 5
  EXPECT_EQ(reason(few), "error pixels below min_progress of lit pixels");
  CorrectionProgress stalled = p;
  stalled.rounds_done = 1;
  stalled.resolved_last = 4;  // the last round resolved < 5
  EXPECT_EQ(reason(stalled), "last round resolved fewer than min_progress of lit pixels");
  stalled.resolved_last = 5;  // exactly at the threshold: go on
  EXPECT_TRUE(decide_correction(stalled).more);
  // The first correction round does not need earlier progress.
  CorrectionProgress first = p;
  first.resolved_last = 0;
  EXPECT_TRUE(decide_correction(first).more);
}

TEST(Correction, NearErrorIsAChebyshevDilation) {
  std::mt19937 rng(7);
  const size_t w = 23, h = 17;
  std::vector<uint8_t> cls(w * h, kAllAgree);
  for (uint8_t& c : cls)
    if (rng() % 29 == 0) c = kError;
  cls[0] = kError;          // corner
  cls[w * h - 1] = kError;  // other corner
  for (uint32_t r : {0u, 1u, 3u}) {
    const std::vector<uint8_t> got = near_error(cls, w, h, r);
    for (size_t y = 0; y < h; ++y)
      for (size_t x = 0; x < w; ++x) {
        bool near = false;  // brute force over all error pixels
        for (size_t yy = 0; yy < h; ++yy)
          for (size_t xx = 0; xx < w; ++xx)
            if (cls[yy * w + xx] == kError &&
                std::max(std::abs(static_cast<long>(xx) - static_cast<long>(x)),
                         std::abs(static_cast<long>(yy) - static_cast<long>(y))) <= static_cast<long>(r))
              near = true;
        ASSERT_EQ(got[y * w + x], near ? 1 : 0) << "r=" << r << " at " << x << "," << y;
      }
  }
}

TEST(Correction, MaskSwitchesOffTheResolvedPointsProjectorPixels) {
  const sdk::Rig rig = rectified_rig();
  std::vector<float> coord(kW * kH, kNaN);
  std::vector<uint8_t> valid(kW * kH, 0), cls(kW * kH, kUnlit);
  // One resolved pixel: camera (20, 10) decodes column 30 (depth 100*100/10 =
  // 1000 mm) -> projector pixel (30, 10).
  coord[10 * kW + 20] = 30.0f;
  valid[10 * kW + 20] = 255;
  cls[10 * kW + 20] = kAllAgree;
  // One resolved pixel next to an error pixel: guarded, stays on.
  coord[25 * kW + 40] = 50.0f;
  valid[25 * kW + 40] = 255;
  cls[25 * kW + 40] = kAllAgree;
  cls[25 * kW + 42] = kError;  // 2 px away
  // A "resolved" column behind the camera (c < u): cannot be located, skipped.
  coord[5 * kW + 50] = 45.0f;
  valid[5 * kW + 50] = 255;
  const std::vector<uint8_t> mask = correction_mask(rig, coord, valid, cls, 2, 3);
  ASSERT_EQ(mask.size(), size_t{kW} * kH);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      const bool off = x >= 28 && x <= 32 && y >= 8 && y <= 12;  // (30, 10) +- 2
      ASSERT_EQ(mask[y * kW + x], off ? 0 : 255) << x << "," << y;
    }
  // Without the guard the second pixel's projector pixel (50, 25) goes off too.
  const std::vector<uint8_t> unguarded = correction_mask(rig, coord, valid, cls, 0, 0);
  EXPECT_EQ(unguarded[25 * kW + 50], 0);
  EXPECT_EQ(unguarded[25 * kW + 49], 255);  // dilation 0: that pixel only
  EXPECT_EQ(unguarded[10 * kW + 30], 0);
}

TEST(Correction, ClearOfMaskLooksAtTheNamedPixelAndItsMargin) {
  const sdk::Rig rig = rectified_rig();
  std::vector<uint8_t> mask(kW * kH, 255);
  mask[10 * kW + 33] = 0;  // 3 px right of projector pixel (30, 10)
  const size_t i = 10 * kW + 20;
  EXPECT_TRUE(clear_of_mask(rig, mask, i, 30.0f));   // margin 2: (33, 10) is outside it
  EXPECT_FALSE(clear_of_mask(rig, mask, i, 31.0f));  // (33, 10) within 2 of (31, 10)
  EXPECT_FALSE(clear_of_mask(rig, mask, i, 15.0f));  // behind the camera: cannot be located
  EXPECT_FALSE(clear_of_mask(rig, mask, i, kNaN));
}

TEST(Correction, MergeTakesOnlyErrorPixelsThatPassEveryRule) {
  const sdk::Rig rig = rectified_rig();
  std::vector<uint8_t> mask(kW * kH, 255);
  for (uint32_t x = 0; x < 10; ++x) mask[12 * kW + x] = 0;  // projector row 12, columns 0..9 off
  const size_t n = size_t{kW} * kH;
  std::vector<float> coord(n, kNaN), confidence(n, 0.0f), masked_white(n, 0.5f), round1(n, 1.0f);
  std::vector<uint8_t> valid(n, 0), cls(n, kError);
  VoteMaps v;
  v.coord.assign(n, 40.0f);  // every camera pixel re-decodes to column 40
  v.valid.assign(n, 255);
  v.confidence.assign(n, 0.75f);
  v.cls.assign(n, kPartial);
  // Pixel a: still an error, lit, window clear -> merged.
  const size_t a = 4 * kW + 20;
  // Pixel b: was resolved in round 1 (not an error) -> untouched.
  const size_t b = 4 * kW + 21;
  cls[b] = kAllAgree;
  coord[b] = 41.0f;
  valid[b] = 255;
  // Pixel c: the new vote is invalid -> stays an error.
  const size_t c = 4 * kW + 22;
  v.valid[c] = 0;
  // Pixel d: keeps only 0.3 of its round-1 light (< 0.35) -> stays an error.
  const size_t d = 4 * kW + 23;
  masked_white[d] = 0.3f;
  round1[d] = 1.0f;
  // Pixel e: exactly 0.35 of its light -> merged (the rule is >=).
  const size_t e = 4 * kW + 24;
  masked_white[e] = 0.35f;
  // Pixel f: names projector (8, 12), whose window touches the switched-off run.
  const size_t f = 12 * kW + 0;
  v.coord[f] = 8.0f;
  // Everything else: no new column.
  for (size_t i = 0; i < n; ++i)
    if (i != a && i != b && i != c && i != d && i != e && i != f) v.valid[i] = 0;
  const size_t resolved =
      merge_correction(rig, mask, v, masked_white, round1, coord, valid, confidence, cls);
  EXPECT_EQ(resolved, 2u);
  EXPECT_EQ(coord[a], 40.0f);
  EXPECT_EQ(valid[a], 255);
  EXPECT_EQ(confidence[a], 0.75f);
  EXPECT_EQ(cls[a], kPartial);
  EXPECT_EQ(cls[e], kPartial);
  EXPECT_EQ(coord[b], 41.0f);
  EXPECT_EQ(cls[b], kAllAgree);
  for (size_t i : {c, d, f}) {
    EXPECT_EQ(cls[i], kError) << i;
    EXPECT_EQ(valid[i], 0) << i;
    EXPECT_TRUE(std::isnan(coord[i])) << i;
  }
  // A masked white frame of the wrong size (no light data) merges nothing.
  std::vector<uint8_t> cls2(n, kError), valid2(n, 0);
  std::vector<float> coord2(n, kNaN), conf2(n, 0.0f);
  EXPECT_EQ(merge_correction(rig, mask, v, std::vector<float>(3, 1.0f), round1, coord2, valid2, conf2, cls2), 0u);
}

}  // namespace
}  // namespace procam::sl
