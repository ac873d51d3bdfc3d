// SPDX-License-Identifier: MIT
// Unit tests for procam_core: Status/Result, logging spec, Image, image files,
// geometry and column triangulation.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "procam/base/calibration.hpp"
#include "procam/core/image.hpp"
#include "procam/core/image_io.hpp"
#include "procam/core/log.hpp"
#include "procam/core/status.hpp"

namespace procam {
namespace {

Result<int> half(int x) {
  if (x % 2) return Error(Code::invalid_argument, "odd", "pass an even number");
  return x / 2;
}
Status twice_half(int x, int& out) {
  auto r = half(x);
  PROCAM_TRY(r);
  out = *r;
  return Status::Ok();
}

TEST(Status, CarriesCodeMessageHint) {
  auto r = half(3);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument);
  EXPECT_EQ(r.status().to_string(), "invalid_argument: odd (hint: pass an even number)");
  int out = 0;
  EXPECT_FALSE(twice_half(5, out).ok());
  EXPECT_TRUE(twice_half(8, out).ok());
  EXPECT_EQ(out, 4);
  EXPECT_EQ(r.status().with_context("parsing").message(), "parsing: odd");
}

TEST(Log, ConfigureSpec) {
  EXPECT_TRUE(log::configure("warn,daemon=debug"));
  EXPECT_TRUE(log::enabled("daemon", log::Level::debug));
  EXPECT_FALSE(log::enabled("sim", log::Level::info));
  EXPECT_TRUE(log::enabled("sim", log::Level::error));
  EXPECT_FALSE(log::configure("loud"));  // unknown level rejected, unchanged
  EXPECT_TRUE(log::enabled("daemon", log::Level::debug));
  EXPECT_FALSE(log::configure("=info"));
  EXPECT_TRUE(log::configure("info"));
}

// Client and plugin text reaches log lines; it must not split or forge them.
TEST(Log, EscapeKeepsOneValidUtf8Line) {
  using procam::log::escape;
  EXPECT_EQ(escape("plain text"), "plain text");
  EXPECT_EQ(escape("a\nb\r\tc"), "a\\nb\\r\\tc");                    // no line breaks survive
  EXPECT_EQ(escape(std::string("x\0y", 3)), "x\\x00y");                   // NUL
  EXPECT_EQ(escape("\x1b[31m"), "\\x1b[31m");                             // terminal escape
  EXPECT_EQ(escape("\x7f"), "\\x7f");                                     // DEL
  EXPECT_EQ(escape("back\\slash"), "back\\\\slash");                   // escapes stay unambiguous
  EXPECT_EQ(escape("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80"),
            "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");                   // valid UTF-8 passes
  EXPECT_EQ(escape("\xc3"), "\\xc3");                                     // truncated sequence
  EXPECT_EQ(escape("\xc0\xaf"), "\\xc0\\xaf");                         // overlong '/'
  EXPECT_EQ(escape("\xed\xa0\x80"), "\\xed\\xa0\\x80");             // UTF-16 surrogate
  EXPECT_EQ(escape("\xf4\x90\x80\x80"), "\\xf4\\x90\\x80\\x80"); // past U+10FFFF
  EXPECT_EQ(escape("\xef\xbb\xbfid"), "\xef\xbb\xbfid");               // a BOM is valid UTF-8 text
  const std::string all = [] {
    std::string b;
    for (int c = 0; c < 256; ++c) b += static_cast<char>(c);
    return b;
  }();
  const std::string e = escape(all);
  for (char c : e) EXPECT_FALSE(c == '\n' || c == '\r' || static_cast<unsigned char>(c) < 0x20);
}

TEST(Image, ViewRoundTripAndValidation) {
  Image img(5, 3, PixelType::u16, 1, 12);
  img.at<uint16_t>(4, 2) = 4095;
  EXPECT_DOUBLE_EQ(img.max_value(), 4095.0);
  procam_image v = img.view();
  EXPECT_EQ(validate_view(v), nullptr);
  Image copy = Image::copy_of(v);
  EXPECT_EQ(copy.at<uint16_t>(4, 2), 4095);
  EXPECT_EQ(copy.bit_depth(), 12u);
  v.stride_bytes = 2;  // smaller than a row
  EXPECT_NE(validate_view(v), nullptr);
  EXPECT_TRUE(Image::copy_of(v).empty());
  v = img.view();
  v.pixel_type = 99;
  EXPECT_NE(validate_view(v), nullptr);
  v = img.view();
  v.bit_depth = 17;
  EXPECT_NE(validate_view(v), nullptr);
}

class ImageFiles : public ::testing::Test {
protected:
  std::filesystem::path dir = std::filesystem::temp_directory_path() /
                              ("procam_core_test_" + std::to_string(::getpid()));
  void SetUp() override { std::filesystem::create_directories(dir); }
  void TearDown() override { std::filesystem::remove_all(dir); }
};

TEST_F(ImageFiles, Png16AndExrRoundTripExactly) {
  Image u16(7, 4, PixelType::u16);
  for (uint32_t y = 0; y < 4; ++y)
    for (uint32_t x = 0; x < 7; ++x) u16.at<uint16_t>(x, y) = static_cast<uint16_t>(x * 9000 + y);
  ASSERT_TRUE(write_image((dir / "a.png").string(), u16).ok());
  auto back = read_image((dir / "a.png").string());
  ASSERT_TRUE(back.ok()) << back.status().to_string();
  EXPECT_EQ(back->type(), PixelType::u16);
  for (uint32_t x = 0; x < 7; ++x) EXPECT_EQ(back->at<uint16_t>(x, 3), u16.at<uint16_t>(x, 3));

  Image f(3, 2, PixelType::f32);
  f.at<float>(0, 0) = 123.25f;
  f.at<float>(2, 1) = NAN;
  ASSERT_TRUE(write_image((dir / "d.exr").string(), f, {{"procam:unit", "mm"}}).ok());
  auto fb = read_image((dir / "d.exr").string());
  ASSERT_TRUE(fb.ok());
  EXPECT_FLOAT_EQ(fb->at<float>(0, 0), 123.25f);
  EXPECT_TRUE(std::isnan(fb->at<float>(2, 1)));
  // No temporary files left behind by the atomic write.
  size_t n = 0;
  for (auto& e : std::filesystem::directory_iterator(dir)) { (void)e; ++n; }
  EXPECT_EQ(n, 2u);
}

// A 12-bit camera frame saved as PNG (16-bit samples holding 0..4095, as
// save_frames records it) reads back as 12-bit with its values unchanged: a
// plugin scales by 2^bit_depth - 1, and a frame read back as 16-bit would
// look 16x too dark offline. PNG has no 12-bit samples, so the depth travels
// in a text chunk (procam:bit_depth). Also for 10 and 14 bits.
TEST_F(ImageFiles, SubSixteenBitPngKeepsItsBitDepth) {
  for (uint32_t bits : {10u, 12u, 14u}) {
    Image img(5, 3, PixelType::u16, 1, bits);
    const uint16_t top = static_cast<uint16_t>((1u << bits) - 1u);
    for (uint32_t y = 0; y < 3; ++y)
      for (uint32_t x = 0; x < 5; ++x) img.at<uint16_t>(x, y) = static_cast<uint16_t>((x * 997 + y * 31) % (top + 1u));
    img.at<uint16_t>(4, 2) = top;
    const std::string path = (dir / ("b" + std::to_string(bits) + ".png")).string();
    ASSERT_TRUE(write_image(path, img).ok());
    auto back = read_image(path);
    ASSERT_TRUE(back.ok()) << back.status().to_string();
    EXPECT_EQ(back->type(), PixelType::u16);
    EXPECT_EQ(back->bit_depth(), bits);
    for (uint32_t y = 0; y < 3; ++y)
      for (uint32_t x = 0; x < 5; ++x) ASSERT_EQ(back->at<uint16_t>(x, y), img.at<uint16_t>(x, y)) << bits;
  }
}

TEST_F(ImageFiles, ColourIsConvertedToGreyAndErrorsAreClear) {
  Image rgb(2, 1, PixelType::u8, 3);
  rgb.at<uint8_t>(0, 0, 0) = 255;  // red
  rgb.at<uint8_t>(1, 0, 1) = 255;  // green
  ASSERT_TRUE(write_image((dir / "c.png").string(), rgb).ok());
  auto g = read_image((dir / "c.png").string());
  ASSERT_TRUE(g.ok());
  EXPECT_EQ(g->channels(), 1u);
  EXPECT_EQ(g->at<uint8_t>(0, 0), 76);   // 0.299 * 255
  EXPECT_EQ(g->at<uint8_t>(1, 0), 150);  // 0.587 * 255

  auto missing = read_image((dir / "nope.png").string());
  EXPECT_EQ(missing.status().code(), Code::not_found);
  std::ofstream((dir / "bad.png").string()) << "not a png at all";
  auto bad = read_image((dir / "bad.png").string());
  EXPECT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("bad.png"), std::string::npos);
  EXPECT_FALSE(write_image((dir / "f.png").string(), Image(2, 2, PixelType::f32)).ok());
}

TEST(Geometry, TriangulateColumnRecoversKnownPoint) {
  CameraCalibration cam;
  cam.intrinsics = {640, 480, 600, 600, 319.5, 239.5};
  Intrinsics proj{800, 600, 900, 900, 399.5, 299.5};
  // Projector 100 mm to the right of the camera, turned 8 degrees towards it.
  Rigid3 proj_from_cam{rotation_from_euler_deg(0, -8, 0), {0, 0, 0}};
  proj_from_cam.translation_mm = -(proj_from_cam.rotation * Vec3{100, 0, 0});
  cam.cam_from_proj = proj_from_cam.inverse();
  const Vec3 X{25, -13, 700};
  double u, v, pc, pr;
  cam.intrinsics.project(X, u, v);
  proj.project(proj_from_cam * X, pc, pr);
  auto got = triangulate_column(cam, proj, u, v, pc);
  ASSERT_TRUE(got.has_value());
  EXPECT_NEAR(got->x, X.x, 1e-6);
  EXPECT_NEAR(got->y, X.y, 1e-6);
  EXPECT_NEAR(got->z, X.z, 1e-6);
  // JSON round trip of the calibration.
  nlohmann::json j = cam;
  auto back = j.get<CameraCalibration>();
  EXPECT_DOUBLE_EQ(back.cam_from_proj.translation_mm.x, cam.cam_from_proj.translation_mm.x);
  EXPECT_DOUBLE_EQ(back.intrinsics.cx, 319.5);
}

}  // namespace
}  // namespace procam
