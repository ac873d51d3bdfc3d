// SPDX-License-Identifier: MIT
// The null plugin's sessions and mean, against values known in closed form.
#include "null_session.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace procam::null_plugin {
namespace {

const nlohmann::json kRig = {{"projector", {{"width", 64}, {"height", 40}}},
                             {"cameras", {{{"width", 48}, {"height", 30}, {"bit_depth", 12}}}}};

std::unique_ptr<sdk::Session> make(const std::string& method, nlohmann::json params = nlohmann::json::object(),
                                   nlohmann::json rig = kRig) {
  sdk::CreateArgs args{method, std::move(params), std::move(rig)};
  std::unique_ptr<sdk::Session> s;
  sdk::Error e = create_session(args, s);
  EXPECT_TRUE(e.ok()) << e.message;
  return s;
}

// Mean of a ramp v(x, y) = x over a width-W frame is (W - 1) / 2, whatever the
// height: the padding bytes after each row (NaN / 0xFF) must not count.
TEST(NullMean, RampInEveryPixelTypeWithPaddedRows) {
  const uint32_t w = 10, h = 3;
  std::vector<uint8_t> u8(size_t{w + 6} * h, 0xFF);
  std::vector<uint16_t> u16(size_t{w + 2} * h, 0xFFFF);
  std::vector<float> f32(size_t{w + 1} * h, std::numeric_limits<float>::quiet_NaN());
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      u8[y * (w + 6) + x] = static_cast<uint8_t>(x);
      u16[y * (w + 2) + x] = static_cast<uint16_t>(x * 400);  // 12-bit values up to 3600
      f32[y * (w + 1) + x] = 0.1f * static_cast<float>(x);
    }
  procam_image a = sdk::gray_view(u8.data(), w, h);
  a.stride_bytes = w + 6;
  procam_image b = sdk::gray_view(u16.data(), w, h, 12);
  b.stride_bytes = size_t{w + 2} * 2;
  procam_image c = sdk::gray_view(f32.data(), w, h);
  c.stride_bytes = size_t{w + 1} * 4;
  EXPECT_DOUBLE_EQ(mean_value(a), 4.5);
  EXPECT_DOUBLE_EQ(mean_value(b), 4.5 * 400);
  EXPECT_NEAR(mean_value(c), 0.45, 1e-7);
}

TEST(NullSession, PlansOneWhiteProjectorSizedFrameThenStops) {
  auto s = make("null");
  ASSERT_TRUE(s);
  sdk::Plan plan;
  bool has = false;
  ASSERT_TRUE(s->next_plan(plan, has).ok());
  ASSERT_TRUE(has);
  ASSERT_EQ(plan.size(), 1u);
  EXPECT_EQ(plan.pattern(0).width, 64u);
  EXPECT_EQ(plan.pattern(0).height, 40u);
  for (uint8_t v : plan.pattern_u8(0)) ASSERT_EQ(v, 255);
  std::vector<uint16_t> frame(48 * 30, 1000);
  ASSERT_TRUE(s->add_frame(0, sdk::gray_view(frame.data(), 48, 30, 12)).ok());
  ASSERT_TRUE(s->end_round().ok());
  sdk::Plan again;
  has = false;
  ASSERT_TRUE(s->next_plan(again, has).ok());
  EXPECT_FALSE(has) << "one round only";
  sdk::Outputs out;
  ASSERT_TRUE(s->outputs(out).ok());
  ASSERT_EQ(out.size(), 1u);
  const procam_output& o = out.view()[0];
  EXPECT_STREQ(o.name, "mean_dn");
  EXPECT_STREQ(o.unit, "DN");
  EXPECT_EQ(o.kind, PROCAM_OUTPUT_SCALAR);
  EXPECT_DOUBLE_EQ(o.scalar, 1000.0);
}

TEST(NullSession, WrongSizedFrameIsBadFrameAndNotCounted) {
  auto s = make("null");
  sdk::Plan plan;
  bool has = false;
  ASSERT_TRUE(s->next_plan(plan, has).ok());
  std::vector<uint16_t> small(47 * 30, 7);
  EXPECT_EQ(s->add_frame(0, sdk::gray_view(small.data(), 47, 30, 12)).code, PROCAM_ERR_BAD_FRAME);
  std::vector<uint16_t> right(48 * 30, 7);
  ASSERT_TRUE(s->add_frame(0, sdk::gray_view(right.data(), 48, 30, 12)).ok());
  ASSERT_TRUE(s->end_round().ok());
  sdk::Outputs out;
  ASSERT_TRUE(s->outputs(out).ok());
  EXPECT_DOUBLE_EQ(out.view()[0].scalar, 7.0) << "the rejected frame must not have been used";
}

TEST(EchoSession, ReturnsTheFrameAsFloatDigitalNumbers) {
  auto s = make("echo");
  sdk::Plan plan;
  bool has = false;
  ASSERT_TRUE(s->next_plan(plan, has).ok());
  std::vector<uint16_t> frame(48 * 30);
  for (size_t i = 0; i < frame.size(); ++i) frame[i] = static_cast<uint16_t>(i % 4096);
  ASSERT_TRUE(s->add_frame(0, sdk::gray_view(frame.data(), 48, 30, 12)).ok());
  ASSERT_TRUE(s->end_round().ok());
  sdk::Outputs out;
  ASSERT_TRUE(s->outputs(out).ok());
  ASSERT_EQ(out.size(), 2u);
  const procam_output* o = out.view();
  const procam_output& img = std::strcmp(o[0].name, "frame_dn") == 0 ? o[0] : o[1];
  ASSERT_STREQ(img.name, "frame_dn");
  ASSERT_EQ(img.image.pixel_type, PROCAM_PIXEL_F32);
  ASSERT_EQ(img.image.width, 48u);
  const float* px = static_cast<const float*>(img.image.data);
  for (size_t i = 0; i < frame.size(); ++i) ASSERT_EQ(px[i], static_cast<float>(i % 4096)) << i;
}

TEST(NullSession, RejectsParamsAndRigsItCannotUse) {
  std::unique_ptr<sdk::Session> s;
  EXPECT_EQ(create_session({"null", {{"bits", 3}}, kRig}, s).code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(create_session({"null", nlohmann::json::object(), nlohmann::json()}, s).code,
            PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_FALSE(s);
}

TEST(NullDescribe, ListsBothMethodsWithIntegerPatternCounts) {
  const nlohmann::json d = describe_methods();
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0]["name"], "null");
  EXPECT_EQ(d[1]["name"], "echo");
  for (const auto& m : d) {
    EXPECT_EQ(m["patterns"], 1);
    EXPECT_TRUE(m["params"].is_array() && m["params"].empty());
  }
}

}  // namespace
}  // namespace procam::null_plugin
