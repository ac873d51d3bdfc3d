// SPDX-License-Identifier: MIT
// Real captures decoded offline (issue 16): the five chessboard captures of
// shared/data/real/procam-calibration-sample (OpenCV GrayCodePattern order,
// 1024x768 projector, 1280x1024 8-bit camera) through run_offline with the
// "opencv-graycode" layout and the gray method's defaults, against a plain
// decode computed here independently (bit = pattern > inverse, lit = white -
// black >= 20 DN, binary-reflected Gray -> column).
// Targets (issue 16): the default decode keeps >= 97 % of the pixels the
// plain decode keeps, with fewer outliers (column more than 3 from both its
// left and its right neighbour in the row). The reference for the 97 % is
// the plain decode that leaves exact pattern = inverse ties undecoded (the
// issue's own "plain rule keeps 91-96 % of lit pixels"; here 91.2-96.5 %):
// with the defaults, whose stripe-averaged rule runs here because its gate
// opens (stripe_average.hpp; finest planes noise-bound on 22-32 % of lit
// pixels), coverage of it is 97.0-99.1 % (floor 97 %: a requirement) with
// 7-32 outliers against its 154-1 987. Against the plain decode that calls
// a tie a 0 bit, coverage is 88.9-95.9 % (defaults) and 91.9-97.4 % with the
// neighbour fill (fill_passes=4, off by default: it raises the sim's gross
// errors), outliers > 100x fewer; asserted at the measured floors.
// Skipped (GTEST_SKIP, with the reason) when the data folder shared/data
// beside the repository (or $PROCAM_DATA_DIR) is absent.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/image_io.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "core/testing/real_sample.hpp"

namespace procam::engine {
namespace {
namespace fs = std::filesystem;

fs::path sample_dir() { return testing::real_sample_dir(); }  // core/testing/real_sample.hpp
const fs::path kSample = sample_dir();
constexpr uint32_t kW = 1280, kH = 1024;
constexpr int kColPlanes = 10;

// Plain decode of one capture: column per pixel (NaN = unlit). With
// `reject_ties`, a pixel whose pattern equals its inverse on any column plane
// is not decoded either (a plain L > L-bar rule cannot decide a tie): that
// variant keeps 91.2-96.5 % of the lit pixels on this sample, the range issue
// 16 quotes for "the plain rule" (91-96 %); the other one calls a tie a 0 bit.
std::vector<float> plain_columns(const fs::path& dir, bool reject_ties = false) {
  auto load = [&](int i) {
    char name[32];
    std::snprintf(name, sizeof name, "graycode_%02d.png", i);
    auto img = read_image((dir / name).string());
    EXPECT_TRUE(img.ok()) << (dir / name);
    EXPECT_EQ(img->width(), kW);
    EXPECT_EQ(img->height(), kH);
    EXPECT_EQ(img->type(), PixelType::u8);
    return std::move(*img);
  };
  const Image white = load(40), black = load(41);
  std::vector<Image> planes;
  for (int k = 0; k < 2 * kColPlanes; ++k) planes.push_back(load(k));
  std::vector<float> col(size_t{kW} * kH, NAN);
  for (size_t i = 0; i < col.size(); ++i) {
    if (int{white.data()[i]} - int{black.data()[i]} < 20) continue;
    uint32_t gray = 0;
    bool tie = false;
    for (int k = 0; k < kColPlanes; ++k) {  // most significant first
      const uint8_t l = planes[2 * static_cast<size_t>(k)].data()[i], lbar = planes[2 * static_cast<size_t>(k) + 1].data()[i];
      gray = (gray << 1) | (l > lbar ? 1u : 0u);
      tie = tie || l == lbar;
    }
    if (reject_ties && tie) continue;
    uint32_t bin = gray;
    for (uint32_t s = 1; s < 16; s <<= 1) bin ^= bin >> s;
    col[i] = static_cast<float>(bin);
  }
  return col;
}

struct Stats {
  size_t kept = 0, outliers = 0;
};
// Outlier: a kept pixel whose left and right neighbours are both kept and
// whose column differs from each by more than 3.
Stats stats(const std::vector<float>& col) {
  Stats s;
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) {
      const float c = col[size_t{y} * kW + x];
      if (std::isnan(c)) continue;
      ++s.kept;
      if (x == 0 || x + 1 == kW) continue;
      const float l = col[size_t{y} * kW + x - 1], r = col[size_t{y} * kW + x + 1];
      if (!std::isnan(l) && !std::isnan(r) && std::fabs(c - l) > 3 && std::fabs(c - r) > 3) ++s.outliers;
    }
  return s;
}

TEST(OfflineRealCapture, OpencvGraycodeLayoutKeepsPlainCoverageWithFewerOutliers) {
  if (!fs::is_directory(kSample / "capture_0"))
    GTEST_SKIP() << "real sample not found at " << kSample.string()
                 << " (the folder shared/data beside the repository): nothing to decode";
  auto rig_cfg = read_json_file((fs::path(PROCAM_SOURCE_DIR) / "docs/report/real-sample-rig.json").string());
  ASSERT_TRUE(rig_cfg.ok()) << rig_cfg.status().to_string();
  auto rig_json = plugin_rig_json_from_config(*rig_cfg, 2);
  ASSERT_TRUE(rig_json.ok()) << rig_json.status().to_string();
  host::PluginHost host(host::LoadOptions{.probe_in_child = false});
  host.load_directories({PROCAM_PLUGIN_DIR});
  // The defaults (neighbour fill off: the sim's gross errors rise with it,
  // docs/report/real.md), and the real-capture setting fill_passes=4.
  // min_strict_coverage: against the plain decode that leaves exact ties
  // undecoded; issue 16's target, >= 97 % on every capture with the
  // defaults (measured 2026-11-24 with stripe averaging: 99.13 / 97.00 /
  // 98.11 / 98.13 / 97.38 %; fill_passes=4 99.28 / 97.47 / 98.76 / 98.64 /
  // 98.29 %). min_coverage: against the tie-as-zero plain decode, the
  // measured values rounded down (defaults 95.89 / 88.90 / 93.23 / 93.04 /
  // 91.43 %, fill 97.40 / 91.92 / 96.08 / 95.08 / 93.93 %).
  // Agreement (column or interval holds the plain column +- 0.5): without
  // stripe averaging every interval held it; the averaged planes decide
  // where the plain bit is within noise, so the two disagree on 0.15-0.38 %
  // of the common pixels (offline model 0.31-0.47 %; no ground truth says
  // which is right, the outliers are the check), >= 99.5 % asserted; the
  // fill chooses by the neighbours where the plain decode guessed, >= 98.5 %
  // (measured 98.95-99.71 %).
  struct Setting {
    const char* params;
    double min_coverage[5];
    double min_strict_coverage[5];
    double min_agreement;
  };
  for (const Setting& set :
       {Setting{R"({"rows":true})", {0.955, 0.885, 0.93, 0.93, 0.91}, {0.99, 0.97, 0.98, 0.98, 0.97}, 0.995},
        Setting{R"({"rows":true,"fill_passes":4})", {0.97, 0.915, 0.96, 0.95, 0.935}, {0.99, 0.97, 0.985, 0.985, 0.98},
                0.985}})
  for (int cap = 0; cap < 5; ++cap) {
    const fs::path dir = kSample / ("capture_" + std::to_string(cap));
    SCOPED_TRACE(dir.string() + " " + set.params);
    auto session = host.create_session("structured-light", "gray", set.params, rig_json->dump());
    ASSERT_TRUE(session.ok()) << session.status().to_string();
    auto outcome = run_offline(*session, dir.string(), nullptr, OfflineOptions{"opencv-graycode"});
    ASSERT_TRUE(outcome.ok()) << outcome.status().to_string();
    auto outs = session->outputs();
    ASSERT_TRUE(outs.ok()) << outs.status().to_string();
    std::vector<float> ours, unc, rows;
    nlohmann::json report;
    for (const auto& o : *outs) {
      if (o.kind == PROCAM_OUTPUT_JSON && o.name == "report") report = nlohmann::json::parse(o.json, nullptr, false);
      if (o.kind != PROCAM_OUTPUT_IMAGE) continue;
      const auto* p = static_cast<const float*>(o.image.data);
      if (o.name == "proj_col_px") ours.assign(p, p + size_t{kW} * kH);
      if (o.name == "proj_col_uncertainty_px") unc.assign(p, p + size_t{kW} * kH);
      if (o.name == "proj_row_px") rows.assign(p, p + size_t{kW} * kH);
    }
    ASSERT_EQ(ours.size(), size_t{kW} * kH);
    ASSERT_EQ(unc.size(), size_t{kW} * kH);
    // The image-level gate of the stripe-averaged rule (stripe_average.hpp):
    // this sample's finest planes are noise-bound on 22-32 % of its lit
    // pixels (offline model), far above the 10 % gate; every sim scene <= 1.7 %.
    ASSERT_TRUE(report.is_object() && report.contains("stripe_average")) << "report.stripe_average";
    const nlohmann::json& sa = report["stripe_average"];
    std::printf("capture_%d %s: %s; %zu pixels added, averaged noise b %.4f (per-pixel b %.4f)\n", cap,
                set.params, sa.value("summary", std::string()).c_str(), sa.value("pixels_added", size_t{0}),
                sa["averaged_noise"].value("b", 0.0), report["noise"].value("b", 0.0));
    EXPECT_GE(sa.value("f_noise", 0.0), 0.15) << "finest planes noise-bound on >= 15 % of lit pixels";
    EXPECT_TRUE(sa.value("fired", false)) << "the gate (10 %) opens on every capture";
    const std::vector<float> plain = plain_columns(dir);
    ASSERT_EQ(rows.size(), size_t{kW} * kH);
    const Stats sp = stats(plain), so = stats(ours);
    size_t rows_kept = 0;
    for (float r : rows) rows_kept += std::isnan(r) ? 0u : 1u;
    std::printf("  rows decoded: %zu px (%.2f%% of the plain decode's lit pixels)\n", rows_kept,
                100.0 * static_cast<double>(rows_kept) / static_cast<double>(sp.kept));
    size_t both = 0, agree = 0;
    for (size_t i = 0; i < plain.size(); ++i) {
      if (std::isnan(plain[i]) || std::isnan(ours[i])) continue;
      ++both;
      // Uncertainty bounds |column - centre|; a plain bit may be the other side.
      agree += std::fabs(ours[i] - plain[i]) <= unc[i] + 0.5f ? 1u : 0u;
      ASSERT_GE(unc[i], 0.0f);
    }
    {
      // Lost pixels: plain-kept, rejected here. How many disagree with a plain neighbour by > 1?
      size_t lost = 0, rough = 0;
      for (uint32_t y = 1; y + 1 < kH; ++y)
        for (uint32_t x = 1; x + 1 < kW; ++x) {
          const size_t i = size_t{y} * kW + x;
          if (std::isnan(plain[i]) || !std::isnan(ours[i])) continue;
          ++lost;
          const float l = plain[i - 1], r = plain[i + 1];
          rough += (std::isnan(l) || std::fabs(plain[i] - l) > 2) || (std::isnan(r) || std::fabs(plain[i] - r) > 2) ? 1u : 0u;
        }
      std::printf("  lost %zu, of which plain column jumps > 2 from a row neighbour: %zu\n", lost, rough);
    }
    const double coverage = static_cast<double>(both) / static_cast<double>(sp.kept);
    const std::vector<float> strict = plain_columns(dir, /*reject_ties=*/true);
    const Stats ss = stats(strict);
    size_t strict_both = 0;
    for (size_t i = 0; i < strict.size(); ++i) strict_both += !std::isnan(strict[i]) && !std::isnan(ours[i]) ? 1u : 0u;
    const double strict_coverage = static_cast<double>(strict_both) / static_cast<double>(ss.kept);
    std::printf("capture_%d %s: plain without ties %zu px (%.1f%% of the plain decode's, %zu outliers), "
                "coverage of it %.3f%%\n",
                cap, set.params, ss.kept, 100.0 * static_cast<double>(ss.kept) / static_cast<double>(sp.kept),
                ss.outliers, 100 * strict_coverage);
    EXPECT_GE(strict_coverage, set.min_strict_coverage[cap]);
    // Issue 16's outlier target against this reference: fewer (measured:
    // 7-32 against 154-1 987, 0-10 before stripe averaging; exact ties are
    // where a plain decode guesses most).
    EXPECT_LT(so.outliers, ss.outliers) << "fewer outliers than the tie-free plain decode";
    std::printf("capture_%d %s: plain %zu px (%zu outliers), ours %zu px (%zu outliers), coverage %.2f%%, "
                "agreement %.2f%%\n",
                cap, set.params, sp.kept, sp.outliers, so.kept, so.outliers, 100 * coverage,
                100.0 * static_cast<double>(agree) / static_cast<double>(both));
    EXPECT_GT(sp.kept, size_t{kW} * kH / 2) << "the plain decode itself should light most pixels";
    // Against the tie-as-zero plain decode (which guesses every tie): most
    // of what is lost has a plain column that jumps by > 2 from a row
    // neighbour (the plain decode guessed) or more uncertain planes than
    // are tracked (docs/report/real.md).
    EXPECT_GE(coverage, set.min_coverage[cap]);
    EXPECT_GE(static_cast<double>(agree), set.min_agreement * static_cast<double>(both))
        << "decoded columns (or their intervals) holding the plain column +- 0.5";
    EXPECT_LT(so.outliers * 100, sp.outliers) << "at least 100x fewer outliers than the plain decode";
  }
}

}  // namespace
}  // namespace procam::engine
