// SPDX-License-Identifier: MIT
// CalibrationTable: format checks, lookup/inverse, never extrapolating, and
// fit_monotonic on noisy scattered pairs from a known map.
#include "procam/sdk/calibration_table.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "procam/sdk/rig.hpp"

namespace procam::sdk {
namespace {

nlohmann::json good_table() {
  return {{"format", "procam-calibration-table"},
          {"version", 1},
          {"name", "defocus.multi-focal"},
          {"x", {{"name", "fbar"}, {"unit", "index"}}},
          {"y", {{"name", "depth"}, {"unit", "mm"}}},
          {"samples", {{0.0, 500.0}, {1.0, 600.0}, {3.0, 800.0}}},
          {"made", {{"scene", "ch2-plane"}}}};
}

TEST(CalibrationTable, ParsesAndInterpolatesLinearly) {
  CalibrationTable t;
  ASSERT_TRUE(parse_table(good_table(), t).ok());
  EXPECT_EQ(t.name, "defocus.multi-focal");
  EXPECT_EQ(t.x_name, "fbar");
  EXPECT_FLOAT_EQ(t.lookup(0.5), 550.f);
  EXPECT_FLOAT_EQ(t.lookup(2.0), 700.f);
  EXPECT_FLOAT_EQ(t.lookup(3.0), 800.f);
  EXPECT_FLOAT_EQ(t.inverse(700.0), 2.f);
  EXPECT_TRUE(t.y_increasing());
}

TEST(CalibrationTable, NeverExtrapolates) {
  CalibrationTable t;
  ASSERT_TRUE(parse_table(good_table(), t).ok());
  EXPECT_TRUE(std::isnan(t.lookup(-0.01)));
  EXPECT_TRUE(std::isnan(t.lookup(3.01)));
  EXPECT_TRUE(std::isnan(t.lookup(NAN)));
  EXPECT_TRUE(std::isnan(t.lookup(INFINITY)));
  EXPECT_TRUE(std::isnan(t.inverse(499.0)));
  EXPECT_TRUE(std::isnan(t.inverse(NAN)));
}

TEST(CalibrationTable, DecreasingTablesWork) {
  nlohmann::json j = good_table();
  j["samples"] = {{0.1, 900.0}, {0.5, 700.0}, {0.9, 400.0}};
  CalibrationTable t;
  ASSERT_TRUE(parse_table(j, t).ok());
  EXPECT_FALSE(t.y_increasing());
  EXPECT_FLOAT_EQ(t.lookup(0.3), 800.f);
  EXPECT_NEAR(t.inverse(550.0), 0.7, 1e-6);
}

TEST(CalibrationTable, RejectsMalformedTablesNamingTheField) {
  auto expect_error = [](nlohmann::json j, const std::string& needle) {
    CalibrationTable t;
    Error e = parse_table(j, t);
    ASSERT_FALSE(e.ok()) << needle;
    EXPECT_NE(e.message.find(needle), std::string::npos) << e.message;
  };
  nlohmann::json j = good_table();
  j["format"] = "something-else";
  expect_error(j, "format must be");
  j = good_table();
  j["version"] = 2;
  expect_error(j, "version must be 1");
  j = good_table();
  j["sampels"] = j["samples"];
  expect_error(j, "unknown key \"sampels\"");
  j = good_table();
  j["samples"] = {{0.0, 500.0}, {0.0, 600.0}};
  expect_error(j, "x must increase strictly");
  j = good_table();
  j["samples"] = {{0.0, 500.0}, {1.0, 600.0}, {2.0, 550.0}};
  expect_error(j, "not strictly monotonic at samples[2]");
  j = good_table();
  j["samples"] = {{0.0, 500.0}};
  expect_error(j, "at least 2");
  j = good_table();
  j["samples"] = {{0.0, 500.0}, {1.0, "600"}};
  expect_error(j, "samples[1] must be a pair of numbers");
  j = good_table();
  j.erase("x");
  expect_error(j, "x and y");
}

TEST(CalibrationTable, JsonRoundTrip) {
  CalibrationTable t, back;
  ASSERT_TRUE(parse_table(good_table(), t).ok());
  ASSERT_TRUE(parse_table(to_json(t), back).ok());
  EXPECT_EQ(back.samples, t.samples);
  EXPECT_EQ(back.made, t.made);
}

// A known map depth = 400 + 300·x² on x ∈ [0.2, 2], noisy pixels and 2 %
// wild outliers: the fitted table reproduces the map within 1 mm inside.
TEST(CalibrationTable, FitMonotonicIsRobustToNoiseAndOutliers) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> ux(0.2f, 2.0f), wild(0.f, 3000.f), u01(0.f, 1.f);
  std::normal_distribution<float> noise(0.f, 5.f);
  std::vector<float> xs, ys;
  for (int i = 0; i < 40000; ++i) {
    const float x = ux(rng);
    xs.push_back(x);
    ys.push_back(u01(rng) < 0.02f ? wild(rng) : 400.f + 300.f * x * x + noise(rng));
  }
  xs.push_back(NAN);  // invalid pixels are skipped
  ys.push_back(500.f);
  CalibrationTable t;
  t.name = "test";
  t.x_name = "x";
  t.x_unit = "1";
  ASSERT_TRUE(fit_monotonic(xs, ys, 32, t).ok());
  EXPECT_EQ(t.samples.size(), 32u);
  CalibrationTable check;
  ASSERT_TRUE(parse_table(to_json(t), check).ok());  // always a valid table
  for (double x = 0.3; x <= 1.9; x += 0.1) {
    const double truth = 400 + 300 * x * x;
    EXPECT_NEAR(t.lookup(x), truth, 1.5) << "x=" << x;
  }
}

TEST(CalibrationTable, FitMonotonicRefusesFlatOrTooFewData) {
  CalibrationTable t;
  std::vector<float> xs(100, 1.f), ys(100, 700.f);
  for (size_t i = 0; i < xs.size(); ++i) xs[i] = static_cast<float>(i);
  Error e = fit_monotonic(xs, ys, 8, t);  // y flat: no monotonic run
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.message.find("tilt it more"), std::string::npos);
  e = fit_monotonic(std::vector<float>(5, 1.f), std::vector<float>(5, 1.f), 8, t);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.message.find("valid pixels"), std::string::npos);
  e = fit_monotonic(std::vector<float>(5), std::vector<float>(4), 2, t);
  EXPECT_FALSE(e.ok());
}

TEST(CalibrationTable, RigCarriesTables) {
  nlohmann::json rig = {{"projector", {{"width", 64}, {"height", 48}}},
                        {"cameras", {{{"width", 64}, {"height", 48}}}},
                        {"calibration_tables", {{"defocus.multi-focal", good_table()}}}};
  Rig r;
  ASSERT_TRUE(parse_rig(rig, r).ok());
  ASSERT_NE(r.table("defocus.multi-focal"), nullptr);
  EXPECT_EQ(r.table("separation.one-focal-depth"), nullptr);
  CalibrationTable t;
  EXPECT_TRUE(parse_table(*r.table("defocus.multi-focal"), t).ok());
  rig["calibration_tables"] = {{"x", 3}};
  Error e = parse_rig(rig, r);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.message.find("calibration_tables.x must be a table object"), std::string::npos);
}

}  // namespace
}  // namespace procam::sdk
