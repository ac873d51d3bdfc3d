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
#include <iterator>
#include <utility>
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
  EXPECT_EQ(reason(none), "no flagged pixels left");
  CorrectionProgress few = p;
  few.errors = 4;  // < 5
  EXPECT_EQ(reason(few), "flagged pixels below min_progress of lit pixels");
  CorrectionProgress stalled = p;
  stalled.rounds_done = 1;
  stalled.resolved_last = 4;  // the last round resolved < 5
  EXPECT_EQ(reason(stalled), "last round resolved fewer than min_progress of lit pixels");
  stalled.resolved_last = 5;  // exactly at the threshold: go on
  EXPECT_TRUE(decide_correction(stalled).more);
  // Issue 18: a round whose answers mostly failed the acceptance tests stops
  // the correction, even with progress.
  CorrectionProgress unsure = stalled;
  unsure.resolved_last = 500;
  unsure.acceptance_last = 0.62;  // < min_acceptance 0.7 (the steel ball's round)
  EXPECT_EQ(reason(unsure), "last round's acceptance rate below min_acceptance");
  unsure.acceptance_last = 0.7;  // at the threshold: go on
  EXPECT_TRUE(decide_correction(unsure).more);
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
    const std::vector<uint8_t> got = near_flagged(cls, w, h, r);
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
  v.cls.assign(n, kAllAgree);
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
  // Pixel g: the mask took away only 5 % of its light (< kCorrectionMinDrop):
  // a different answer is chance -> stays an error.
  const size_t g = 4 * kW + 25;
  masked_white[g] = 0.95f;
  // Pixel k: exactly 10 % taken away -> merged (the rule is <= 1 - 0.1).
  const size_t k = 4 * kW + 26;
  masked_white[k] = 0.9f;
  // Pixel p: only a pair agrees in the masked round -> stays an error.
  const size_t p = 4 * kW + 27;
  v.cls[p] = kPartial;
  // Pixel q: a conflict pixel (flagged like an error) -> merged.
  const size_t q = 4 * kW + 28;
  cls[q] = kConflict;
  // Everything else: no new column.
  for (size_t i = 0; i < n; ++i)
    if (i != a && i != b && i != c && i != d && i != e && i != f && i != g && i != k && i != p && i != q)
      v.valid[i] = 0;
  const size_t resolved =
      merge_correction(rig, mask, v, masked_white, round1, coord, valid, confidence, cls);
  EXPECT_EQ(resolved, 4u);
  EXPECT_EQ(coord[a], 40.0f);
  EXPECT_EQ(valid[a], 255);
  EXPECT_EQ(confidence[a], 0.75f);
  for (size_t i : {a, e, k, q}) {
    EXPECT_EQ(cls[i], kAllAgree) << i;
    EXPECT_EQ(valid[i], 255) << i;
  }
  EXPECT_EQ(coord[b], 41.0f);
  EXPECT_EQ(cls[b], kAllAgree);
  for (size_t i : {c, d, f, g, p}) {
    EXPECT_EQ(cls[i], kError) << i;
    EXPECT_EQ(valid[i], 0) << i;
    EXPECT_TRUE(std::isnan(coord[i])) << i;
  }
  // A masked white frame of the wrong size (no light data) merges nothing.
  std::vector<uint8_t> cls2(n, kError), valid2(n, 0);
  std::vector<float> coord2(n, kNaN), conf2(n, 0.0f);
  EXPECT_EQ(merge_correction(rig, mask, v, std::vector<float>(3, 1.0f), round1, coord2, valid2, conf2, cls2), 0u);
}

// Re-check of first-pass claims (recheck_claims). The masked round is voted
// from four per-code maps (vote_pixels), so "all four agree" is the vote's
// own class. Most valid first-pass pixels claim projector column 32, a
// mirror's: projector rows 6..16, columns 30..34 are switched off, as the
// mirror's source would be.
TEST(Correction, MergeRefutesAClaimWhenAllFourCodesAgreeElsewhereUnderTheMask) {
  const sdk::Rig rig = rectified_rig();
  std::vector<uint8_t> mask(kW * kH, 255);
  for (uint32_t y = 6; y <= 16; ++y)
    for (uint32_t x = 30; x <= 34; ++x) mask[y * kW + x] = 0;
  const size_t n = size_t{kW} * kH;
  std::vector<float> coord(n, kNaN), confidence(n, 0.0f), masked_white(n, 0.5f), round1(n, 1.0f);
  std::vector<uint8_t> valid(n, 0), cls(n, kUnlit);
  std::vector<float> code[kEnsembleCodes];
  for (auto& c : code) c.assign(n, kNaN);  // the masked round: dark unless set below
  const auto claim = [&](uint32_t u, uint32_t y, float col) {
    const size_t i = size_t{y} * kW + u;
    coord[i] = col;
    valid[i] = 255;
    confidence[i] = 1.0f;
    cls[i] = kAllAgree;
    return i;
  };
  const auto masked = [&](size_t i, float g, float x2, float x4, float m) {
    code[kGray][i] = g;
    code[kXor02][i] = x2;
    code[kXor04][i] = x4;
    code[kMinsw][i] = m;
  };
  // Fires: claim 32 (switched off), the masked round's four codes agree at 50.
  const size_t a = claim(10, 6, 32.0f);
  masked(a, 50, 50, 50, 50);
  // Must not fire: the codes disagree (two pairs) ...
  const size_t b = claim(20, 6, 32.0f);
  masked(b, 50, 50, 60, 60);
  // ... fewer than four valid, the three agreeing ...
  const size_t c = claim(10, 8, 32.0f);
  masked(c, 50, kNaN, 50, 50);
  // ... the masked answer equals the claim (within kRefutedMovePx) ...
  const size_t d = claim(20, 8, 32.0f);
  masked(d, 33, 33, 33, 33);
  // ... and the pixel goes dark, as a right claim should.
  const size_t f = claim(20, 16, 32.0f);
  (void)f;
  // Refuted, but its new column fails the row-neighbour test (a valid,
  // unrefuted neighbour 3 px away claims 20): invalid, not the mirror's 32.
  const size_t g = claim(10, 10, 32.0f);
  masked(g, 50, 50, 50, 50);
  const size_t g_nb = claim(13, 10, 20.0f);
  // Two refuted neighbours: neither's estimate reads the other's refuted claim.
  const size_t h1 = claim(10, 12, 32.0f), h2 = claim(12, 12, 32.0f);
  masked(h1, 50, 50, 50, 50);
  masked(h2, 52, 52, 52, 52);
  // A flagged pixel between two refuted ones: its neighbour test reads their
  // corrected columns (50, 54 -> estimate 52), not the mirror's 32.
  const size_t i1 = claim(10, 14, 32.0f), i2 = claim(14, 14, 32.0f);
  masked(i1, 50, 50, 50, 50);
  masked(i2, 54, 54, 54, 54);
  const size_t fl = 14 * kW + 12;
  cls[fl] = kError;
  masked(fl, 52, 52, 52, 52);
  // Fires also where the claim's projector pixel is on (projector row 20 is
  // not masked): a right claim would have kept its direct light and won.
  const size_t e = claim(10, 20, 45.0f);
  masked(e, 50, 50, 50, 50);
  // Refuted, new column named by a switched-off projector pixel margin: invalid.
  const size_t k = claim(10, 16, 32.0f);
  masked(k, 36, 36, 36, 36);  // (36, 16) within 2 of column 34, switched off

  std::vector<uint8_t> lit(n, 255);
  VoteMaps v;
  v.coord.resize(n);
  v.valid.resize(n);
  v.confidence.resize(n);
  v.cls.resize(n);
  const float* const cp[kEnsembleCodes] = {code[0].data(), code[1].data(), code[2].data(),
                                           code[3].data()};
  vote_pixels(cp, lit.data(), 0, n, 1.0f, v.coord.data(), v.valid.data(), v.confidence.data(),
              v.cls.data());
  ASSERT_EQ(v.cls[a], kAllAgree);
  ASSERT_NE(v.cls[c], kAllAgree);  // three agreeing codes are kPartial, not all four

  const std::vector<float> coord0 = coord;
  std::vector<float> coord_off = coord, conf_off = confidence;
  std::vector<uint8_t> valid_off = valid, cls_off = cls;
  MergeCounts counts;
  std::vector<MergeUndo> undo;
  const size_t resolved = merge_correction(rig, mask, v, masked_white, round1, coord, valid,
                                           confidence, cls, true, &counts, &undo);
  EXPECT_EQ(counts.refuted, 8u);  // a, e, g, h1, h2, i1, i2, k
  EXPECT_EQ(counts.refuted_moved, 6u);
  EXPECT_EQ(resolved, 1u);  // fl
  EXPECT_EQ(counts.resolved, 1u);
  for (const auto& [i, col] : {std::pair{a, 50.0f}, {e, 50.0f}, {h1, 50.0f}, {h2, 52.0f}, {i1, 50.0f},
                                {i2, 54.0f}, {fl, 52.0f}}) {
    EXPECT_EQ(coord[i], col) << i;
    EXPECT_EQ(valid[i], 255) << i;
    EXPECT_EQ(cls[i], kAllAgree) << i;
  }
  for (size_t i : {b, c, d, f, g_nb}) {
    EXPECT_EQ(coord[i], coord0[i]) << i;
    EXPECT_EQ(valid[i], 255) << i;
    EXPECT_EQ(cls[i], kAllAgree) << i;
  }
  for (size_t i : {g, k}) {
    EXPECT_TRUE(std::isnan(coord[i])) << i;
    EXPECT_EQ(valid[i], 0) << i;
    EXPECT_EQ(cls[i], kError) << i;
  }
  // The undo list holds every changed pixel's previous value.
  ASSERT_EQ(undo.size(), 9u);
  for (const MergeUndo& u : undo) {
    EXPECT_EQ(u.was_flagged, u.i == fl) << u.i;
    if (u.i == fl) EXPECT_TRUE(std::isnan(u.coord));
    else EXPECT_EQ(u.coord, u.i == e ? 45.0f : 32.0f) << u.i;
  }
  // Off: no claim is re-checked, and the flagged pixel's neighbours are the
  // mirror's 32 (|52 - 32| > kCorrectionNeighbourPx): it stays an error.
  MergeCounts off;
  EXPECT_EQ(merge_correction(rig, mask, v, masked_white, round1, coord_off, valid_off, conf_off,
                             cls_off, false, &off),
            0u);
  EXPECT_EQ(off.refuted, 0u);
  for (size_t i : {a, g, h1, i1, k}) EXPECT_EQ(coord_off[i], 32.0f) << i;
  EXPECT_EQ(coord_off[e], 45.0f);
  EXPECT_EQ(cls_off[fl], kError);
}

// The conflict rule on hand-made votes: only {gray, xor02/04} agreeing
// against a valid third code is a conflict; every other vote stands.
TEST(Correction, ConflictRuleFlagsOnlyACorrelatedPairAgainstADissenter) {
  struct Case {
    float g, x2, x4, m;
    uint8_t cls;       // the vote's class (as vote.hpp would give it)
    bool conflict;     // expected
  };
  const Case cases[] = {
      {100, 100, kNaN, 300, kPartial, true},     // gray + xor02 vs minsw
      {100, kNaN, 100.5f, 40, kPartial, true},   // gray + xor04 vs minsw
      {100, 250, 100, kNaN, kPartial, true},     // gray + xor04 vs xor02
      {100, 100, kNaN, kNaN, kPartial, false},   // the pair alone: no dissent, stands
      {100, 100, 100, 300, kPartial, false},     // three agree (3 pairs): stands
      {300, 100, 100, 120, kInterreflection, false},  // the thesis's XOR pair: stands
      {100, 200, 300, 100, kSubsurface, false},  // the Gray pair: stands
      {100, kNaN, 300, 300.5f, kPartial, false}, // xor04 + minsw vs gray: stands
      {100, 100, 100, 100, kAllAgree, false},
  };
  const size_t n = std::size(cases);
  std::vector<float> code[kEnsembleCodes];
  for (auto& c : code) c.resize(n);
  std::vector<float> coord(n, 100.0f), conf(n, 0.5f);
  std::vector<uint8_t> valid(n, 255), cls(n);
  for (size_t i = 0; i < n; ++i) {
    code[kGray][i] = cases[i].g;
    code[kXor02][i] = cases[i].x2;
    code[kXor04][i] = cases[i].x4;
    code[kMinsw][i] = cases[i].m;
    cls[i] = cases[i].cls;
  }
  const float* ptr[kEnsembleCodes] = {code[0].data(), code[1].data(), code[2].data(), code[3].data()};
  const size_t got = label_conflicts(ptr, 1.0f, 0, n, coord.data(), valid.data(), conf.data(), cls.data());
  size_t want = 0;
  for (size_t i = 0; i < n; ++i) {
    want += cases[i].conflict ? 1u : 0u;
    EXPECT_EQ(cls[i] == kConflict, cases[i].conflict) << "case " << i;
    EXPECT_EQ(valid[i], cases[i].conflict ? 0 : 255) << "case " << i;
    EXPECT_EQ(std::isnan(coord[i]), cases[i].conflict) << "case " << i;
  }
  EXPECT_EQ(got, want);
}

// The vote applies the conflict rule on its integer keys (issue 17: no
// per-code float maps); it must label exactly what label_conflicts labels on
// the maps key / 2 (NaN for key -1), whose cases are checked above.
TEST(Correction, ConflictRuleOnKeysEqualsRuleOnMaps) {
  std::mt19937 rng(1717);
  std::uniform_int_distribution<int32_t> key(-1, 12);  // narrow: agreements and conflicts are common
  for (const float agree_px : {0.5f, 1.0f, 2.5f}) {
    const size_t n = 20000;
    std::vector<int32_t> keys[kEnsembleCodes];
    std::vector<float> maps[kEnsembleCodes];
    std::vector<uint8_t> lit(n);
    for (size_t i = 0; i < n; ++i) lit[i] = (i % 17 == 0) ? 0 : 255;
    for (uint32_t k = 0; k < kEnsembleCodes; ++k) {
      keys[k].resize(n);
      maps[k].resize(n);
      for (size_t i = 0; i < n; ++i) {
        keys[k][i] = key(rng);
        maps[k][i] = keys[k][i] < 0 ? std::numeric_limits<float>::quiet_NaN() : 0.5f * static_cast<float>(keys[k][i]);
      }
    }
    const int32_t* kp[kEnsembleCodes] = {keys[0].data(), keys[1].data(), keys[2].data(), keys[3].data()};
    const float* mp[kEnsembleCodes] = {maps[0].data(), maps[1].data(), maps[2].data(), maps[3].data()};
    const int32_t agree2 = agree_key_threshold(agree_px);
    std::vector<float> coord_a(n), conf_a(n);
    std::vector<uint8_t> valid_a(n), cls_a(n);
    vote_keys(kp, lit.data(), n, agree2, coord_a.data(), valid_a.data(), conf_a.data(), cls_a.data());
    std::vector<float> coord_b = coord_a, conf_b = conf_a;
    std::vector<uint8_t> valid_b = valid_a, cls_b = cls_a;
    const size_t on_maps = label_conflicts(mp, agree_px, 0, n, coord_a.data(), valid_a.data(), conf_a.data(), cls_a.data());
    const size_t on_keys = label_conflicts_keys(kp, agree2, n, coord_b.data(), valid_b.data(), conf_b.data(), cls_b.data());
    EXPECT_GT(on_maps, n / 100) << agree_px;  // the case is exercised
    EXPECT_EQ(on_keys, on_maps) << agree_px;
    for (size_t i = 0; i < n; ++i) {
      ASSERT_EQ(cls_b[i], cls_a[i]) << "pixel " << i << " agree_px " << agree_px;
      ASSERT_EQ(valid_b[i], valid_a[i]) << i;
      ASSERT_EQ(conf_b[i], conf_a[i]) << i;
      ASSERT_EQ(std::isnan(coord_b[i]), std::isnan(coord_a[i])) << i;
      if (!std::isnan(coord_a[i])) {
        ASSERT_EQ(coord_b[i], coord_a[i]) << i;
      }
    }
  }
}

// The probe's forecast sorts flagged pixels by the three tests; the counts
// are checked against the rule written out per pixel.
TEST(Correction, ForecastCountsFixablePixelsByTheProbeRules) {
  std::vector<uint8_t> cls = {kError, kError, kError, kError, kConflict, kAllAgree, kError, kUnlit};
  std::vector<uint8_t> lit = {255, 255, 255, 255, 255, 255, 255, 0};
  std::vector<float> w1 = {1.0f, 1.0f, 1.0f, 1.0f, 0.8f, 1.0f, 0.5f, 0.0f};
  //                 own light off, unchanged, blurred, fixable, fixable, (valid), fixable (8-bit dark), unlit
  std::vector<float> wm = {0.30f, 0.95f, 0.6f, 0.6f, 0.4f, 0.6f, 0.2f, 0.0f};
  // |L - L_inv| / Wm: 0.2/0.6 = 0.33 < 0.5 (blurred); 0.4/0.6 = 0.67 (fixable);
  // conflict: 0.4/0.4 = 1; last error: 0.2/0.2 = 1.
  std::vector<float> plane = {0.3f, 0.5f, 0.4f, 0.5f, 0.4f, 0.3f, 0.2f, 0.0f};
  std::vector<float> inverse = {0.0f, 0.45f, 0.2f, 0.1f, 0.0f, 0.3f, 0.0f, 0.0f};
  const sdk::Rig rig = rectified_rig();
  const std::vector<uint8_t> no_mask;
  const std::vector<float> no_coord;
  const RoundForecast f = forecast_round(rig, no_mask, no_coord, cls, lit, wm, w1, plane, inverse, 0.5f, 0.03f, false);
  EXPECT_EQ(f.lit, 7u);
  EXPECT_EQ(f.flagged, 6u);
  EXPECT_EQ(f.own_light_off, 1u);
  EXPECT_EQ(f.unchanged, 1u);
  EXPECT_EQ(f.blurred, 1u);
  EXPECT_EQ(f.fixable, 3u);
  EXPECT_DOUBLE_EQ(f.predicted_gain(), 3.0 / 7.0);
  EXPECT_EQ(f.flagged, f.own_light_off + f.unchanged + f.blurred + f.fixable);
  // A black masked white (0 / 0) is "own light off", never NaN-fixable.
  const RoundForecast z = forecast_round(rig, no_mask, no_coord, {kError}, {255}, {0.0f}, {0.0f}, {0.0f}, {0.0f}, 0.5f, 0.03f, false);
  // An "on" stripe whose inverse is as bright (ambient or blur): not fixable,
  // although |2L - Wm| alone would pass.
  const RoundForecast amb = forecast_round(rig, no_mask, no_coord, {kError}, {255}, {0.6f}, {1.0f}, {0.5f}, {0.45f}, 0.5f, 0.03f, false);
  EXPECT_EQ(amb.blurred, 1u);
  EXPECT_EQ(z.fixable + z.unchanged + z.blurred + z.own_light_off, 1u);
  EXPECT_EQ(z.fixable, 0u);
  // With geometry: a flagged pixel whose row neighbours name a projector
  // pixel next to the mask is "own light off" (merge_correction would reject
  // any answer there); one whose neighbours name a lit area stays fixable.
  const size_t n = size_t{kW} * kH;
  std::vector<uint8_t> mask(n, 255), cls2(n, kAllAgree), lit2(n, 255);
  for (uint32_t x = 30; x <= 34; ++x) mask[10 * kW + x] = 0;  // projector row 10, cols 30..34 off
  std::vector<float> coord(n, kNaN), ones(n, 1.0f), half(n, 0.6f), on(n, 0.6f), off(n, 0.0f);
  const size_t near_mask = 10 * kW + 20, far_from_mask = 10 * kW + 40;
  cls2[near_mask] = kError;
  cls2[far_from_mask] = kError;
  coord[near_mask - 1] = 28.0f;  // neighbours: columns 28 and 30 -> estimate 29, within 2 of 30..34
  coord[near_mask + 1] = 30.0f;
  coord[far_from_mask - 2] = 55.0f;  // estimate 55 (one side only): far from the mask
  const RoundForecast g = forecast_round(rig, mask, coord, cls2, lit2, half, ones, on, off, 0.5f, 0.03f, false);
  EXPECT_EQ(g.flagged, 2u);
  EXPECT_EQ(g.own_light_off, 1u);
  EXPECT_EQ(g.fixable, 1u);
  EXPECT_FLOAT_EQ(row_column_estimate(coord, kW, near_mask, 6), 29.0f);
  EXPECT_FLOAT_EQ(row_column_estimate(coord, kW, far_from_mask, 6), 55.0f);
  EXPECT_TRUE(std::isnan(row_column_estimate(coord, kW, 20 * kW + 5, 6)));
  EXPECT_TRUE(fixable_pixel(0.6f, 1.0f));
  EXPECT_FALSE(fixable_pixel(0.95f, 1.0f));
  EXPECT_FALSE(fixable_pixel(0.2f, 1.0f));
  EXPECT_FALSE(fixable_pixel(kNaN, 1.0f));
}

// Too dark under the mask (correction.hpp): the masked round decodes a pixel
// only where Wm - B >= min_contrast (decode.hpp rule 1). Four flagged pixels
// that pass the light-ratio and stripe tests (Wm = 0.6 W1, |L - L̄| = 0.8 Wm),
// at round-1 whites of 10, 12.8, 13 and 100 DN of 255 (as on the chrome dish,
// ~10 DN, and a matte part): with min_contrast 0.03 (7.65 DN) the masked
// whites 6, 7.68, 7.8 and 60 DN give too dark, fixable (just above), fixable,
// fixable. With a black frame B = L + L̄ - Wm is
// subtracted first: a 1 DN black makes the 7.68 and 7.8 DN pixels too dark.
TEST(Correction, ForecastCountsPixelsTooDarkForTheMaskedRound) {
  const float dn = 1.0f / 255.0f;
  const std::vector<uint8_t> cls(4, kError), lit(4, 255);
  std::vector<float> w1, wm, plane, inverse;
  for (float white_dn : {10.0f, 12.8f, 13.0f, 100.0f}) {
    w1.push_back(white_dn * dn);
    wm.push_back(0.6f * white_dn * dn);
    plane.push_back(0.9f * wm.back());
    inverse.push_back(0.1f * wm.back());
  }
  const sdk::Rig rig = rectified_rig();
  const std::vector<uint8_t> no_mask;
  const std::vector<float> no_coord;
  std::vector<uint8_t> verdict;
  const RoundForecast f =
      forecast_round(rig, no_mask, no_coord, cls, lit, wm, w1, plane, inverse, 0.5f, 0.03f, false, &verdict);
  EXPECT_EQ(f.too_dark, 1u);
  EXPECT_EQ(f.fixable, 3u);
  EXPECT_EQ(f.flagged, f.own_light_off + f.unchanged + f.blurred + f.fixable + f.too_dark);
  EXPECT_EQ(verdict, (std::vector<uint8_t>{5, 4, 4, 4}));
  // Black frame: the probe's B = L + L̄ - Wm (here 1 DN on every pixel).
  for (size_t i = 0; i < 4; ++i) {
    plane[i] += 0.5f * dn;
    inverse[i] += 0.5f * dn;
  }
  const RoundForecast b =
      forecast_round(rig, no_mask, no_coord, cls, lit, wm, w1, plane, inverse, 0.5f, 0.03f, true, &verdict);
  EXPECT_EQ(verdict, (std::vector<uint8_t>{5, 5, 5, 4}));
  EXPECT_EQ(b.too_dark, 3u);
  // Without a black frame the same frames keep B = 0, as the decoder does.
  const RoundForecast nb =
      forecast_round(rig, no_mask, no_coord, cls, lit, wm, w1, plane, inverse, 0.5f, 0.03f, false);
  EXPECT_EQ(nb.too_dark, 1u);
  // min_contrast 0 (the thesis decoder): nothing is too dark.
  const RoundForecast z = forecast_round(rig, no_mask, no_coord, cls, lit, wm, w1, plane, inverse, 0.5f, 0.0f, false);
  EXPECT_EQ(z.too_dark, 0u);
  EXPECT_EQ(z.fixable, 4u);
}

}  // namespace
}  // namespace procam::sl
