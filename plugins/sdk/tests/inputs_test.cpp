// SPDX-License-Identifier: MIT
// Tests of sdk::Inputs (procam/sdk/inputs.hpp): copying an F32 input map, the
// three errors (missing, not F32, wrong size) naming the input and how to
// supply it, non-finite values becoming NaN, row strides, and the
// describe() "inputs" key of sdk::MethodDescription.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/sdk/inputs.hpp"
#include "procam/sdk/method.hpp"

namespace sdk = procam::sdk;

namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

procam_output image_output(const char* name, const void* data, uint32_t w, uint32_t h,
                           procam_pixel_type type, size_t stride) {
  procam_output o{};
  o.name = name;
  o.kind = PROCAM_OUTPUT_IMAGE;
  o.unit = "mm";
  o.image.width = w;
  o.image.height = h;
  o.image.channels = 1;
  o.image.pixel_type = type;
  o.image.bit_depth = type == PROCAM_PIXEL_F32 ? 32 : 8;
  o.image.stride_bytes = stride;
  o.image.data = data;
  return o;
}

TEST(SdkInputs, CopiesRowsThroughAStrideAndMakesNonFiniteNaN) {
  // 3x2 map in rows of 4 floats (one padding float per row, value 99).
  const float inf = std::numeric_limits<float>::infinity();
  const float px[8] = {1.f, 2.f, -inf, 99.f, 4.f, NAN, 6.f, 99.f};
  const procam_output o = image_output("depth_mm", px, 3, 2, PROCAM_PIXEL_F32, 4 * sizeof(float));
  const sdk::Inputs in = sdk::Inputs::from_abi(&o, 1);
  ASSERT_TRUE(in.has("depth_mm"));
  EXPECT_FALSE(in.has("depth"));
  std::vector<float> out;
  ASSERT_TRUE(in.image_f32("depth_mm", 3, 2, out).ok());
  ASSERT_EQ(out.size(), 6u);
  EXPECT_EQ(out[0], 1.f);
  EXPECT_EQ(out[1], 2.f);
  EXPECT_TRUE(std::isnan(out[2]));  // -inf: invalid, as NaN
  EXPECT_EQ(out[3], 4.f);           // the padding float was skipped
  EXPECT_TRUE(std::isnan(out[4]));
  EXPECT_EQ(out[5], 6.f);
}

TEST(SdkInputs, ErrorsNameTheInputAndHowToSupplyIt) {
  const uint8_t bytes[4] = {1, 2, 3, 4};
  const float px[4] = {1, 2, 3, 4};
  const procam_output items[2] = {image_output("mask", bytes, 2, 2, PROCAM_PIXEL_U8, 2),
                                  image_output("depth_mm", px, 2, 2, PROCAM_PIXEL_F32, 8)};
  const sdk::Inputs in = sdk::Inputs::from_abi(items, 2);
  std::vector<float> out{7.f};

  sdk::Error missing = in.image_f32("ref_mm", 2, 2, out);
  EXPECT_EQ(missing.code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(missing.message, "input 'ref_mm' is missing")) << missing.message;
  EXPECT_TRUE(contains(missing.message, "--input ref_mm=")) << missing.message;
  EXPECT_TRUE(out.empty());

  sdk::Error kind = in.image_f32("mask", 2, 2, out);
  EXPECT_EQ(kind.code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(kind.message, "input 'mask' is not a 1-channel float (F32) image")) << kind.message;

  sdk::Error size = in.image_f32("depth_mm", 4, 2, out);
  EXPECT_EQ(size.code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_TRUE(contains(size.message, "input 'depth_mm' is 2x2, this method needs 4x2")) << size.message;
  EXPECT_TRUE(out.empty());

  // A short stride cannot hold a row: refused, never read past the rows.
  procam_output shortrow = image_output("depth_mm", px, 2, 2, PROCAM_PIXEL_F32, 4);
  sdk::Error stride = sdk::Inputs::from_abi(&shortrow, 1).image_f32("depth_mm", 2, 2, out);
  EXPECT_EQ(stride.code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_TRUE(sdk::Inputs::from_abi(nullptr, 0).empty());
}

TEST(SdkInputs, OwnedMapsForTestsSurviveCopies) {
  sdk::Inputs a;
  a.add_image_f32("depth_mm", 2, 1, {10.f, 20.f});
  a.add_image_f32("bad_mm", 2, 2, {1.f});  // wrong count: kept, but reported as malformed
  const sdk::Inputs b = a;  // shares the maps
  a = sdk::Inputs{};
  std::vector<float> out;
  ASSERT_TRUE(b.image_f32("depth_mm", 2, 1, out).ok());
  EXPECT_EQ(out, (std::vector<float>{10.f, 20.f}));
  EXPECT_FALSE(b.image_f32("bad_mm", 2, 2, out).ok());
  EXPECT_EQ(b.names(), (std::vector<std::string>{"depth_mm", "bad_mm"}));
}

TEST(SdkInputs, MethodDescriptionDeclaresInputs) {
  sdk::MethodDescription d;
  d.name = "calibrate";
  d.summary = "a method that takes a depth map";
  d.outputs = {"calibration_table"};
  EXPECT_FALSE(d.to_json().contains("inputs"));  // absent = takes none
  d.inputs = {{"depth_mm", "image_f32", "mm", true, "reference depth of a plane"}};
  const nlohmann::json j = d.to_json();
  ASSERT_TRUE(j["inputs"].is_array());
  ASSERT_EQ(j["inputs"].size(), 1u);
  EXPECT_EQ(j["inputs"][0],
            (nlohmann::json{{"name", "depth_mm"}, {"kind", "image_f32"}, {"unit", "mm"},
                            {"required", true}, {"description", "reference depth of a plane"}}));
  sdk::MethodDescription bad = d;
  bad.inputs[0].kind = "image_u8";
  EXPECT_THROW(bad.to_json(), std::invalid_argument);
  bad = d;
  bad.inputs[0].name = "Depth";
  EXPECT_THROW(bad.to_json(), std::invalid_argument);
  bad = d;
  bad.inputs.push_back(d.inputs[0]);
  EXPECT_THROW(bad.to_json(), std::invalid_argument);
}

}  // namespace
