// SPDX-License-Identifier: MIT
// Offline frame layouts (frame_layout.hpp): file -> plan frame assignments
// checked against orders written out by hand, and the error messages.
#include "procam/engine/frame_layout.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace procam::engine {
namespace {
namespace fs = std::filesystem;

// The gray plan of a 4-column, 2-row projector with inverses and rows
// (plan_layout.hpp order): white, black, col bit 1, inv, col bit 0, inv, row bit 0, inv.
const std::vector<std::string> kLabels = {"white",     "black",         "col bit 1", "col bit 1 inverse",
                                          "col bit 0", "col bit 0 inverse", "row bit 0", "row bit 0 inverse"};

std::vector<std::string> files(size_t n) {
  std::vector<std::string> f;
  for (size_t i = 0; i < n; ++i) {
    char name[40];
    std::snprintf(name, sizeof name, "/cap/graycode_%02zu.png", i);
    f.push_back(name);
  }
  return f;
}

TEST(FrameLayout, ProcamIsThePlanOrder) {
  auto a = assign_frames("procam", kLabels, files(8));
  ASSERT_TRUE(a.ok()) << a.status().to_string();
  EXPECT_EQ(a->frame_of_file, (std::vector<size_t>{0, 1, 2, 3, 4, 5, 6, 7}));
  EXPECT_EQ(a->white, -1);
  EXPECT_EQ(a->black, -1);
}

TEST(FrameLayout, OpencvGraycodePutsWhiteAndBlackLast) {
  auto a = assign_frames("opencv-graycode", kLabels, files(8));
  ASSERT_TRUE(a.ok()) << a.status().to_string();
  // file 0..5: the pairs in plan order; file 6 white (plan 0), file 7 black (plan 1).
  EXPECT_EQ(a->frame_of_file, (std::vector<size_t>{2, 3, 4, 5, 6, 7, 0, 1}));
  EXPECT_EQ(a->files, (std::vector<size_t>{0, 1, 2, 3, 4, 5, 6, 7}));
  EXPECT_EQ(a->white, -1);
  EXPECT_TRUE(a->pair_frames.empty());
}

TEST(FrameLayout, GuptaPairsSynthesizesWhiteAndBlack) {
  auto a = assign_frames("gupta-pairs", kLabels, files(6));
  ASSERT_TRUE(a.ok()) << a.status().to_string();
  EXPECT_EQ(a->frame_of_file, (std::vector<size_t>{2, 3, 4, 5, 6, 7}));
  EXPECT_EQ(a->white, 0);
  EXPECT_EQ(a->black, 1);
  EXPECT_EQ(a->pair_frames, (std::vector<size_t>{2, 3, 4, 5, 6, 7}));
}

TEST(FrameLayout, CountMismatchNamesTheFileAndTheFrame) {
  auto more = assign_frames("opencv-graycode", kLabels, files(9));
  ASSERT_FALSE(more.ok());
  EXPECT_NE(more.status().message().find("file graycode_08.png has no frame"), std::string::npos)
      << more.status().to_string();
  auto fewer = assign_frames("opencv-graycode", kLabels, files(7));
  ASSERT_FALSE(fewer.ok());
  EXPECT_NE(fewer.status().message().find("frame 1 'black' (file #7) is missing"), std::string::npos)
      << fewer.status().to_string();
  EXPECT_NE(fewer.status().hint().find("--rig"), std::string::npos);
  // A capture for a projector with one more column plane (9 pairs + 2)
  // against this 4x2 plan (2 column + 1 row planes): both counts named.
  auto wider = assign_frames("opencv-graycode", kLabels, files(2 * 4 + 2));
  ASSERT_FALSE(wider.ok());
  const std::string msg = wider.status().message();
  EXPECT_NE(msg.find("2 column + 1 row planes"), std::string::npos) << msg;
  EXPECT_NE(msg.find("3..4 columns wide"), std::string::npos) << msg;
  EXPECT_NE(msg.find("the capture holds 4 pairs"), std::string::npos) << msg;
}

TEST(FrameLayout, PairLayoutsNeedInverses) {
  const std::vector<std::string> white_mode = {"white", "black", "col bit 1", "col bit 0"};
  auto a = assign_frames("gupta-pairs", white_mode, files(2));
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.status().message().find("'col bit 1' is not followed by 'col bit 1 inverse'"), std::string::npos)
      << a.status().to_string();
}

TEST(FrameLayout, UnknownLayoutIsAClearError) {
  auto a = assign_frames("opencv", kLabels, files(8));
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.status().message().find("unknown layout 'opencv'"), std::string::npos);
}

struct TempFile {
  fs::path path = fs::temp_directory_path() / ("procam-layout-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + ".json");
  explicit TempFile(const std::string& text) { std::ofstream(path) << text; }
  ~TempFile() { fs::remove(path); }
};

TEST(FrameLayout, FileLayoutByGlobAndIndexWithSynthesizedBlack) {
  // No black file: synthesized from the pattern frames. Files out of order.
  TempFile f(R"([{"file": "*_05.png", "frame": "col bit 1"}, {"file": 4, "frame": "col bit 1 inverse"},
                 {"file": "*_03.png", "frame": "col bit 0"}, {"file": "*_02.png", "frame": "col bit 0 inverse"},
                 {"file": "*_01.png", "frame": "row bit 0"}, {"file": "*_00.png", "frame": "row bit 0 inverse"},
                 {"file": "*_06.png", "frame": "white"}])");
  auto a = assign_frames(f.path.string(), kLabels, files(7));
  ASSERT_TRUE(a.ok()) << a.status().to_string();
  // In plan order: white (file 6), col bit 1 (5), inv (4), col bit 0 (3), inv (2), row (1), inv (0).
  EXPECT_EQ(a->frame_of_file, (std::vector<size_t>{0, 2, 3, 4, 5, 6, 7}));
  EXPECT_EQ(a->files, (std::vector<size_t>{6, 5, 4, 3, 2, 1, 0}));
  EXPECT_EQ(a->white, -1);
  EXPECT_EQ(a->black, 1);
  EXPECT_EQ(a->pair_frames, (std::vector<size_t>{2, 3, 4, 5, 6, 7}));
}

TEST(FrameLayout, FileLayoutErrorsNameFileAndFrame) {
  TempFile missing(R"([{"file": "*_00.png", "frame": "col bit 1"}])");
  auto a = assign_frames(missing.path.string(), kLabels, files(8));
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.status().message().find("no file for plan frame 3 'col bit 1 inverse'"), std::string::npos)
      << a.status().to_string();
  TempFile ambiguous(R"([{"file": "graycode_0*.png", "frame": "col bit 1"}])");
  auto b = assign_frames(ambiguous.path.string(), kLabels, files(8));
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.status().message().find("matches both graycode_00.png and graycode_01.png"), std::string::npos)
      << b.status().to_string();
  TempFile bad_label(R"([{"file": 0, "frame": "col bit 7"}])");
  auto c = assign_frames(bad_label.path.string(), kLabels, files(8));
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.status().message().find("the plan has no frame 'col bit 7'"), std::string::npos);
}

}  // namespace
}  // namespace procam::engine
