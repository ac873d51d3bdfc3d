// SPDX-License-Identifier: MIT
// Unit tests for the engine: results files, previews, PLY, evaluation maths,
// rig description from a config.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "procam/core/image_io.hpp"
#include "procam/engine/evaluate.hpp"
#include "procam/engine/results.hpp"
#include "procam/engine/rig_json.hpp"

namespace procam::engine {
namespace {
namespace fs = std::filesystem;

class TempDir : public ::testing::Test {
protected:
  fs::path dir = fs::temp_directory_path() / ("procam_engine_test_" + std::to_string(::getpid()));
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
};

TEST_F(TempDir, PlyIsBinaryLittleEndianAndSkipsNonFinitePoints) {
  const float pts[] = {1, 2, 3, 0.5f, NAN, 0, 0, 1, 4, 5, 6, 1};
  uint64_t kept = 0;
  ASSERT_TRUE(write_ply((dir / "p.ply").string(), pts, 3, 4, "x,y,z,intensity", &kept).ok());
  EXPECT_EQ(kept, 2u);
  std::ifstream in(dir / "p.ply", std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(in)), {});
  const std::string end = "end_header\n";
  auto pos = all.find(end);
  ASSERT_NE(pos, std::string::npos);
  EXPECT_NE(all.find("element vertex 2\n"), std::string::npos);
  EXPECT_NE(all.find("property float intensity\n"), std::string::npos);
  EXPECT_NE(all.find("format binary_little_endian 1.0"), std::string::npos);
  const std::string body = all.substr(pos + end.size());
  ASSERT_EQ(body.size(), 2u * 4u * sizeof(float));
  float back[8];
  std::memcpy(back, body.data(), sizeof back);
  EXPECT_FLOAT_EQ(back[0], 1);
  EXPECT_FLOAT_EQ(back[4], 4);
  EXPECT_FLOAT_EQ(back[7], 1);
}

TEST(Preview, TurboEndsAndNanAreDistinct) {
  uint8_t lo[3], hi[3], mid[3];
  turbo(0.15, lo);
  turbo(1, hi);
  turbo(0.5, mid);
  // Turbo starts dark blue-violet, ends dark red, passes through green.
  EXPECT_GT(lo[2], lo[0]);
  EXPECT_GT(hi[0], hi[2]);
  EXPECT_GT(mid[1], 150);
  Image f(4, 1, PixelType::f32);
  f.at<float>(0, 0) = 1;
  f.at<float>(1, 0) = 2;
  f.at<float>(2, 0) = NAN;
  f.at<float>(3, 0) = 3;
  Image p = colormap_preview(f);
  EXPECT_EQ(p.channels(), 3u);
  EXPECT_EQ(p.at<uint8_t>(2, 0, 0) + p.at<uint8_t>(2, 0, 1) + p.at<uint8_t>(2, 0, 2), 0);
  EXPECT_NE(p.at<uint8_t>(0, 0, 2), p.at<uint8_t>(3, 0, 2));
}

TEST_F(TempDir, WriteOutputsMakesFilesPreviewsAndManifestEntries) {
  Image depth(3, 2, PixelType::f32);
  for (uint32_t i = 0; i < 6; ++i) depth.ptr<float>()[i] = 500.0f + float(i);
  depth.at<float>(1, 1) = NAN;
  Image col(3, 2, PixelType::f32);
  col.at<float>(0, 0) = 12.5f;
  col.at<float>(1, 0) = NAN;
  Image valid(3, 2, PixelType::u8);
  const float pts[] = {0, 0, 500};
  std::vector<host::Output> outs(5);
  outs[0].name = "depth_mm"; outs[0].kind = PROCAM_OUTPUT_IMAGE; outs[0].unit = "mm"; outs[0].image = depth.view();
  outs[1].name = "proj_col_px"; outs[1].kind = PROCAM_OUTPUT_IMAGE; outs[1].unit = "px"; outs[1].image = col.view();
  outs[2].name = "valid"; outs[2].kind = PROCAM_OUTPUT_IMAGE; outs[2].image = valid.view();
  outs[3].name = "points"; outs[3].kind = PROCAM_OUTPUT_POINTS; outs[3].points = pts; outs[3].point_count = 1; outs[3].point_stride = 3;
  outs[4].name = "decode_ms"; outs[4].kind = PROCAM_OUTPUT_SCALAR; outs[4].scalar = 1.5;
  auto w = write_outputs(dir.string(), outs);
  ASSERT_TRUE(w.ok()) << w.status().to_string();
  for (const char* f : {"depth_mm.exr", "depth_mm.preview.png", "proj_col_px.exr", "proj_col_px.png",
                        "proj_col_px.preview.png", "valid.png", "points.ply"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  auto d = read_image((dir / "depth_mm.exr").string());
  ASSERT_TRUE(d.ok());
  EXPECT_FLOAT_EQ(d->at<float>(2, 1), 505.0f);
  EXPECT_TRUE(std::isnan(d->at<float>(1, 1)));
  auto c16 = read_image((dir / "proj_col_px.png").string());
  ASSERT_TRUE(c16.ok());
  EXPECT_EQ(c16->at<uint16_t>(0, 0), 200);    // 12.5 px * 16
  EXPECT_EQ(c16->at<uint16_t>(1, 0), 65535);  // invalid
  EXPECT_EQ(w->outputs[4]["value"], 1.5);
  EXPECT_EQ(w->outputs[3]["count"], 1);
  EXPECT_EQ(w->previews.size(), 3u);  // depth, column, valid
  auto files = list_files(dir.string());
  EXPECT_EQ(files.size(), 7u);
}

hw::GroundTruth make_truth(uint32_t w, uint32_t h) {
  hw::GroundTruth t;
  t.depth_mm = Image(w, h, PixelType::f32);
  t.proj_col = Image(w, h, PixelType::f32);
  t.proj_row = Image(w, h, PixelType::f32);
  t.lit = Image(w, h, PixelType::u8);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      t.depth_mm.at<float>(x, y) = 800.0f;
      t.proj_col.at<float>(x, y) = float(x) * 1.5f + 0.2f;
      t.lit.at<uint8_t>(x, y) = x < w - 1 ? 255 : 0;  // last column in shadow
    }
  return t;
}

TEST(Evaluate, CountsWithinOneColumnGrossErrorsAndDepth) {
  auto t = make_truth(10, 10);  // 90 lit pixels
  Image col(10, 10, PixelType::f32), depth(10, 10, PixelType::f32);
  for (uint32_t y = 0; y < 10; ++y)
    for (uint32_t x = 0; x < 10; ++x) {
      col.at<float>(x, y) = t.lit.at<uint8_t>(x, y) ? std::round(t.proj_col.at<float>(x, y)) : NAN;  // exact decode
      depth.at<float>(x, y) = 801.0f;                                // 1 mm off
    }
  col.at<float>(0, 0) = NAN;       // one lit pixel not decoded
  col.at<float>(1, 0) += 5.0f;     // one gross error
  col.at<float>(9, 3) = 3.0f;      // decoded but not lit: spurious
  auto j = evaluate_correspondence(col, &depth, t);
  EXPECT_EQ(j["lit_pixels"], 90);
  EXPECT_NEAR(j["decoded_fraction"].get<double>(), 89.0 / 90.0, 1e-12);
  EXPECT_NEAR(j["within_1col_fraction"].get<double>(), 88.0 / 90.0, 1e-12);
  EXPECT_NEAR(j["gross_error_fraction"].get<double>(), 1.0 / 89.0, 1e-12);
  EXPECT_NEAR(j["spurious_fraction"].get<double>(), 1.0 / 90.0, 1e-12);  // 89 lit + 1 unlit decoded
  EXPECT_NEAR(j["depth_rms_mm"].get<double>(), 1.0, 1e-6);
  EXPECT_NEAR(j["depth_median_abs_mm"].get<double>(), 1.0, 1e-6);
  EXPECT_LE(j["col_rms_px"].get<double>(), 0.5);
}

TEST(RigJson, FromConfigNamesMissingField) {
  nlohmann::json cfg = {{"projector", {{"intrinsics", {{"width", 64}, {"height", 48}, {"fx", 100}, {"fy", 100}, {"cx", 31.5}, {"cy", 23.5}}}}},
                        {"cameras", {{{"intrinsics", {{"width", 32}, {"height", 24}, {"fx", 50}, {"fy", 50}, {"cx", 15.5}, {"cy", 11.5}}},
                                      {"cam_from_proj", {{"euler_deg", {0, 5, 0}}, {"translation_mm", {-100, 0, 0}}}},
                                      {"bit_depth", 12}}}}};
  auto j = plugin_rig_json_from_config(cfg, 3);
  ASSERT_TRUE(j.ok()) << j.status().to_string();
  EXPECT_EQ((*j)["projector"]["width"], 64);
  EXPECT_EQ((*j)["cameras"][0]["bit_depth"], 12);
  EXPECT_EQ((*j)["threads"], 3);
  EXPECT_DOUBLE_EQ((*j)["cameras"][0]["calibration"]["cam_from_proj"]["translation_mm"][0].get<double>(), -100.0);
  cfg["cameras"][0].erase("cam_from_proj");
  auto bad = plugin_rig_json_from_config(cfg, 1);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("cameras[0].cam_from_proj"), std::string::npos);
}

TEST_F(TempDir, AtomicWriteLeavesNoTemporaries) {
  ASSERT_TRUE(write_file_atomic((dir / "m.json").string(), "{\"a\":1}").ok());
  ASSERT_TRUE(write_file_atomic((dir / "m.json").string(), "{\"a\":2}").ok());
  auto j = read_json_file((dir / "m.json").string());
  ASSERT_TRUE(j.ok());
  EXPECT_EQ((*j)["a"], 2);
  size_t n = 0;
  for (auto& e : fs::directory_iterator(dir)) { (void)e; ++n; }
  EXPECT_EQ(n, 1u);
  EXPECT_FALSE(write_file_atomic((dir / "no/such/dir/m.json").string(), "x").ok());
}

}  // namespace
}  // namespace procam::engine
