// SPDX-License-Identifier: MIT
// Plugin ABI 2 (plugin_abi.h "Scan inputs", "Version history"): ABI 1 plugins
// of both table sizes still load and run in an ABI 2 host and are never
// handed inputs; an ABI 2 SDK plugin gets its declared inputs through
// session_create2; every mismatch between a scan's inputs and a method's
// declaration is refused before plugin code runs, with a message saying what
// to do. The fixtures are testdata/v1_table.c, v1_host.c (built with the ABI 1
// values) and sdk_inputs.cpp ("inputs-fixture").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "plugin_loader.hpp"
#include "procam/core/image.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::host {
namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

std::string fixture(const std::string& name) { return std::string(PROCAM_HOST_FIXTURE_DIR) + "/" + name + ".so"; }
std::string inputs_fixture() { return std::string(PROCAM_INPUTS_FIXTURE_DIR) + "/inputs_fixture.so"; }

// A rig description with a 4x3 camera and a 4x3 projector.
const char* kRig = R"({"projector":{"width":4,"height":3},"cameras":[{"width":4,"height":3,"bit_depth":8}]})";

// A width x height F32 map holding `values` (row-major).
Image f32_map(const std::vector<float>& values, uint32_t w, uint32_t h) {
  Image m(w, h, PixelType::f32);
  std::copy(values.begin(), values.end(), m.ptr<float>());
  return m;
}

// Runs the single round of a session whose plan is one 4x3 frame; returns the outputs.
std::vector<Output> run_round(Session& s, uint8_t value) {
  auto plan = s.next_plan();
  EXPECT_TRUE(plan.ok() && plan->has_value()) << plan.status().to_string();
  if (!plan.ok() || !plan->has_value()) return {};
  Image frame(4, 3, PixelType::u8);
  std::memset(frame.data(), value, frame.size_bytes());
  EXPECT_TRUE(s.add_frame(0, frame.view()).ok());
  EXPECT_TRUE(s.end_round().ok());
  auto done = s.next_plan();
  EXPECT_TRUE(done.ok() && !done->has_value());
  auto outs = s.outputs();
  EXPECT_TRUE(outs.ok()) << outs.status().to_string();
  return outs.ok() ? *outs : std::vector<Output>{};
}

const Output* find(const std::vector<Output>& outs, const std::string& name) {
  for (const Output& o : outs)
    if (o.name == name) return &o;
  return nullptr;
}

TEST(InputsAbi, TableSizesOfEachVersion) {
  // ABI 1 with session_set_host ends where ABI 2's session_create2 begins.
  EXPECT_EQ(PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE, PROCAM_PLUGIN_VTABLE_V1_SIZE + sizeof(void (*)(void)));
  EXPECT_EQ(sizeof(procam_plugin_vtable), PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE + sizeof(void (*)(void)));
  EXPECT_EQ(PROCAM_PLUGIN_ABI_VERSION, 3u);
  EXPECT_EQ(PROCAM_PLUGIN_ABI_VERSION_MIN, 1u);
}

TEST(InputsAbi, Abi1PluginsOfBothTableSizesLoadRunAndRefuseInputs) {
  const Image depth = f32_map(std::vector<float>(12, 800.f), 4, 3);
  for (const char* name : {"v1_table", "v1_host"}) {
    for (bool probe : {true, false}) {
      SCOPED_TRACE(std::string(name) + (probe ? " probed" : " in-process"));
      PluginHost host(LoadOptions{.probe_in_child = probe, .probe_timeout = std::chrono::seconds(5)});
      Status st = host.load_file(fixture(name));
      ASSERT_TRUE(st.ok()) << st.to_string();
      ASSERT_EQ(host.plugins().size(), 1u);
      EXPECT_EQ(host.plugins()[0].abi, 1u);
      // Runs (through session_create; v1_host's session_create2 slot is a trap).
      auto s = host.create_session(name, "null", "{}", "{}");
      ASSERT_TRUE(s.ok()) << s.status().to_string();
      const auto outs = run_round(*s, 7);
      const Output* mean = find(outs, "frame_mean");
      ASSERT_NE(mean, nullptr);
      EXPECT_DOUBLE_EQ(mean->scalar, 7.0);
      // Inputs are refused with the reason, before any plugin call.
      auto refused = host.create_session(name, "null", "{}", "{}",
                                         {{"depth_mm", "mm", "test", depth.view()}});
      ASSERT_FALSE(refused.ok());
      EXPECT_EQ(refused.status().code(), Code::invalid_argument);
      EXPECT_TRUE(contains(refused.status().message(), "was built for plugin ABI 1")) << refused.status().message();
    }
  }
}

// ABI 3 appended light_index to procam_frame_settings, which changes the
// stride of a plan's frame array: an ABI 2 plugin (testdata/v2_frames.c, two
// frames in the ABI 2 layout) must still load and run, its second frame read
// at the ABI 2 offset, and both frames lit by the projector (light_index 0).
TEST(LightsAbi, Abi2PluginPlansAreReadWithTheirOwnStride) {
  EXPECT_EQ(sizeof(procam_frame_settings), sizeof(procam_frame_settings_v2) + 8);
  EXPECT_EQ(sizeof(procam_pattern_frame), sizeof(procam_pattern_frame_v2) + 8);
  for (bool probe : {true, false}) {
    SCOPED_TRACE(probe ? "probed" : "in-process");
    PluginHost host(LoadOptions{.probe_in_child = probe, .probe_timeout = std::chrono::seconds(5)});
    Status st = host.load_file(fixture("v2_frames"));
    ASSERT_TRUE(st.ok()) << st.to_string();
    ASSERT_EQ(host.plugins().size(), 1u);
    EXPECT_EQ(host.plugins()[0].abi, 2u);
    auto s = host.create_session("v2_frames", "null", "{}", "{}");
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    auto plan = s->next_plan();
    ASSERT_TRUE(plan.ok() && plan->has_value()) << plan.status().to_string();
    const auto& frames = (**plan).frames;
    ASSERT_EQ(frames.size(), 2u);
    for (size_t i = 0; i < 2; ++i) {
      EXPECT_EQ(frames[i].label, "black-" + std::to_string(i));
      EXPECT_EQ(frames[i].settings.camera_index, static_cast<int32_t>(i));
      EXPECT_EQ(frames[i].settings.exposure_us, 1000.0 * static_cast<double>(i + 1));
      EXPECT_EQ(frames[i].settings.light_index, 0);
      EXPECT_EQ(frames[i].settings.struct_size, sizeof(procam_frame_settings));
      EXPECT_EQ(frames[i].pattern.width, 4u);
    }
    Image frame(4, 3, PixelType::u8);
    std::memset(frame.data(), 6, frame.size_bytes());
    ASSERT_TRUE(s->add_frame(0, frame.view()).ok());
    std::memset(frame.data(), 10, frame.size_bytes());
    ASSERT_TRUE(s->add_frame(1, frame.view()).ok());
    ASSERT_TRUE(s->end_round().ok());
    auto done = s->next_plan();
    ASSERT_TRUE(done.ok() && !done->has_value());
    auto outs = s->outputs();
    ASSERT_TRUE(outs.ok()) << outs.status().to_string();
    const Output* mean = find(*outs, "frame_mean");
    ASSERT_NE(mean, nullptr);
    EXPECT_DOUBLE_EQ(mean->scalar, 8.0);  // (6 + 10) / 2: both frames reached the plugin
  }
}

class InputsFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    Status st = host_.load_file(inputs_fixture());
    ASSERT_TRUE(st.ok()) << st.to_string();
  }
  PluginHost host_;
};

TEST_F(InputsFixture, DescribeDeclaresInputsAndTheHostParsesThem) {
  const PluginInfo* p = host_.find("inputs-fixture");
  ASSERT_NE(p, nullptr);
  EXPECT_EQ(p->abi, PROCAM_PLUGIN_ABI_VERSION);
  ASSERT_EQ(p->methods.size(), 3u);
  ASSERT_EQ(p->methods[0].inputs.size(), 1u);  // stats
  EXPECT_EQ(p->methods[0].inputs[0].name, "depth_mm");
  EXPECT_EQ(p->methods[0].inputs[0].kind, "image_f32");
  EXPECT_EQ(p->methods[0].inputs[0].unit, "mm");
  EXPECT_TRUE(p->methods[0].inputs[0].required);
  EXPECT_TRUE(p->methods[2].inputs.empty());  // plain
  EXPECT_TRUE(p->methods[0].describe.contains("inputs"));
}

TEST_F(InputsFixture, TheInputReachesThePluginAndIsCopied) {
  // Values computed here: mean of the finite ones, NaN kept as invalid.
  std::vector<float> depth = {700.f, 710.f, NAN, 730.f, 740.f, 750.f,
                              760.f, 770.f, 780.f, 790.f, 800.f, 810.f};
  double sum = 0;
  int n = 0;
  for (float v : depth)
    if (std::isfinite(v)) sum += double(v), ++n;
  Image map = f32_map(depth, 4, 3);
  auto s = host_.create_session("inputs-fixture", "stats", "{}", kRig, {{"depth_mm", "mm", "test map", map.view()}});
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  // The host's memory is only lent during create: scribble over it now.
  std::fill(map.ptr<float>(), map.ptr<float>() + map.pixel_count(), -1.f);
  const auto outs = run_round(*s, 3);
  const Output* mean = find(outs, "input_mean_mm");
  const Output* count = find(outs, "input_valid_count");
  const Output* shifted = find(outs, "shifted_depth_mm");
  ASSERT_TRUE(mean && count && shifted);
  EXPECT_NEAR(mean->scalar, sum / n, 1e-3);
  EXPECT_EQ(count->scalar, 11.0);
  ASSERT_EQ(shifted->image.pixel_type, PROCAM_PIXEL_F32);
  const auto* px = static_cast<const float*>(shifted->image.data);
  EXPECT_FLOAT_EQ(px[0], 710.f);
  EXPECT_TRUE(std::isnan(px[2]));
  EXPECT_FLOAT_EQ(px[11], 820.f);
}

TEST_F(InputsFixture, MismatchesAreRefusedBeforeThePluginRuns) {
  const Image depth = f32_map(std::vector<float>(12, 800.f), 4, 3);
  const Image small = f32_map(std::vector<float>(4, 800.f), 2, 2);
  Image u8(4, 3, PixelType::u8);
  auto refuse = [&](const std::string& method, const std::vector<InputImage>& in, Code code,
                    const std::string& part) {
    auto s = host_.create_session("inputs-fixture", method, "{}", kRig, in);
    ASSERT_FALSE(s.ok()) << method;
    EXPECT_EQ(s.status().code(), code) << s.status().to_string();
    EXPECT_TRUE(contains(s.status().to_string(), part)) << s.status().to_string();
  };
  // A method that takes none.
  refuse("plain", {{"depth_mm", "mm", "", depth.view()}}, Code::invalid_argument,
         "method 'inputs-fixture/plain' takes no inputs, but the request gives 'depth_mm'");
  // A name the method does not declare.
  refuse("stats", {{"depth_mm", "mm", "", depth.view()}, {"ref_mm", "mm", "", depth.view()}},
         Code::invalid_argument, "has no input 'ref_mm' (it takes: depth_mm)");
  // The required one absent: says how to give it.
  refuse("stats", {}, Code::invalid_argument, "needs input 'depth_mm' (image_f32, mm");
  refuse("stats", {}, Code::invalid_argument, "procam scan --input depth_mm=SCAN_ID");
  // Twice.
  refuse("stats", {{"depth_mm", "mm", "", depth.view()}, {"depth_mm", "mm", "", depth.view()}},
         Code::invalid_argument, "input 'depth_mm' is given twice");
  // Wrong kind: an 8-bit mask.
  refuse("stats", {{"depth_mm", "", "", u8.view()}}, Code::invalid_argument,
         "must be a 1-channel float map (image_f32), got 1-channel 8-bit pixels");
  // Wrong size: the plugin's own check (sdk::Inputs::image_f32).
  refuse("stats", {{"depth_mm", "mm", "", small.view()}}, Code::invalid_argument,
         "input 'depth_mm' is 2x2, this method needs 4x3");
  // The host still works afterwards.
  auto ok = host_.create_session("inputs-fixture", "plain", "{}", kRig);
  ASSERT_TRUE(ok.ok()) << ok.status().to_string();
  const auto outs = run_round(*ok, 5);
  ASSERT_NE(find(outs, "frame_mean_dn"), nullptr);
  EXPECT_DOUBLE_EQ(find(outs, "frame_mean_dn")->scalar, 5.0);
}

TEST(InputsAbi, FailedPreconditionKeepsItsMeaning) {
  EXPECT_EQ(detail::code_for_rc(PROCAM_ERR_FAILED_PRECONDITION), Code::failed_precondition);
  EXPECT_STREQ(procam_rc_name(PROCAM_ERR_FAILED_PRECONDITION), "PROCAM_ERR_FAILED_PRECONDITION");
}

}  // namespace
}  // namespace procam::host
