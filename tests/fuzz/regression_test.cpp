// SPDX-License-Identifier: MIT
// Replays the committed fuzz seed corpus and every kept crash input
// (tests/fuzz/regressions/) through the fuzz harnesses, built with the normal
// compiler: runs in every `make test`, with or without clang.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

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

}  // namespace
