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
#include "procam/engine/previews.hpp"
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

// A float map's preview keeps the map's pixels and adds a colour bar below
// that runs from Turbo(0) on the left to Turbo(1) on the right.
TEST(Preview, ScalarMapHasTheMapAndAColourBarBelow) {
  Image f(200, 50, PixelType::f32);
  for (uint32_t y = 0; y < 50; ++y)
    for (uint32_t x = 0; x < 200; ++x) f.at<float>(x, y) = 500.0f + static_cast<float>(x);
  f.at<float>(3, 3) = NAN;
  const Image map = colormap_preview(f);
  const Image p = scalar_map_preview(f, "mm", "depth_mm");
  ASSERT_EQ(p.width(), 200u);
  ASSERT_GT(p.height(), 50u + 20u);  // bar and labels
  for (uint32_t y = 0; y < 50; ++y)
    for (uint32_t x = 0; x < 200; ++x)
      for (uint32_t c = 0; c < 3; ++c) ASSERT_EQ(p.at<uint8_t>(x, y, c), map.at<uint8_t>(x, y, c)) << x << "," << y;
  // Find the bar: the first row below the map whose middle pixel is not white.
  uint32_t bar = 0;
  for (uint32_t y = 50; y < p.height() && bar == 0; ++y) {
    const uint32_t x = 100;
    if (p.at<uint8_t>(x, y, 0) + p.at<uint8_t>(x, y, 1) + p.at<uint8_t>(x, y, 2) < 3 * 250 &&
        p.at<uint8_t>(8, y, 0) + p.at<uint8_t>(8, y, 1) + p.at<uint8_t>(8, y, 2) < 3 * 250 &&
        p.at<uint8_t>(190, y, 0) + p.at<uint8_t>(190, y, 1) + p.at<uint8_t>(190, y, 2) < 3 * 250)
      bar = y;
  }
  ASSERT_GT(bar, 50u) << "no colour bar under the map";
  uint8_t left[3], right[3];
  turbo(0.0, left);
  turbo(1.0, right);
  for (uint32_t c = 0; c < 3; ++c) {
    EXPECT_NEAR(p.at<uint8_t>(6, bar + 2, c), left[c], 12) << c;
    EXPECT_NEAR(p.at<uint8_t>(193, bar + 2, c), right[c], 12) << c;
  }
  // No valid pixel: still an image, the same width, no crash.
  Image empty(10, 4, PixelType::f32);
  for (size_t i = 0; i < empty.pixel_count(); ++i) empty.ptr<float>()[i] = NAN;
  EXPECT_EQ(scalar_map_preview(empty, "mm", "x").width(), 10u);
}

// A class map's raw values (0..5) look black; its preview colours each class
// and puts a key beside it.
TEST(Preview, ClassMapIsColouredWithAKey) {
  Image m(60, 40, PixelType::u8);
  for (uint32_t y = 0; y < 40; ++y)
    for (uint32_t x = 0; x < 60; ++x) m.at<uint8_t>(x, y) = static_cast<uint8_t>(x / 20);  // classes 0, 1, 2
  const auto legend = parse_class_legend(nlohmann::json::parse(
      R"({"classes":[{"value":0,"name":"unlit"},{"value":1,"name":"all_agree"},{"value":2,"name":"interreflection"},
                     {"value":"x"},{"value":300,"name":"bad"}]})"));
  ASSERT_EQ(legend.size(), 3u);  // the malformed entries are skipped
  EXPECT_EQ(legend[2].name, "interreflection");
  const Image p = class_map_preview(m, legend, "transport_class");
  ASSERT_GT(p.width(), 60u);  // key to the right
  for (uint32_t x : {5u, 25u, 45u}) {
    uint8_t rgb[3];
    class_color(static_cast<int>(x / 20), rgb);
    for (uint32_t c = 0; c < 3; ++c) EXPECT_EQ(p.at<uint8_t>(x, 10, c), rgb[c]) << x;
  }
  uint8_t c1[3], c2[3];
  class_color(1, c1);
  class_color(2, c2);
  EXPECT_NE(std::vector<uint8_t>(c1, c1 + 3), std::vector<uint8_t>(c2, c2 + 3));
  // Each class's swatch appears in the key.
  auto key_has = [&](const uint8_t rgb[3]) {
    for (uint32_t y = 0; y < p.height(); ++y)
      for (uint32_t x = 61; x < p.width(); ++x)
        if (p.at<uint8_t>(x, y, 0) == rgb[0] && p.at<uint8_t>(x, y, 1) == rgb[1] && p.at<uint8_t>(x, y, 2) == rgb[2])
          return true;
    return false;
  };
  EXPECT_TRUE(key_has(c1));
  EXPECT_TRUE(key_has(c2));
  EXPECT_TRUE(parse_class_legend(nlohmann::json()).empty());
  EXPECT_TRUE(parse_class_legend(nlohmann::json::parse(R"({"classes":7})")).empty());
}

TEST_F(TempDir, ClassMapWithLegendGetsAColouredPreview) {
  Image cls(4, 2, PixelType::u8);
  cls.at<uint8_t>(1, 0) = 3;
  std::vector<host::Output> outs(2);
  outs[0].name = "transport_class"; outs[0].kind = PROCAM_OUTPUT_IMAGE; outs[0].unit = "class"; outs[0].image = cls.view();
  const std::string legend = R"({"classes":[{"value":3,"name":"subsurface"}]})";
  outs[1].name = "transport_class_legend"; outs[1].kind = PROCAM_OUTPUT_JSON; outs[1].json = legend;
  auto w = write_outputs(dir.string(), outs);
  ASSERT_TRUE(w.ok()) << w.status().to_string();
  EXPECT_TRUE(fs::exists(dir / "transport_class.png"));  // raw values for tools
  ASSERT_TRUE(fs::exists(dir / "transport_class.preview.png"));
  ASSERT_EQ(w->previews.size(), 1u);
  EXPECT_EQ(w->previews[0]["file"], "transport_class.preview.png");
  // (read_image gives grey; the colours themselves are checked in memory by
  // Preview.ClassMapIsColouredWithAKey.) The file is the map plus its key.
  auto p = read_image((dir / "transport_class.preview.png").string());
  ASSERT_TRUE(p.ok());
  EXPECT_GT(p->width(), 4u);
  EXPECT_GE(p->height(), 2u);
  const Image expect = class_map_preview(cls, parse_class_legend(nlohmann::json::parse(legend)), "transport_class");
  EXPECT_EQ(p->width(), expect.width());
  EXPECT_EQ(p->height(), expect.height());
}

TEST_F(TempDir, ScanReportShowsWhatWasRunTheNumbersAndTheMaps) {
  const nlohmann::json m = nlohmann::json::parse(R"({
    "scan_id": "20261122-000000-abcdef", "state": "done", "plugin": "structured-light", "method": "gray",
    "label": "<script>", "params": {"bits": 10},
    "plan": {"patterns": 24, "rounds": [{"frames": 24, "note": "Gray code"}]},
    "timing_ms": {"capture": 400.5, "decode": 12.25},
    "evaluation": {"within_1col_fraction": 0.9981, "lit_pixels": 1000},
    "outputs": [{"name": "decode_ms", "kind": "scalar", "value": 12.25, "unit": "ms", "description": "decode time"},
                {"name": "depth_mm", "kind": "image", "description": "z of the point"},
                {"name": "report", "kind": "json", "value": {"method": "gray"}}],
    "previews": [{"of": "depth_mm", "file": "depth_mm.preview.png"}]})");
  ASSERT_TRUE(write_scan_report(dir.string(), m).ok());
  std::ifstream in(dir / "report.html");
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const char* want : {"20261122-000000-abcdef", "structured-light / gray", "24 in 1 round(s)", "0.9981",
                           "within_1col_fraction", "decode_ms", "12.25", "<img src=\"depth_mm.preview.png\"",
                           "z of the point", "&lt;script&gt;", "&quot;method&quot;"})
    EXPECT_NE(html.find(want), std::string::npos) << want;
  EXPECT_EQ(html.find("<script>"), std::string::npos);  // client text is escaped
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
