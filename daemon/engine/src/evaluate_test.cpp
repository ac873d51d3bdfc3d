// SPDX-License-Identifier: MIT
// Evaluators chosen by a plugin's outputs (evaluate_outputs), on small maps
// whose errors are planted, so every expected number is counted by hand.
#include "procam/engine/evaluate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace procam::engine {
namespace {

constexpr uint32_t W = 10, H = 10;  // 100 pixels; the last column is unlit: 90 lit

hw::GroundTruth truth() {
  hw::GroundTruth t;
  t.depth_mm = Image(W, H, PixelType::f32);
  t.proj_col = Image(W, H, PixelType::f32);
  t.proj_row = Image(W, H, PixelType::f32);
  t.lit = Image(W, H, PixelType::u8);
  t.direct = Image(W, H, PixelType::f32);
  t.global = Image(W, H, PixelType::f32);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W; ++x) {
      const bool lit = x < W - 1;
      t.depth_mm.at<float>(x, y) = 800.0f;
      t.proj_col.at<float>(x, y) = lit ? 2.0f * float(x) : NAN;
      t.lit.at<uint8_t>(x, y) = lit ? 255 : 0;
      t.direct.at<float>(x, y) = lit ? 100.0f : 0.0f;
      t.global.at<float>(x, y) = 0.0f;  // a plane: no global light
    }
  return t;
}

// An F32 output viewing `pixels` (kept alive by the caller).
host::Output image_output(const std::string& name, const std::vector<float>& pixels) {
  host::Output o;
  o.name = name;
  o.kind = PROCAM_OUTPUT_IMAGE;
  o.image.width = W;
  o.image.height = H;
  o.image.channels = 1;
  o.image.pixel_type = PROCAM_PIXEL_F32;
  o.image.bit_depth = 32;
  o.image.stride_bytes = W * sizeof(float);
  o.image.data = pixels.data();
  return o;
}
host::Output scalar_output(const std::string& name, double v) {
  host::Output o;
  o.name = name;
  o.kind = PROCAM_OUTPUT_SCALAR;
  o.scalar = v;
  return o;
}

TEST(EvaluateOutputs, NothingToEvaluateForTheNullPluginsOutputs) {
  const auto j = evaluate_outputs({scalar_output("mean_dn", 42.0)}, truth());
  EXPECT_TRUE(j["evaluators"].empty());
  EXPECT_FALSE(j.contains("lit_pixels"));
}

TEST(EvaluateOutputs, CorrespondenceAtTheTopLevelAndDepthOnItsOwn) {
  const hw::GroundTruth t = truth();
  std::vector<float> col(W * H, NAN), depth(W * H, NAN);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W - 1; ++x) {
      col[y * W + x] = 2.0f * float(x);
      depth[y * W + x] = 802.0f;  // 2 mm too far
    }
  col[0] += 3.0f;        // one gross column error (its depth stays +2 mm)
  col[1] = NAN;          // one lit pixel not decoded...
  depth[1 * W + 4] = NAN;  // ...and one pixel without depth
  depth[2 * W + 4] = 796.0f;  // one 4 mm too near
  const auto j = evaluate_outputs({image_output("proj_col_px", col), image_output("depth_mm", depth)}, t);
  EXPECT_EQ(j["evaluators"], nlohmann::json({"correspondence", "depth"}));
  EXPECT_EQ(j["lit_pixels"], 90);
  EXPECT_NEAR(j["within_1col_fraction"].get<double>(), 88.0 / 90.0, 1e-12);
  EXPECT_NEAR(j["gross_error_fraction"].get<double>(), 1.0 / 89.0, 1e-12);
  // Depth on its own: 89 pixels with depth (90 lit - 1), whatever the columns.
  const auto& d = j["depth"];
  EXPECT_EQ(d["pixels"], 89);
  EXPECT_NEAR(d["decoded_fraction"].get<double>(), 89.0 / 90.0, 1e-12);
  EXPECT_NEAR(d["bias_mm"].get<double>(), (88 * 2.0 - 4.0) / 89.0, 1e-5);
  EXPECT_NEAR(d["rms_mm"].get<double>(), std::sqrt((88 * 4.0 + 16.0) / 89.0), 1e-5);
  EXPECT_NEAR(d["median_abs_mm"].get<double>(), 2.0, 1e-5);
  // Relative to the true depth (800 mm): 88 pixels 2/800, one 4/800.
  EXPECT_NEAR(d["median_rel_error"].get<double>(), 2.0 / 800.0, 1e-7);
  EXPECT_NEAR(d["rel_rms"].get<double>(), std::sqrt((88 * 4.0 + 16.0) / 89.0) / 800.0, 1e-7);
}

TEST(EvaluateOutputs, PerCodeAndSubpixelMapsGoUnderCodesAndSubpx) {
  const hw::GroundTruth t = truth();
  std::vector<float> exact(W * H, NAN), off(W * H, NAN);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W - 1; ++x) {
      exact[y * W + x] = 2.0f * float(x);
      off[y * W + x] = 2.0f * float(x) + 5.0f;  // every pixel gross
    }
  const auto j = evaluate_outputs({image_output("proj_col_px", exact), image_output("proj_col_px_gray", off),
                                   image_output("proj_col_subpx", exact)},
                                  t);
  EXPECT_NEAR(j["within_1col_fraction"].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(j["codes"]["gray"]["gross_error_fraction"].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(j["subpx"]["col_rms_px"].get<double>(), 0.0, 1e-12);
  EXPECT_FALSE(j.contains("depth"));
}

TEST(EvaluateOutputs, ComponentsAgainstDirectAndGlobalTruth) {
  const hw::GroundTruth t = truth();
  std::vector<float> direct(W * H, NAN), global(W * H, NAN);
  for (uint32_t y = 0; y < H; ++y)
    for (uint32_t x = 0; x < W - 1; ++x) {
      direct[y * W + x] = x < 3 ? 130.0f : 110.0f;  // 27 pixels 30 % high, 63 pixels 10 % high
      global[y * W + x] = 2.0f;
    }
  const auto j = evaluate_outputs({image_output("direct_dn", direct), image_output("global_dn", global)}, t);
  EXPECT_EQ(j["evaluators"], nlohmann::json({"components"}));
  const auto& d = j["components"]["direct"];
  EXPECT_EQ(d["pixels"], 90);
  EXPECT_NEAR(d["median_rel_error"].get<double>(), 0.10, 1e-6);
  EXPECT_NEAR(d["median_abs_error_dn"].get<double>(), 10.0, 1e-5);
  // No global light in the truth: nothing to divide by, the absolute error tells.
  const auto& g = j["components"]["global"];
  EXPECT_EQ(g["rel_pixels"], 0);
  EXPECT_TRUE(g["median_rel_error"].is_null());
  EXPECT_NEAR(g["median_abs_error_dn"].get<double>(), 2.0, 1e-6);
}

TEST(EvaluateOutputs, NoTruthIsReportedNotInvented) {
  hw::GroundTruth t = truth();
  t.direct = Image();
  t.global = Image();
  t.medium = {{"extinction_per_mm", 0.002}};
  std::vector<float> direct(W * H, 1.0f);
  const auto j = evaluate_outputs({image_output("direct_dn", direct), scalar_output("medium_extinction_per_mm", 0.0021),
                                   scalar_output("medium_albedo", 0.9)},
                                  t);
  EXPECT_EQ(j["evaluators"], nlohmann::json({"components", "medium"}));
  EXPECT_TRUE(j["components"]["direct"]["error"].get<std::string>().find("no truth for direct_dn") == 0);
  EXPECT_FALSE(j["components"]["direct"].contains("median_rel_error"));
  const auto& m = j["medium"];
  EXPECT_NEAR(m["medium_extinction_per_mm"]["rel_error"].get<double>(), 0.05, 1e-9);
  EXPECT_NEAR(m["medium_extinction_per_mm"]["abs_error"].get<double>(), 0.0001, 1e-12);
  EXPECT_EQ(m["medium_albedo"]["error"], "no truth for medium_albedo");
}

TEST(EvaluateOutputs, WrongSizedMapIsAnErrorNotANumber) {
  const hw::GroundTruth t = truth();
  std::vector<float> col(W * H, 0.0f);
  host::Output o = image_output("depth_mm", col);
  o.image.width = W - 1;
  o.image.stride_bytes = (W - 1) * sizeof(float);
  const auto j = evaluate_outputs({o}, t);
  EXPECT_TRUE(j["depth"].contains("error"));
  EXPECT_FALSE(j["depth"].contains("rms_mm"));
}

}  // namespace
}  // namespace procam::engine
