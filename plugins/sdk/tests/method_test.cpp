// SPDX-License-Identifier: MIT
// Tests of sdk::MethodDescription (procam/sdk/method.hpp): the describe() JSON
// keys and types the protocol's list_plugins expects, and the checks that
// catch plugin bugs.
#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "procam/sdk/method.hpp"

namespace sdk = procam::sdk;

namespace {

sdk::MethodDescription demo() {
  sdk::MethodDescription d;
  d.name = "demo";
  d.summary = "a demonstration method";
  d.outputs = {"proj_col_px", "valid_fraction"};
  d.params = {{"bits", sdk::ParamType::integer, 10, 1.0, 16.0, {}, "code bits"}};
  return d;
}

TEST(SdkMethod, FixedCountsAreIntegersAndUnknownIsNull) {
  sdk::MethodDescription d = demo();
  d.patterns = 22;
  const nlohmann::json j = d.to_json();
  EXPECT_EQ(j["name"], "demo");
  EXPECT_EQ(j["description"], "a demonstration method");
  ASSERT_TRUE(j["patterns"].is_number_unsigned());
  EXPECT_EQ(j["patterns"], 22);
  EXPECT_FALSE(j.contains("patterns_formula"));  // omitted when empty
  EXPECT_EQ(j["rounds"], 1);
  EXPECT_EQ(j["outputs"], nlohmann::json({"proj_col_px", "valid_fraction"}));
  ASSERT_EQ(j["params"].size(), 1u);
  EXPECT_EQ(j["params"][0]["name"], "bits");
  EXPECT_EQ(j["params"][0]["type"], "int");
  EXPECT_EQ(j["params"][0]["max"], 16.0);

  d.patterns = std::nullopt;
  d.patterns_formula = "2 + 2*ceil(log2 W)";
  d.rounds_formula = "1 + up to correction_rounds";
  const nlohmann::json k = d.to_json();
  EXPECT_TRUE(k["patterns"].is_null());  // "depends" is null, never a string
  EXPECT_EQ(k["patterns_formula"], "2 + 2*ceil(log2 W)");
  EXPECT_EQ(k["rounds"], "1 + up to correction_rounds");
  EXPECT_EQ(k.size(), 7u);  // name description patterns patterns_formula rounds outputs params
}

TEST(SdkMethod, DescribeMethodsIsAnArrayInOrder) {
  sdk::MethodDescription a = demo(), b = demo();
  b.name = "other";
  const nlohmann::json arr = nlohmann::json::parse(sdk::describe_methods({a, b}));
  ASSERT_TRUE(arr.is_array());
  ASSERT_EQ(arr.size(), 2u);
  EXPECT_EQ(arr[0]["name"], "demo");
  EXPECT_EQ(arr[1]["name"], "other");
  EXPECT_EQ(sdk::describe_methods({}), "[]");
}

TEST(SdkMethod, PluginBugsThrow) {
  sdk::MethodDescription d = demo();
  d.outputs.push_back("Depth mm");
  EXPECT_THROW(d.to_json(), std::invalid_argument);
  sdk::MethodDescription e = demo();
  e.summary.clear();
  EXPECT_THROW(e.to_json(), std::invalid_argument);
  sdk::MethodDescription f = demo();
  f.name.clear();
  EXPECT_THROW(f.to_json(), std::invalid_argument);
}

}  // namespace
