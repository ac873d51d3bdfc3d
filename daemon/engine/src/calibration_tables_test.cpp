// SPDX-License-Identifier: MIT
// Tests of the rig config's "calibration_tables" (calibration_tables.hpp):
// files resolved relative to the config, checked with the SDK's reader, every
// malformed case a clear error naming the config file and the field; the
// `procam rig` line with ranges computed here from the samples.
#include "procam/engine/calibration_tables.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace procam::engine {
namespace {
namespace fs = std::filesystem;

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

nlohmann::json table(const std::string& name = "defocus.two-focal") {
  return {{"format", "procam-calibration-table"}, {"version", 1}, {"name", name},
          {"x", {{"name", "omega"}, {"unit", "ratio"}}}, {"y", {{"name", "depth"}, {"unit", "mm"}}},
          {"samples", {{0.5, 900.0}, {1.0, 800.0}, {2.0, 650.0}}},
          {"made", {{"plugin", "defocus"}, {"date", "2026-11-23T10:00:00Z"}}}};
}

class CalibrationTables : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("procam-tables-" + std::to_string(::getpid()));
    fs::create_directories(dir_ / "tables");
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  void write(const std::string& rel, const nlohmann::json& j) { std::ofstream(dir_ / rel) << j.dump(); }
  Status load(const nlohmann::json& rig, nlohmann::json* out = nullptr) {
    auto r = load_calibration_tables(rig, dir_.string(), "rigs/my.json");
    if (r && out) *out = *r;
    return r.status();
  }
  fs::path dir_;
};

TEST_F(CalibrationTables, LoadsRelativeToTheConfigAndStripsTheKey) {
  write("tables/t.json", table());
  const nlohmann::json rig = {{"name", "r"}, {"calibration_tables", {{"defocus.two-focal", "tables/t.json"}}}};
  nlohmann::json got;
  ASSERT_TRUE(load(rig, &got).ok());
  EXPECT_EQ(got, (nlohmann::json{{"defocus.two-focal", table()}}));
  EXPECT_EQ(without_calibration_tables(rig), (nlohmann::json{{"name", "r"}}));
  nlohmann::json none;
  ASSERT_TRUE(load({{"name", "r"}}, &none).ok());  // absent: no tables
  EXPECT_TRUE(none.is_object() && none.empty());
}

TEST_F(CalibrationTables, EveryMistakeNamesTheFileAndTheField) {
  auto expect = [&](const nlohmann::json& rig, Code code, const std::string& part) {
    Status st = load(rig);
    ASSERT_FALSE(st.ok()) << rig.dump();
    EXPECT_EQ(st.code(), code) << st.to_string();
    EXPECT_TRUE(contains(st.message(), "rig config 'rigs/my.json'")) << st.to_string();
    EXPECT_TRUE(contains(st.message() + " " + st.hint(), part)) << st.to_string();
  };
  expect({{"calibration_tables", nlohmann::json::array()}}, Code::invalid_argument,
         "'calibration_tables' must be an object");
  expect({{"calibration_tables", {{"a", 5}}}}, Code::invalid_argument, "'calibration_tables.a' must be a file path");
  expect({{"calibration_tables", {{"a", "tables/none.json"}}}}, Code::not_found, "'calibration_tables.a'");
  nlohmann::json bad = table();
  bad["samples"][2][1] = 850.0;  // y turns back: not invertible
  write("tables/bad.json", bad);
  expect({{"calibration_tables", {{"defocus.two-focal", "tables/bad.json"}}}}, Code::invalid_argument,
         "y is not strictly monotonic at samples[2]");
  nlohmann::json typo = table();
  typo["sample"] = typo["samples"];
  write("tables/typo.json", typo);
  expect({{"calibration_tables", {{"defocus.two-focal", "tables/typo.json"}}}}, Code::invalid_argument,
         "unknown key \"sample\"");
  write("tables/other.json", table("defocus.multi-focal"));
  expect({{"calibration_tables", {{"defocus.two-focal", "tables/other.json"}}}}, Code::invalid_argument,
         "holds a table named 'defocus.multi-focal'");
  std::ofstream(dir_ / "tables" / "garbage.json") << "{not json";
  expect({{"calibration_tables", {{"a", "tables/garbage.json"}}}}, Code::invalid_argument, "is not valid JSON");
}

TEST_F(CalibrationTables, RigLineShowsNamesUnitsRangesCountAndMade) {
  const std::string line = describe_calibration_table("defocus.two-focal", table());
  // x 0.5..2, y 650..900 (the samples' extremes), 3 samples.
  EXPECT_EQ(line,
            "defocus.two-focal: omega [ratio] -> depth [mm], x 0.5..2, y 650..900, 3 samples; "
            "made: date 2026-11-23T10:00:00Z, plugin defocus");
}

}  // namespace
}  // namespace procam::engine
