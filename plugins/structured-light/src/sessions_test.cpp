// SPDX-License-Identifier: MIT
// Session-level tests of the methods added in issue 4, driven through the C++
// SDK (as the ABI glue does) with frames synthesized here from each plan's
// patterns: camera pixel (x, y) sees projector pixel (x, y) of a 256 x 48
// projector, L = 10 + 200 * pattern / 255 (+ optional per-pixel global light).
// Checks: phase-shift and modulated-phase-shift columns against the truth;
// every binary method's columns exact; auto stops after xor04 + minsw on a
// clean scene and asks for gray + xor02 where they disagree; the ensemble's
// correction stops with a reason on an uncalibrated rig; reports name the
// method and the patterns.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "codes.hpp"
#include "codes_session.hpp"
#include "gray_session.hpp"
#include "procam/sdk/map_cache.hpp"
#include "phase_session.hpp"
#include "vote.hpp"

namespace procam::sl {
namespace {

constexpr uint32_t kW = 256, kH = 48;

nlohmann::json rig_json() {
  return {{"projector", {{"width", kW}, {"height", kH}}},
          {"cameras", {{{"width", kW}, {"height", kH}, {"bit_depth", 8}}}},
          {"threads", 2}};
}

// A calibrated rectified rig for the correction tests: projector and camera
// share intrinsics (f = 100 px), camera 100 mm right of the projector. With
// `shift` = 16 the camera pixel (x, y) sees projector pixel (x + 16, y): a
// plane at 100 * 100 / 16 = 625 mm, so a decoded column triangulates back to
// the projector pixel it names and correction masks land where they should.
constexpr uint32_t kShift = 16;
nlohmann::json calibrated_rig_json() {
  const nlohmann::json k = {{"width", kW}, {"height", kH}, {"fx", 100.0}, {"fy", 100.0},
                            {"cx", (kW - 1) / 2.0}, {"cy", (kH - 1) / 2.0}};
  return {{"projector", {{"width", kW}, {"height", kH}, {"intrinsics", k}}},
          {"cameras",
           {{{"width", kW},
             {"height", kH},
             {"bit_depth", 8},
             {"calibration",
              {{"intrinsics", k},
               {"cam_from_proj",
                {{"rotation", {1, 0, 0, 0, 1, 0, 0, 0, 1}}, {"translation_mm", {-100.0, 0.0, 0.0}}}}}}}}},
          {"threads", 2}};
}

struct ScanRun {
  std::map<std::string, std::vector<float>> maps;
  std::map<std::string, std::vector<uint8_t>> maps8;
  std::map<std::string, double> scalars;
  nlohmann::json report;
  uint32_t rounds = 0, patterns = 0;
};

// `distort(round, frame label, x, y, value)` may alter a captured value.
using Distort = std::function<double(uint32_t, const std::string&, uint32_t, uint32_t, double)>;

// `shift` > 0 (with a calibrated rig): camera pixel (x, y) sees projector
// pixel (x + shift, y); pixels past the projector's edge see only 10 DN.
// `global(round, pattern, x, y)` adds light to a captured value (long-range
// global light computed from the whole pattern).
using Global = std::function<double(const uint8_t*, uint32_t, uint32_t)>;
ScanRun run(const std::string& method, nlohmann::json params, const Distort& distort = nullptr,
            nlohmann::json rig = rig_json(), uint32_t shift = 0, const Global& global = nullptr) {
  sdk::CreateArgs args{method, std::move(params), std::move(rig)};
  std::unique_ptr<sdk::Session> s;
  sdk::Error e = method.find("phase") != std::string::npos ? create_phase_session(args, s)
                 : method == "gray"                       ? create_gray_session(args, s)
                                                           : create_codes_session(args, s);
  EXPECT_TRUE(e.ok()) << e.message;
  ScanRun r;
  if (!e.ok()) return r;
  for (;;) {
    sdk::Plan plan;
    bool has = false;
    EXPECT_TRUE(s->next_plan(plan, has).ok());
    if (!has) break;
    ++r.rounds;
    r.patterns += plan.size();
    const procam_plan* cp = plan.view();
    for (uint32_t i = 0; i < plan.size(); ++i) {
      const auto pat = plan.pattern_u8(i);
      std::vector<uint8_t> px(size_t{kW} * kH);
      for (uint32_t y = 0; y < kH; ++y)
        for (uint32_t x = 0; x < kW; ++x) {
          const uint32_t px_x = x + shift;
          double v = 10.0 + (px_x < kW ? (shift > 0 ? 80.0 : 200.0) * pat[size_t{y} * kW + px_x] / 255.0 : 0.0);
          if (global) v += global(pat.data(), x, y);
          if (distort) v = distort(r.rounds, cp->frames[i].label, x, y, v);
          px[size_t{y} * kW + x] = static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 255.0)));
        }
      const sdk::Error fe = s->add_frame(i, sdk::gray_view(px.data(), kW, kH));
      EXPECT_TRUE(fe.ok()) << fe.message;
    }
    EXPECT_TRUE(s->end_round().ok());
    EXPECT_LT(r.rounds, 10u);
    if (r.rounds >= 10) break;
  }
  sdk::Outputs out;
  EXPECT_TRUE(s->outputs(out).ok());
  const procam_output* o = out.view();
  for (uint32_t i = 0; i < out.size(); ++i) {
    const std::string name = o[i].name;
    if (o[i].kind == PROCAM_OUTPUT_IMAGE && o[i].image.pixel_type == PROCAM_PIXEL_F32) {
      const auto* f = static_cast<const float*>(o[i].image.data);
      r.maps[name].assign(f, f + size_t{kW} * kH);
    }
    if (o[i].kind == PROCAM_OUTPUT_IMAGE && o[i].image.pixel_type == PROCAM_PIXEL_U8) {
      const auto* b = static_cast<const uint8_t*>(o[i].image.data);
      r.maps8[name].assign(b, b + size_t{kW} * kH);
    }
    if (o[i].kind == PROCAM_OUTPUT_SCALAR) r.scalars[name] = o[i].scalar;
    if (o[i].kind == PROCAM_OUTPUT_JSON) r.report = nlohmann::json::parse(o[i].json);
  }
  return r;
}

void expect_columns(const ScanRun& r, double tol, double min_valid) {
  const auto& c = r.maps.at("proj_col_px");
  size_t valid = 0;
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      const float v = c[size_t{y} * kW + x];
      if (!std::isfinite(v)) continue;
      ++valid;
      ASSERT_LE(std::fabs(static_cast<double>(v) - x), tol) << x << "," << y;
    }
  EXPECT_GE(static_cast<double>(valid), min_valid * kW * kH);
}

TEST(Sessions, PhaseShiftRecoversContinuousColumns) {
  const ScanRun r = run("phase-shift", nlohmann::json::object());
  EXPECT_EQ(r.patterns, 18u);
  expect_columns(r, 0.35, 0.99);  // 8-bit quantization of the sinusoids
  EXPECT_EQ(r.report["method"], "phase-shift");
}

TEST(Sessions, ModulatedPhaseShiftRecoversColumns) {
  const ScanRun r = run("modulated-phase-shift", nlohmann::json::object());
  EXPECT_EQ(r.patterns, 162u);
  expect_columns(r, 0.5, 0.99);
}

TEST(Sessions, BinaryMethodsExactOnDirectLight) {
  for (const char* m : {"xor02", "xor04", "minsw", "ensemble", "auto"}) {
    const ScanRun r = run(m, nlohmann::json::object());
    expect_columns(r, 0.0, 1.0);
    EXPECT_EQ(r.report["method"], m);
    EXPECT_EQ(r.scalars.at("pattern_count"), static_cast<double>(r.patterns)) << m;
    EXPECT_TRUE(r.maps.count("proj_col_subpx")) << m;
  }
}

// proj_col_subpx is built in recycled map storage (map_cache.hpp): a scan
// right after another must not show the first scan's values. The second
// scene is dark on its left half, so the columns there are NaN and the
// sub-pixel map must be NaN exactly there (and within the refinement's
// +-1 px clamp of the column elsewhere, subpixel.cpp).
TEST(Sessions, SubpixelMapOfTheNextScanHoldsNoStaleValues) {
  const ScanRun first = run("ensemble", nlohmann::json::object());
  ASSERT_TRUE(first.maps.count("proj_col_subpx"));
  const ScanRun r = run("ensemble", nlohmann::json::object(),
                        [](uint32_t, const std::string&, uint32_t x, uint32_t, double v) {
                          return x < kW / 2 ? 10.0 : v;
                        });
  const auto& col = r.maps.at("proj_col_px");
  const auto& sub = r.maps.at("proj_col_subpx");
  size_t nan_left = 0;
  for (size_t i = 0; i < col.size(); ++i) {
    ASSERT_EQ(std::isfinite(col[i]), std::isfinite(sub[i])) << "pixel " << i;
    if (std::isfinite(col[i])) {
      ASSERT_LE(std::fabs(sub[i] - col[i]), 1.0f) << "pixel " << i;
    }
    if (i % kW < kW / 2 && !std::isfinite(sub[i])) ++nan_left;
  }
  EXPECT_EQ(nan_left, size_t{kW / 2} * kH);  // the dark half: nothing decoded
}

TEST(Sessions, AutoStopsAfterFirstPairOnCleanScene) {
  const ScanRun r = run("auto", nlohmann::json::object());
  EXPECT_EQ(r.rounds, 1u);
  EXPECT_EQ(r.patterns, 1u + 8u + 10u);  // white + xor04 (8 bits at W = 256) + minsw
  EXPECT_NE(r.report["auto_decision"].get<std::string>().find("no further"), std::string::npos);
}

TEST(Sessions, AutoAddsCodesWhereFirstPairDisagrees) {
  // Columns 100..139: flip minsw's third plane (as blur near its edges would):
  // xor04 and minsw disagree there, gray + xor02 are projected and the vote
  // recovers the columns (gray, xor02, xor04 agree).
  const Distort flip = [](uint32_t, const std::string& label, uint32_t x, uint32_t, double v) {
    if (label == "minsw bit 7" && x >= 100 && x < 140) return 220.0 - v;
    return v;
  };
  const ScanRun r = run("auto", {{"correction_rounds", 0}}, flip);
  EXPECT_EQ(r.rounds, 2u);
  expect_columns(r, 0.0, 1.0);
  EXPECT_NE(r.report["auto_decision"].get<std::string>().find("gray and xor02"), std::string::npos);
}

TEST(Sessions, EnsembleDetectsErrorsAndStopsCorrectingWithoutCalibration) {
  // Columns 50..59: every code's LSB plane replaced by noise-free mid-grey
  // ties -> invalid in all codes -> error pixels; no calibration -> no mask.
  const Distort tie = [](uint32_t, const std::string& label, uint32_t x, uint32_t, double v) {
    if (x >= 50 && x < 60 && label != "white") return 110.0;
    return v;
  };
  const ScanRun r = run("ensemble", nlohmann::json::object(), tie);
  EXPECT_EQ(r.rounds, 1u);
  EXPECT_GT(r.scalars.at("error_fraction"), 0.03);
  EXPECT_NE(r.report["correction_stop"].get<std::string>().find("not calibrated"), std::string::npos);
  const auto& c = r.maps.at("proj_col_px");
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 50; x < 60; ++x) ASSERT_TRUE(std::isnan(c[size_t{y} * kW + x]));
}

// Issue 18, end to end through the session: camera columns 100..139 also
// see, by a mirror path, projector column x - 80 at 0.95 of their own direct
// light, so every bit where the two columns differ is a near-tie: no code
// decodes there, the pixels are flagged. Camera columns 4..43 show those
// mirror sources (projector 20..59) and decode cleanly, so the mask switches
// them off; the probe sees the flagged pixels lose the mirror light while
// keeping their own and predicts the round pays; the round (reusing the
// probe's white and finest xor02 plane) resolves them to their true columns.
TEST(Sessions, CorrectionRoundRunsWhenTheProbePredictsAGain) {
  const Global inter = [](const uint8_t* pat, uint32_t x, uint32_t y) {
    if (x < 100 || x >= 140) return 0.0;
    return 0.95 * 80.0 * pat[size_t{y} * kW + (x - 80)] / 255.0;
  };
  const ScanRun r = run("ensemble", {{"correction_rounds", 1}}, nullptr, calibrated_rig_json(), kShift, inter);
  ASSERT_TRUE(r.report.contains("steps")) << r.report.dump();
  const auto& steps = r.report["steps"];
  ASSERT_EQ(steps.size(), 1u) << r.report.dump();
  EXPECT_TRUE(steps[0]["taken"].get<bool>()) << steps.dump();
  EXPECT_GT(steps[0]["predicted_gain"].get<double>(), 0.05) << steps.dump();  // the region: 40 of 240 lit columns
  EXPECT_EQ(r.rounds, 3u);  // first pass, probe, correction
  // Patterns: 35 (1 + 3 x 8 + 10 at W = 256), probe 3, round 35 - 2 reused.
  EXPECT_EQ(r.patterns, 35u + 3u + 33u);
  const auto& c = r.maps.at("proj_col_px");
  size_t right = 0, wrong = 0, region = 0;
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 100; x < 140; ++x) {
      ++region;
      const float v = c[size_t{y} * kW + x];
      if (std::isnan(v)) continue;
      (std::fabs(v - static_cast<float>(x + kShift)) <= 0.5f ? right : wrong) += 1;
    }
  EXPECT_EQ(wrong, 0u);
  EXPECT_GE(static_cast<double>(right), 0.7 * static_cast<double>(region)) << steps.dump();
  // The measured change matches the sign and rough size of the prediction.
  EXPECT_LT(steps[0]["measured_change"].get<double>(), -0.5 * steps[0]["predicted_gain"].get<double>()) << steps.dump();
}

// The same rig with flagged pixels no mask can help (every code's frames are
// mid-grey ties there, like blur or noise would give): the probe predicts
// nothing fixable and the round is skipped, costing only the probe's 3 frames.
TEST(Sessions, CorrectionRoundSkippedWhenTheProbePredictsNoGain) {
  const Distort tie = [](uint32_t, const std::string& label, uint32_t x, uint32_t, double v) {
    if (x >= 100 && x < 120 && label.find("white") == std::string::npos) return 45.0;  // = W / 2: margin 0
    return v;
  };
  const ScanRun r = run("ensemble", {{"correction_rounds", 2}}, tie, calibrated_rig_json(), kShift);
  EXPECT_EQ(r.rounds, 2u);  // first pass + probe
  EXPECT_EQ(r.patterns, 35u + 3u);
  EXPECT_NE(r.report["correction_stop"].get<std::string>().find("round skipped"), std::string::npos)
      << r.report.dump();
  EXPECT_FALSE(r.report["steps"][0]["taken"].get<bool>());
}

TEST(Sessions, WeakFinestPlaneToleratedAndReported) {
  // Columns 30..39: xor04's bit 0 (the stripe-width-2 Gray plane, error bound
  // 1 column) and its inverse pushed to a 5% margin, right sign.
  const Distort weak = [](uint32_t, const std::string& label, uint32_t x, uint32_t, double v) {
    if (x >= 30 && x < 40 && label.rfind("xor04 bit 0", 0) == 0) return v > 110.0 ? 115.0 : 105.0;
    return v;
  };
  // The tolerance rule alone: intervals (max_uncertainty_px, below) off.
  const ScanRun tolerant = run("xor04", {{"max_uncertainty_px", 0}}, weak);  // max_weak_error_px default: 1
  const ScanRun strict = run("xor04", {{"max_weak_error_px", 0}, {"max_uncertainty_px", 0}}, weak);
  EXPECT_EQ(tolerant.report["max_weak_error_px"], 1);
  EXPECT_EQ(strict.report["max_weak_error_px"], 0);
  const nlohmann::json& code = tolerant.report["codes"][0];
  EXPECT_EQ(code["error_bound_px"][0], 1);
  EXPECT_EQ(code["tolerated_weak_bits"], nlohmann::json::array({0}));
  EXPECT_EQ(code["weak_plane_pixels"], 10u * kH);
  EXPECT_EQ(strict.report["codes"][0]["weak_plane_pixels"], 0u);
  const auto& ct = tolerant.maps.at("proj_col_px");
  const auto& cs = strict.maps.at("proj_col_px");
  const auto& conf = tolerant.maps.at("confidence");
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 30; x < 40; ++x) {
      const size_t i = size_t{y} * kW + x;
      ASSERT_EQ(ct[i], static_cast<float>(x)) << x;
      ASSERT_TRUE(std::isnan(cs[i])) << x;
      ASSERT_NEAR(conf[i], 0.05f, 0.01f);
    }
}

// Single codes give a pixel at a blurred stripe edge the interval of the two
// columns it lies between (MultiCodeDecoder::set_uncertain_output), as gray
// does. At camera column x the one plane whose bit changes between projector
// columns x and x + 1 (and that is not the tolerated finest plane) is pushed
// to a 5 % margin, right sign: below min_bit_margin (10 %). With intervals
// (default max_uncertainty_px 0.5) the pixel decodes to x + 0.5 with
// half-width 0.5, an interval holding the true column x; without them it is
// invalid. A low margin on a plane with no edge next to x names a far column
// and stays invalid either way.
TEST(Sessions, SingleCodesGiveStripeEdgesAnInterval) {
  // min-SW only: its adjacent columns differ in exactly one plane and its
  // stripes are >= 8 wide, so both kinds of pixel exist; the XOR codes'
  // adjacent columns differ in every plane above the base at a base edge,
  // and no XOR plane is flat over 5 columns.
  for (const std::string id : {"minsw"}) {
    SCOPED_TRACE(id);
    const ProjectedCode pc = make_projected_code(id, kW);
    const uint32_t bits = pc.bits();
    // Per camera column: the plane to weaken (-1: none) and whether it sits at an edge.
    std::vector<int> plane_at(kW, -1);
    std::vector<uint8_t> at_edge(kW, 0);
    for (uint32_t x = 8; x + 8 < kW; ++x) {
      int differ = 0, p_edge = -1;
      for (uint32_t p = 0; p < bits; ++p)
        if (pc.bit(p, x) != pc.bit(p, x + 1)) {
          ++differ;
          p_edge = static_cast<int>(p);
        }
      if (x % 2 == 0) {  // even columns: the edge plane, if it is the only one and not the finest
        if (differ == 1 && p_edge != static_cast<int>(bits) - 1) {
          plane_at[x] = p_edge;
          at_edge[x] = 1;
        }
      } else {  // odd columns: a plane with no edge within 2 columns (a flip names a far column)
        for (uint32_t p = 0; p + 1 < bits && plane_at[x] < 0; ++p) {
          bool flat = true;
          for (uint32_t d = x - 2; d <= x + 2; ++d) flat = flat && pc.bit(p, d) == pc.bit(p, x);
          if (flat) plane_at[x] = static_cast<int>(p);
        }
      }
    }
    const Distort weaken = [&](uint32_t, const std::string& label, uint32_t x, uint32_t, double v) {
      if (plane_at[x] < 0) return v;
      const std::string plane = id + " bit " + std::to_string(bits - 1 - static_cast<uint32_t>(plane_at[x]));
      if (label != plane && label != plane + " inverse") return v;
      return v > 110.0 ? 115.0 : 105.0;  // margin 10 of contrast 200
    };
    const ScanRun with = run(id, nlohmann::json::object(), weaken);
    const ScanRun without = run(id, {{"max_uncertainty_px", 0}}, weaken);
    ASSERT_TRUE(with.maps.count("proj_col_uncertainty_px"));
    EXPECT_FALSE(without.maps.count("proj_col_uncertainty_px"));
    const auto& c = with.maps.at("proj_col_px");
    const auto& u = with.maps.at("proj_col_uncertainty_px");
    const auto& c0 = without.maps.at("proj_col_px");
    size_t edges = 0, far = 0;
    for (uint32_t y = 0; y < kH; ++y)
      for (uint32_t x = 0; x < kW; ++x) {
        const size_t i = size_t{y} * kW + x;
        if (plane_at[x] < 0) {  // untouched: exact
          ASSERT_EQ(c[i], static_cast<float>(x)) << x;
          ASSERT_EQ(u[i], 0.0f) << x;
        } else if (at_edge[x] != 0) {
          ASSERT_EQ(c[i], static_cast<float>(x) + 0.5f) << x;
          ASSERT_EQ(u[i], 0.5f) << x;
          ASSERT_TRUE(std::isnan(c0[i])) << x;
          ++edges;
        } else {
          ASSERT_TRUE(std::isnan(c[i])) << x;
          ASSERT_TRUE(std::isnan(u[i])) << x;
          ASSERT_TRUE(std::isnan(c0[i])) << x;
          ++far;
        }
      }
    EXPECT_GT(edges, 20u * kH);
    EXPECT_GT(far, 20u * kH);
    EXPECT_EQ(with.report["max_uncertainty_px"], 0.5);
    EXPECT_EQ(with.report["noise_k"], 3.0);
  }
}

// The report's pixel counts (transport_classes, valid_fraction,
// error_fraction) are counted in the vote's own pass on the first round
// (VoteSpec::count, issue 17) and in a separate pass otherwise (auto's
// second step, correction rounds): either way they must be the counts of
// the maps the scan returns. Unlit pixels are class unlit, so lit = all -
// unlit, and the flagged ones are error + conflict.
TEST(Sessions, ReportedPixelCountsAreThoseOfTheReturnedMaps) {
  const Distort tie = [](uint32_t, const std::string& label, uint32_t x, uint32_t y, double v) {
    if (x >= 50 && x < 60 && label != "white") return 110.0;            // errors in every code
    if (x >= 200 && y < 10) return 10.0;                                 // shadow: unlit
    if (x >= 150 && x < 160 && label.find("gray") != std::string::npos)  // gray alone broken
      return 255.0 - v;
    return v;
  };
  const Global inter = [](const uint8_t* pat, uint32_t x, uint32_t y) {  // mirror: flagged, then corrected
    if (x < 100 || x >= 140) return 0.0;
    return 0.95 * 80.0 * pat[size_t{y} * kW + (x - 80)] / 255.0;
  };
  struct Case {
    const char* method;
    nlohmann::json params;
    bool corrected;
  };
  for (const Case& k : {Case{"ensemble", nlohmann::json::object(), false}, Case{"auto", nlohmann::json::object(), false},
                        Case{"ensemble", {{"code_maps", true}}, false},
                        Case{"ensemble", {{"correction_rounds", 1}}, true}}) {
    const ScanRun r = k.corrected ? run(k.method, k.params, nullptr, calibrated_rig_json(), kShift, inter)
                                  : run(k.method, k.params, tie);
    const std::string what = std::string(k.method) + " " + k.params.dump();
    const auto& cls = r.maps8.at("transport_class");
    const auto& valid = r.maps8.at("valid");
    std::vector<size_t> hist(kTransportClassCount, 0);
    size_t n_valid = 0;
    for (size_t i = 0; i < cls.size(); ++i) {
      ++hist.at(cls[i]);
      n_valid += valid[i] != 0 ? 1u : 0u;
    }
    const auto& classes = r.report.at("transport_classes");
    size_t kinds = 0;
    for (uint8_t c = 0; c < kTransportClassCount; ++c) {
      EXPECT_EQ(classes.at(transport_class_name(c)).get<size_t>(), hist[c]) << what << " class " << int(c);
      kinds += hist[c] > 0 ? 1u : 0u;
    }
    EXPECT_GE(kinds, 3u) << what << ": the scene should give several classes";  // not vacuous
    const double n = static_cast<double>(cls.size());
    EXPECT_DOUBLE_EQ(r.scalars.at("valid_fraction"), static_cast<double>(n_valid) / n) << what;
    const size_t lit = cls.size() - hist[kUnlit];
    EXPECT_DOUBLE_EQ(r.scalars.at("error_fraction"),
                     static_cast<double>(hist[kError] + hist[kConflict]) / static_cast<double>(lit))
        << what;
  }
}

TEST(Sessions, BadParamsAreRejected) {
  std::unique_ptr<sdk::Session> s;
  EXPECT_FALSE(create_codes_session({"ensemble", {{"agree_px", -1}}, rig_json()}, s).ok());
  EXPECT_FALSE(create_codes_session({"xor04", {{"correction_rounds", 1}}, rig_json()}, s).ok());
  EXPECT_FALSE(create_phase_session({"phase-shift", {{"unwrap_tolerance", 0.9}}, rig_json()}, s).ok());
  EXPECT_FALSE(create_codes_session({"minsw", nlohmann::json::object(), nullptr}, s).ok());
}

// Output maps recycled through the map cache (map_cache.hpp) hold the last
// scan's values until the decoder overwrites them. A scan after a different
// one must give exactly the maps of the same scan with the cache off: scan A
// is fully lit and valid everywhere; scan B has a shadowed band (unlit,
// invalid), a band of near ties (invalid) and noise-free columns elsewhere,
// so any pixel the decoder failed to write would keep A's valid value.
TEST(MapCache, RecycledMapsGiveTheSameResults) {
  const Distort scene_b = [](uint32_t, const std::string& label, uint32_t x, uint32_t, double v) {
    if (x < 40) return 10.0;  // shadow under 10 DN of ambient light
    if (x >= 100 && x < 120 && label.find("bit") != std::string::npos)
      return v > 100 ? 113.0 : 107.0;  // near ties: |L - L̄| = 6 DN << 0.1 (W - B)
    return v;
  };
  const Distort scene_a = [](uint32_t, const std::string&, uint32_t, uint32_t, double v) { return v + 5.0; };
  const size_t limit = sdk::map_cache_limit();
  for (const char* m : {"gray", "ensemble", "xor04"}) {
    sdk::set_map_cache_limit(0);
    const ScanRun ref = run(m, nlohmann::json::object(), scene_b);
    EXPECT_EQ(sdk::map_cache_bytes(), 0u) << m;
    sdk::set_map_cache_limit(limit);
    (void)run(m, nlohmann::json::object(), scene_a);  // its maps go to the cache at session end
    EXPECT_GT(sdk::map_cache_bytes(), size_t{kW} * kH * 4) << m;
    const ScanRun got = run(m, nlohmann::json::object(), scene_b);
    ASSERT_FALSE(ref.maps.empty()) << m;
    for (const auto& [name, want] : ref.maps) {
      const auto& have = got.maps.at(name);
      size_t diff = 0;
      for (size_t i = 0; i < want.size(); ++i)
        diff += !(want[i] == have[i] || (std::isnan(want[i]) && std::isnan(have[i])));
      EXPECT_EQ(diff, 0u) << m << " / " << name;
    }
    for (const auto& [name, want] : ref.maps8) EXPECT_EQ(got.maps8.at(name), want) << m << " / " << name;
    // The scan really has invalid pixels (so stale values would show): the
    // shadow and the near-tie band, 60 of 256 columns.
    size_t invalid = 0;
    for (float c : ref.maps.at("proj_col_px")) invalid += std::isnan(c) ? 1u : 0u;
    EXPECT_EQ(invalid, size_t{60} * kH) << m;
  }
  sdk::set_map_cache_limit(limit);
}

// The ensemble's 41 patterns have no black frame (B = 0 assumed): a shadow
// under ambient light reads "on" in every plane. Each code then decodes its
// all-ones word; XOR-02's (column 1) and XOR-04's (column 2) agree within a
// column, which used to be voted valid. The shadow rule (multi_round.hpp)
// marks such pixels unlit; every lit pixel still decodes exactly, including
// the columns whose word is all ones in one code (gray 170, xor02 1, xor04 2,
// minsw 74 at 256 columns).
TEST(Sessions, EnsembleWithoutBlackFrameRejectsAmbientShadow) {
  const Distort shadow = [](uint32_t, const std::string&, uint32_t x, uint32_t y, double v) {
    return x >= 200 && y < 10 ? 10.0 : v;  // a shadowed block; 10 DN > min_contrast's 7.65
  };
  for (const char* m : {"ensemble", "auto"}) {
    const ScanRun r = run(m, nlohmann::json::object(), shadow);
    const auto& col = r.maps.at("proj_col_px");
    const auto& cls = r.maps8.at("transport_class");
    for (uint32_t y = 0; y < kH; ++y)
      for (uint32_t x = 0; x < kW; ++x) {
        const size_t i = size_t{y} * kW + x;
        if (x >= 200 && y < 10) {
          ASSERT_TRUE(std::isnan(col[i])) << m << " " << x << "," << y << " decoded " << col[i];
          ASSERT_EQ(cls[i], 0) << m << " " << x << "," << y;  // kUnlit
        } else {
          ASSERT_EQ(col[i], static_cast<float>(x)) << m << " " << x << "," << y;
        }
      }
  }
  // The per-code maps (code_maps) mark the shadow invalid too.
  const ScanRun r = run("ensemble", {{"code_maps", true}}, shadow);
  for (const char* code : {"gray", "xor02", "xor04", "minsw"}) {
    const auto& c = r.maps.at(std::string("proj_col_px_") + code);
    EXPECT_TRUE(std::isnan(c[size_t{5} * kW + 220])) << code;
    EXPECT_EQ(c[size_t{20} * kW + 220], 220.0f) << code;
  }
}

}  // namespace
}  // namespace procam::sl
