// SPDX-License-Identifier: MIT
// Tests of the plan layout: frame counts, order and labels as documented in
// plugins/structured-light/README.md, pattern pixels against the Gray code
// computed here independently (g = c xor c>>1), default frame settings.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "gray_code.hpp"
#include "plan_layout.hpp"

namespace procam::sl {
namespace {

uint32_t ref_gray_bit(uint32_t c, uint32_t position) { return ((c ^ (c >> 1)) >> position) & 1u; }

TEST(PlanLayout, FrameCounts) {
  const StripeCode cols = make_gray_code(1280), rows = make_gray_code(800);
  EXPECT_EQ(make_layout(cols, nullptr, true).frames.size(), 2u + 2u * 11u);
  EXPECT_EQ(make_layout(cols, nullptr, false).frames.size(), 2u + 11u);
  EXPECT_EQ(make_layout(cols, &rows, true).frames.size(), 2u + 2u * 11u + 2u * 10u);
  EXPECT_EQ(make_layout(cols, &rows, false).frames.size(), 2u + 11u + 10u);
  const StripeCode one = make_gray_code(1);
  EXPECT_EQ(make_layout(one, nullptr, true).frames.size(), 4u);
}

TEST(PlanLayout, LabelsAndOrderInverse) {
  const StripeCode cols = make_gray_code(1280), rows = make_gray_code(800);
  const Layout l = make_layout(cols, &rows, true);
  std::vector<std::string> expected = {"white", "black"};
  for (int k = 10; k >= 0; --k) {
    expected.push_back("col bit " + std::to_string(k));
    expected.push_back("col bit " + std::to_string(k) + " inverse");
  }
  for (int k = 9; k >= 0; --k) {
    expected.push_back("row bit " + std::to_string(k));
    expected.push_back("row bit " + std::to_string(k) + " inverse");
  }
  ASSERT_EQ(l.frames.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(l.frames[i].label, expected[i]) << i;
  // Partners point at each other.
  for (size_t i = 2; i < l.frames.size(); ++i) {
    const auto p = static_cast<size_t>(l.frames[i].partner);
    ASSERT_LT(p, l.frames.size());
    EXPECT_EQ(static_cast<size_t>(l.frames[p].partner), i);
  }
}

TEST(PlanLayout, LabelsAndOrderWhite) {
  const StripeCode cols = make_gray_code(5);
  const Layout l = make_layout(cols, nullptr, false);
  const std::vector<std::string> expected = {"white", "black", "col bit 2", "col bit 1",
                                             "col bit 0"};
  ASSERT_EQ(l.frames.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(l.frames[i].label, expected[i]);
  for (const FrameRole& r : l.frames) EXPECT_EQ(r.partner, -1);
}

TEST(PlanLayout, PatternPixelsMatchGrayCode) {
  const uint32_t W = 1000, H = 37;
  const StripeCode cols = make_gray_code(W), rows = make_gray_code(H);
  const Layout l = make_layout(cols, &rows, true);
  sdk::Plan plan;
  render_plan(l, cols, &rows, W, H, plan);
  ASSERT_EQ(plan.size(), l.frames.size());
  const procam_plan* view = plan.view();
  ASSERT_EQ(view->frame_count, l.frames.size());
  for (uint32_t i = 0; i < view->frame_count; ++i) {
    const procam_pattern_frame& f = view->frames[i];
    EXPECT_STREQ(f.label, l.frames[i].label.c_str());
    ASSERT_EQ(f.pattern.width, W);
    ASSERT_EQ(f.pattern.height, H);
    ASSERT_EQ(f.pattern.pixel_type, static_cast<uint32_t>(PROCAM_PIXEL_U8));
    ASSERT_EQ(f.pattern.channels, 1u);
    ASSERT_EQ(f.pattern.stride_bytes, W);
    const auto* px = static_cast<const uint8_t*>(f.pattern.data);
    const std::string label = f.label;
    const bool inverse = label.find("inverse") != std::string::npos;
    for (uint32_t y = 0; y < H; ++y) {
      for (uint32_t x = 0; x < W; ++x) {
        uint32_t lit;
        if (label == "white") {
          lit = 1;
        } else if (label == "black") {
          lit = 0;
        } else {
          // "col bit k" / "row bit k": parse k from the label itself.
          const uint32_t k = static_cast<uint32_t>(std::stoul(label.substr(8)));
          lit = ref_gray_bit(label[0] == 'c' ? x : y, k);
          if (inverse) lit = 1 - lit;
        }
        ASSERT_EQ(px[size_t{y} * W + x], lit ? 255 : 0) << label << " at " << x << "," << y;
      }
    }
    // Every frame keeps the rig's settings.
    EXPECT_EQ(f.settings.struct_size, sizeof(procam_frame_settings));
    EXPECT_EQ(f.settings.camera_index, 0);
    EXPECT_EQ(f.settings.exposure_us, 0.0);
    EXPECT_LT(f.settings.gain_db, 0.0);
    EXPECT_EQ(f.settings.projector_focus_mm, 0.0);
    EXPECT_TRUE(std::isnan(f.settings.polarizer_deg));
    EXPECT_TRUE(std::isnan(f.settings.projector_polarizer_deg));
  }
}

TEST(PlanLayout, RejectsMismatchedProjectorSize) {
  const StripeCode cols = make_gray_code(100);
  sdk::Plan plan;
  EXPECT_THROW(render_plan(make_layout(cols, nullptr, true), cols, nullptr, 99, 10, plan),
               std::invalid_argument);
}

}  // namespace
}  // namespace procam::sl
