// SPDX-License-Identifier: MIT
// The column intervals of gray and of the single codes min-SW and XOR-04
// (proj_col_uncertainty_px, issue 16)
// against the sim's ground truth: where a pixel's uncertain planes give an
// interval (uncertainty > 0), the interval must hold the true column,
//   |proj_col_px - truth| <= proj_col_uncertainty_px + 0.5
// (truth: the sim's continuous column, as the evaluators compare it; + 0.5:
// a decoded column c stands for the projector pixel around c),
// for at least 99 % of those pixels on every scene with global light, with
// the default rule and with tie_intervals. Exact pixels (uncertainty 0) are
// the claims tests' business. The single codes' intervals (default half-width
// 0.5: one blurred stripe edge) hold the truth less often on the wax candle:
// 97.7 % (min-SW) and 98.6 % (XOR-04) measured, asserted >= 97 / 98 %. Wax
// scatters light across the edge, which moves its blurred image by more than
// the half column the interval allows; those pixels are still few (min-SW's
// gross rate on the candle goes 0.04 -> 0.07 % with intervals, gray's default
// is 0.11 %; docs/structured-light.md). Scenes: where intervals come from blur
// (sub-surface scattering, defocus). Not the metal lamp: there long-range
// specular inter-reflection flips the *certain* planes too, so only ~26 % of
// its ~10k interval pixels hold the truth (docs/report/real.md) — an
// interval is only as right as the planes it trusts, a known limit of the
// rule, not asserted here.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <ostream>

#include "plugin_runs.hpp"

namespace procam {
namespace {

struct Case {
  const char* method;
  const char* scene;
  const char* params;
  double min_hold = 0.99;  // fraction of interval pixels whose interval holds the truth
};

// How gtest names a case in ctest's listing (instead of a byte dump).
void PrintTo(const Case& c, std::ostream* os) { *os << c.method << " on " << c.scene << " " << c.params; }

class Intervals : public ::testing::TestWithParam<Case> {};

TEST_P(Intervals, HoldTheTrueColumn) {
  const Case& c = GetParam();
  suite::SimRun run;
  ASSERT_TRUE(suite::run_on_sim("structured-light", c.method, c.scene, run, c.params));
  const host::Output* col = suite::find_output(run.outputs, "proj_col_px");
  const host::Output* unc = suite::find_output(run.outputs, "proj_col_uncertainty_px");
  ASSERT_NE(col, nullptr);
  ASSERT_NE(unc, nullptr);
  auto truth = run.rig->ground_truth(0);
  ASSERT_TRUE(truth.ok()) << truth.status().message();
  const uint32_t w = col->image.width, h = col->image.height;
  ASSERT_EQ(truth->proj_col.width(), w);
  ASSERT_EQ(truth->proj_col.height(), h);
  const auto* cp = static_cast<const float*>(col->image.data);
  const auto* up = static_cast<const float*>(unc->image.data);
  const auto* tp = truth->proj_col.ptr<float>();
  const uint8_t* lit = truth->lit.ptr<uint8_t>();
  size_t intervals = 0, hold = 0, gross_centre = 0;
  for (size_t i = 0; i < size_t{w} * h; ++i) {
    if (std::isnan(cp[i])) {
      EXPECT_TRUE(std::isnan(up[i])) << "pixel " << i << ": invalid, so no uncertainty";
      continue;
    }
    ASSERT_TRUE(std::isfinite(up[i]) && up[i] >= 0.0f) << "pixel " << i;
    if (up[i] == 0.0f || lit[i] == 0 || !std::isfinite(tp[i])) continue;
    ++intervals;
    const double err = std::fabs(static_cast<double>(cp[i]) - static_cast<double>(tp[i]));
    hold += err <= static_cast<double>(up[i]) + 0.5 ? 1u : 0u;
    gross_centre += err > 1.0 ? 1u : 0u;
  }
  const double frac = intervals == 0 ? 1.0 : static_cast<double>(hold) / static_cast<double>(intervals);
  std::printf("%-6s %-16s %-28s interval pixels %zu, truth inside %.3f%%, centre > 1 column off %zu\n", c.method, c.scene, c.params,
              intervals, 100 * frac, gross_centre);
  EXPECT_GE(frac, c.min_hold) << intervals << " interval pixels";
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, Intervals,
    ::testing::Values(Case{"gray", "bowl-on-marble", "{}"}, Case{"gray", "wax-candle", "{}"},
                      Case{"gray", "v-groove", "{}"}, Case{"gray", "bowl-on-marble", R"({"tie_intervals":true})"},
                      Case{"gray", "wax-candle", R"({"tie_intervals":true})"}, Case{"minsw", "bowl-on-marble", "{}"},
                      Case{"minsw", "wax-candle", "{}", 0.97}, Case{"minsw", "v-groove", "{}"},
                      Case{"xor04", "bowl-on-marble", "{}"}, Case{"xor04", "wax-candle", "{}", 0.98}),
    [](const ::testing::TestParamInfo<Case>& i) {
      std::string n = std::string(i.param.method) + "_" + i.param.scene +
                      (std::string(i.param.params) == "{}" ? "" : "_ties");
      for (char& ch : n)
        if (ch == '-') ch = '_';
      return n;
    });

}  // namespace
}  // namespace procam
