// SPDX-License-Identifier: MIT
// Tests of sdk::add_standard_outputs (procam/sdk/standard_outputs.hpp): names,
// units, values and the report's "patterns" key.
#include <gtest/gtest.h>

#include <map>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "procam/sdk/standard_outputs.hpp"

namespace sdk = procam::sdk;

namespace {

std::map<std::string, procam_output> by_name(sdk::Outputs& out) {
  std::map<std::string, procam_output> m;
  const procam_output* o = out.view();
  for (uint32_t i = 0; i < out.size(); ++i) m[o[i].name] = o[i];
  return m;
}

TEST(SdkStandardOutputs, AddsTheFourOutputsWithUnitsAndValues) {
  sdk::Outputs out;
  sdk::StandardOutputs s;
  s.decode_ms = 12.5;
  s.pattern_count = 41;
  s.valid_pixels = 3;
  s.total_pixels = 12;
  s.report = {{"method", "demo"}};
  sdk::add_standard_outputs(out, s);
  auto m = by_name(out);
  ASSERT_EQ(m.size(), 4u);
  EXPECT_EQ(m["decode_ms"].kind, PROCAM_OUTPUT_SCALAR);
  EXPECT_STREQ(m["decode_ms"].unit, "ms");
  EXPECT_EQ(m["decode_ms"].scalar, 12.5);
  EXPECT_EQ(m["pattern_count"].scalar, 41.0);
  EXPECT_STREQ(m["pattern_count"].unit, "");
  EXPECT_EQ(m["valid_fraction"].scalar, 0.25);  // 3 / 12
  ASSERT_EQ(m["report"].kind, PROCAM_OUTPUT_JSON);
  const nlohmann::json r = nlohmann::json::parse(m["report"].json);
  EXPECT_EQ(r["method"], "demo");
  EXPECT_EQ(r["patterns"], 41);  // filled in from pattern_count
}

TEST(SdkStandardOutputs, KeepsTheReportsOwnPatternsAndHandlesNoPixels) {
  sdk::Outputs out;
  sdk::StandardOutputs s;
  s.pattern_count = 5;
  s.report = {{"patterns", 4}};  // a plugin's own count wins
  sdk::add_standard_outputs(out, s);
  auto m = by_name(out);
  EXPECT_EQ(m["valid_fraction"].scalar, 0.0);  // total 0: no division by zero
  EXPECT_EQ(nlohmann::json::parse(m["report"].json)["patterns"], 4);
}

TEST(SdkStandardOutputs, RejectsANonObjectReportAndDuplicates) {
  sdk::Outputs out;
  sdk::StandardOutputs s;
  s.report = nlohmann::json::array();
  EXPECT_THROW(sdk::add_standard_outputs(out, s), std::invalid_argument);
  sdk::Outputs twice;
  twice.add_scalar("decode_ms", "ms", "", 1.0);
  EXPECT_THROW(sdk::add_standard_outputs(twice, sdk::StandardOutputs{}), std::invalid_argument);
}

}  // namespace
