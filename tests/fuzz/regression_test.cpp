// SPDX-License-Identifier: MIT
// Replays the committed fuzz seed corpus and every kept crash input
// (tests/fuzz/regressions/) through the fuzz harnesses, built with the normal
// compiler: runs in every `make test`, with or without clang.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../../daemon/procamd/config.hpp"

extern "C" int FuzzRequest(const uint8_t* data, size_t size);
extern "C" int FuzzConfig(const uint8_t* data, size_t size);
extern "C" int FuzzWorker(const uint8_t* data, size_t size);

namespace {
namespace fs = std::filesystem;

std::vector<fs::path> inputs(const std::string& kind) {
  std::vector<fs::path> out;
  for (const char* root : {"corpus", "regressions"}) {
    const fs::path dir = fs::path(PROCAM_SOURCE_DIR) / "tests/fuzz" / root / kind;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.is_regular_file()) out.push_back(e.path());
  }
  return out;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(FuzzRegression, RequestCorpusAndCrashInputs) {
  auto files = inputs("request");
  EXPECT_GE(files.size(), 10u);
  for (const auto& f : files) {
    const std::string s = slurp(f);
    SCOPED_TRACE(f.string());
    EXPECT_EQ(FuzzRequest(reinterpret_cast<const uint8_t*>(s.data()), s.size()), 0);
  }
}

TEST(FuzzRegression, ConfigCorpusAndCrashInputs) {
  auto files = inputs("config");
  EXPECT_GE(files.size(), 5u);
  for (const auto& f : files) {
    const std::string s = slurp(f);
    SCOPED_TRACE(f.string());
    EXPECT_EQ(FuzzConfig(reinterpret_cast<const uint8_t*>(s.data()), s.size()), 0);
  }
}

TEST(FuzzRegression, WorkerProtocolCorpusAndCrashInputs) {
  auto files = inputs("worker");
  EXPECT_GE(files.size(), 5u);
  for (const auto& f : files) {
    const std::string s = slurp(f);
    SCOPED_TRACE(f.string());
    EXPECT_EQ(FuzzWorker(reinterpret_cast<const uint8_t*>(s.data()), s.size()), 0);
  }
}

// The count fields accept JSON integers in range only. A huge float (1e52
// threads, found by fuzz_config in CI) used to reach an unsigned conversion,
// which is undefined behaviour; 2.5 was silently truncated to 2.
TEST(FuzzRegression, ConfigCountsAreIntegersInRange) {
  const auto base = nlohmann::json{{"rig", nlohmann::json{{"name", "inline"}}}};
  auto with = [&](const char* key, nlohmann::json v) {
    auto j = base;
    j[key] = std::move(v);
    return procam::daemon::parse_config(j, "/fuzz/base");
  };
  ASSERT_TRUE(procam::daemon::parse_config(base, "/fuzz/base").ok());
  for (const char* key : {"threads", "max_queue"}) {
    SCOPED_TRACE(key);
    for (const nlohmann::json& bad : {nlohmann::json(1.2e52), nlohmann::json(2.5), nlohmann::json(-1),
                                      nlohmann::json(0), nlohmann::json(1000000), nlohmann::json("4")}) {
      auto c = with(key, bad);
      ASSERT_FALSE(c.ok()) << bad.dump();
      EXPECT_NE(c.status().message().find(key), std::string::npos) << c.status().message();
      EXPECT_NE(c.status().message().find("integer"), std::string::npos) << c.status().message();
    }
  }
  auto ok = with("threads", 8);
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  EXPECT_EQ(ok->threads, 8u);
  ok = with("max_queue", 100000);
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  EXPECT_EQ(ok->max_queue, 100000u);
}

}  // namespace
