// SPDX-License-Identifier: MIT
// The animated GIF of `procam sim --frames N` (animation.hpp): N frames that
// read back, with OpenImageIO's reader, as the 8-bit frames written (within
// one gray level: the GIF writer's palette quantisation), at the frame rate
// asked for; bad input refused with a Status.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "animation.hpp"

namespace procam::cli {
namespace {
namespace fs = std::filesystem;

fs::path temp_path(const std::string& name) {
  return fs::temp_directory_path() / ("procam_animation_test_" + std::to_string(::getpid()) + "_" + name);
}

// Frame k: a horizontal ramp shifted by 17 k (every 8-bit level appears).
Image ramp(uint32_t w, uint32_t h, int k, PixelType type, uint32_t bits) {
  Image im(w, h, type, 1, bits);
  const double max = im.max_value();
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const uint32_t g = (x + 3 * y + 17 * static_cast<uint32_t>(k)) % 256;  // the 8-bit level expected back
      if (type == PixelType::u8) im.at<uint8_t>(x, y) = static_cast<uint8_t>(g);
      else if (type == PixelType::u16) im.at<uint16_t>(x, y) = static_cast<uint16_t>(std::lround(g / 255.0 * max));
      else im.at<float>(x, y) = static_cast<float>(g / 255.0);
    }
  return im;
}

void expect_reads_back(const fs::path& p, uint32_t w, uint32_t h, int n, int fps_num, int fps_den) {
  auto in = OIIO::ImageInput::open(p.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  int count = 0;
  while (in->seek_subimage(count, 0)) ++count;
  EXPECT_EQ(count, n);
  std::vector<uint8_t> px;
  for (int k = 0; k < count; ++k) {
    ASSERT_TRUE(in->seek_subimage(k, 0));
    const OIIO::ImageSpec& s = in->spec();
    ASSERT_EQ(s.width, static_cast<int>(w));
    ASSERT_EQ(s.height, static_cast<int>(h));
    int rate[2] = {0, 0};
    ASSERT_TRUE(s.getattribute("FramesPerSecond", OIIO::TypeRational, rate));
    EXPECT_EQ(rate[0] * fps_den, rate[1] * fps_num) << rate[0] << "/" << rate[1];
    px.resize(size_t{w} * h * static_cast<size_t>(s.nchannels));
    ASSERT_TRUE(in->read_image(k, 0, 0, -1, OIIO::TypeDesc::UINT8, px.data()));
    size_t bad = 0;
    int worst = 0;
    for (uint32_t y = 0; y < h; ++y)
      for (uint32_t x = 0; x < w; ++x) {
        const uint8_t* q = &px[(size_t{y} * w + x) * static_cast<size_t>(s.nchannels)];
        const uint8_t g = static_cast<uint8_t>((x + 3 * y + 17 * static_cast<uint32_t>(k)) % 256);
        bad += (q[0] != q[1] || q[1] != q[2]);  // gray stays gray
        worst = std::max(worst, std::abs(int{q[0]} - int{g}));
      }
    EXPECT_EQ(bad, 0u) << "frame " << k;
    EXPECT_LE(worst, 1) << "frame " << k;  // the GIF palette (256 entries, quantised) is off by at most one level
  }
}

TEST(AnimatedGif, HasNFramesThatReadBackExactly) {
  const fs::path p = temp_path("u8.gif");
  std::vector<Image> frames;
  for (int k = 0; k < 7; ++k) frames.push_back(ramp(300, 20, k, PixelType::u8, 8));
  ASSERT_TRUE(write_animated_gif(p.string(), frames, 25.0).ok());
  expect_reads_back(p, 300, 20, 7, 25, 1);  // delay 4/100 s
  fs::remove(p);
}

TEST(AnimatedGif, DeepAndFloatFramesScaleTo8Bits) {
  for (auto [type, bits] : {std::pair{PixelType::u16, 12u}, {PixelType::u16, 16u}, {PixelType::f32, 0u}}) {
    const fs::path p = temp_path("deep.gif");
    std::vector<Image> frames;
    for (int k = 0; k < 3; ++k) frames.push_back(ramp(256, 4, k, type, bits));
    ASSERT_TRUE(write_animated_gif(p.string(), frames, 30.0).ok());
    expect_reads_back(p, 256, 4, 3, 100, 3);  // 30 fps -> delay 3/100 s
    fs::remove(p);
  }
  // NaN and out-of-range float pixels: black / clamped, never garbage.
  Image f(4, 1, PixelType::f32);
  f.at<float>(0, 0) = std::nanf("");
  f.at<float>(1, 0) = -2.f;
  f.at<float>(2, 0) = 7.f;
  f.at<float>(3, 0) = 0.5f;
  const fs::path p = temp_path("nan.gif");
  ASSERT_TRUE(write_animated_gif(p.string(), {f}, 10.0).ok());
  auto in = OIIO::ImageInput::open(p.string());
  ASSERT_TRUE(in);
  std::vector<uint8_t> px(4 * static_cast<size_t>(in->spec().nchannels));
  ASSERT_TRUE(in->read_image(0, 0, 0, -1, OIIO::TypeDesc::UINT8, px.data()));
  const size_t c = static_cast<size_t>(in->spec().nchannels);
  EXPECT_EQ(px[0], 0);
  EXPECT_EQ(px[c], 0);
  EXPECT_EQ(px[2 * c], 255);
  EXPECT_NEAR(px[3 * c], 128, 1);
  fs::remove(p);
}

TEST(AnimatedGif, BadInputIsRefused) {
  const fs::path p = temp_path("bad.gif");
  EXPECT_EQ(write_animated_gif(p.string(), {}, 10.0).code(), Code::failed_precondition);
  EXPECT_EQ(write_animated_gif(p.string(), {Image(4, 4, PixelType::u8)}, 0.0).code(), Code::invalid_argument);
  EXPECT_EQ(write_animated_gif(p.string(), {Image(4, 4, PixelType::u8)}, 101.0).code(), Code::invalid_argument);
  EXPECT_EQ(write_animated_gif(p.string(), {Image(4, 4, PixelType::u8), Image(4, 5, PixelType::u8)}, 10.0).code(),
            Code::invalid_argument);
  EXPECT_EQ(write_animated_gif(p.string(), {Image(4, 4, PixelType::u8, 3)}, 10.0).code(), Code::invalid_argument);
  const Status st = write_animated_gif("/nonexistent-dir/x.gif", {Image(4, 4, PixelType::u8)}, 10.0);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("x.gif"), std::string::npos) << st.to_string();
  fs::remove(p);
}

}  // namespace
}  // namespace procam::cli
