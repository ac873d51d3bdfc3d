// SPDX-License-Identifier: MIT
// Tests of the header-only plugin SDK (plugins/sdk/include/procam/): error
// truncation, image reading, params and rig parsing, Plan/Outputs ownership,
// parallel_rows, and the ABI wrapper (exception barrier, call order, poisoning,
// lifetimes) through a tiny plugin defined in this test.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace sdk = procam::sdk;

namespace {

// ---- errors ---------------------------------------------------------------

TEST(SdkImage, GrayViewDescribesTheBufferAndPassesTheFrameCheck) {
  const std::vector<uint16_t> px(6, 4095);
  const procam_image v = sdk::gray_view(px.data(), 3, 2, 12);
  EXPECT_EQ(v.pixel_type, PROCAM_PIXEL_U16);
  EXPECT_EQ(v.bit_depth, 12u);
  EXPECT_EQ(v.stride_bytes, 6u);
  EXPECT_EQ(v.channels, 1u);
  EXPECT_TRUE(sdk::check_frame(&v, 3, 2, 1, "frame").ok());
  EXPECT_EQ(sdk::full_scale(v), 4095.0);
  EXPECT_EQ(sdk::pixel_value(v, 2, 1), 4095.0f);
  const std::vector<float> f(6, 0.5f);
  const procam_image g = sdk::gray_view(f.data(), 3, 2);
  EXPECT_EQ(g.pixel_type, PROCAM_PIXEL_F32);
  EXPECT_EQ(g.stride_bytes, 12u);
  EXPECT_EQ(sdk::pixel_value(g, 1, 1), 0.5f);
  const std::vector<uint8_t> b(6, 7);
  EXPECT_EQ(sdk::gray_view(b.data(), 3, 2).stride_bytes, 3u);
}

TEST(SdkError, WriteErrorTruncatesAtCharacterBoundary) {
  procam_error err;
  sdk::write_error(&err, "short");
  EXPECT_STREQ(err.message, "short");
  const std::string ascii(2000, 'a');
  sdk::write_error(&err, ascii.c_str());
  EXPECT_EQ(std::strlen(err.message), sizeof(err.message) - 1);
  EXPECT_EQ(std::string(err.message).substr(508), "...");
  std::string utf8;
  for (int i = 0; i < 400; ++i) utf8 += "\xC3\xA9";  // "é", 2 bytes each
  sdk::write_error(&err, utf8.c_str());
  const std::string got = err.message;
  ASSERT_GE(got.size(), 3u);
  ASSERT_EQ(got.substr(got.size() - 3), "...");
  const std::string body = got.substr(0, got.size() - 3);
  EXPECT_EQ(body.size() % 2, 0u) << "a 2-byte character was split";
  EXPECT_EQ(body, utf8.substr(0, body.size()));
  sdk::write_error(nullptr, "ignored");  // must not crash
}

// ---- images ---------------------------------------------------------------

procam_image view(const void* data, uint32_t w, uint32_t h, uint32_t ch, procam_pixel_type t,
                  uint32_t bits, size_t stride) {
  procam_image img{};
  img.width = w;
  img.height = h;
  img.channels = ch;
  img.pixel_type = t;
  img.bit_depth = bits;
  img.stride_bytes = stride;
  img.data = data;
  return img;
}

TEST(SdkImage, ReadsEveryTypeWithStrideAndChannels) {
  // 3x2, 2 channels, row stride padded by one sample pair.
  const std::vector<uint8_t> u8 = {1, 2, 3, 4, 5, 6, 0, 0, 7, 8, 9, 10, 11, 12, 0, 0};
  const std::vector<uint16_t> u16 = {100, 1, 4095, 2, 0, 3, 0, 0, 7, 4, 8, 5, 9, 6, 0, 0};
  const std::vector<float> f32 = {0.5f, 1, 0.25f, 2, 1.5f, 3, 0, 0, -1, 4, 2, 5, 3, 6, 0, 0};
  const procam_image a = view(u8.data(), 3, 2, 2, PROCAM_PIXEL_U8, 8, 8);
  const procam_image b = view(u16.data(), 3, 2, 2, PROCAM_PIXEL_U16, 12, 16);
  const procam_image c = view(f32.data(), 3, 2, 2, PROCAM_PIXEL_F32, 32, 32);
  for (const procam_image* img : {&a, &b, &c}) ASSERT_TRUE(sdk::check_image(img, "t").ok());
  EXPECT_EQ(sdk::pixel_value(a, 2, 1, 1), 12.0f);
  EXPECT_EQ(sdk::pixel_value(b, 1, 0, 0), 4095.0f);
  EXPECT_EQ(sdk::pixel_value(c, 0, 1, 0), -1.0f);
  EXPECT_EQ(sdk::full_scale(a), 255.0);
  EXPECT_EQ(sdk::full_scale(b), 4095.0);
  EXPECT_EQ(sdk::full_scale(view(u16.data(), 1, 1, 1, PROCAM_PIXEL_U16, 16, 2)), 65535.0);
  EXPECT_EQ(sdk::full_scale(c), 1.0);
  float row[3];
  sdk::read_row(b, 1, row, 1);
  EXPECT_EQ(row[0], 4.0f);
  EXPECT_EQ(row[1], 5.0f);
  EXPECT_EQ(row[2], 6.0f);
  sdk::read_row(c, 0, row, 0);
  EXPECT_EQ(row[0], 0.5f);
  EXPECT_EQ(row[2], 1.5f);
}

TEST(SdkImage, CheckImageRejectsBrokenViews) {
  const std::vector<uint16_t> px(64, 0);
  auto msg = [](const procam_image& img) { return sdk::check_image(&img, "frame 2").message; };
  EXPECT_EQ(sdk::check_image(nullptr, "frame 2").code, PROCAM_ERR_BAD_FRAME);
  procam_image img = view(nullptr, 4, 4, 1, PROCAM_PIXEL_U16, 12, 8);
  EXPECT_NE(msg(img).find("NULL"), std::string::npos);
  img = view(px.data(), 4, 4, 1, PROCAM_PIXEL_U16, 12, 8);
  img.pixel_type = 9;
  EXPECT_NE(msg(img).find("unknown pixel_type 9"), std::string::npos);
  img = view(px.data(), 4, 4, 1, PROCAM_PIXEL_U8, 9, 8);
  EXPECT_NE(msg(img).find("bit_depth 9"), std::string::npos);
  img = view(px.data(), 4, 4, 1, PROCAM_PIXEL_U16, 12, 6);
  EXPECT_NE(msg(img).find("stride_bytes 6"), std::string::npos);
  img = view(reinterpret_cast<const uint8_t*>(px.data()) + 1, 4, 4, 1, PROCAM_PIXEL_U16, 12, 8);
  EXPECT_NE(msg(img).find("aligned"), std::string::npos);
  img = view(px.data(), 4, 4, 1, PROCAM_PIXEL_U16, 12, 8);
  const sdk::Error e = sdk::check_frame(&img, 8, 4, 1, "frame 2 (col bit 3)");
  EXPECT_EQ(e.code, PROCAM_ERR_BAD_FRAME);
  EXPECT_EQ(e.message, "frame 2 (col bit 3): expected 8x4 1ch, got 4x4 U16/12-bit 1ch");
}

// ---- params ---------------------------------------------------------------

constexpr double kInf = std::numeric_limits<double>::infinity();

const std::vector<sdk::ParamSpec>& specs() {
  static const std::vector<sdk::ParamSpec> s = {
      {"bits", sdk::ParamType::integer, 10, 1, 16, {}, "code bits"},
      {"rows", sdk::ParamType::boolean, false, -kInf, kInf, {}, "rows too"},
      {"gain", sdk::ParamType::number, 0.5, 0, 1, {}, "a fraction"},
      {"mode", sdk::ParamType::string, "a", -kInf, kInf, {"a", "b"}, "mode"},
  };
  return s;
}

std::string parse_msg(const char* json) {
  sdk::Params p;
  const sdk::Error e = sdk::parse_params(nlohmann::json::parse(json), specs(), p, "m");
  EXPECT_EQ(e.code, PROCAM_ERR_INVALID_ARGUMENT) << json;
  return e.message;
}

TEST(SdkParams, DefaultsAndValues) {
  sdk::Params p;
  ASSERT_TRUE(sdk::parse_params(nlohmann::json::object(), specs(), p, "m").ok());
  EXPECT_EQ(p.get_int("bits"), 10);
  EXPECT_FALSE(p.get_bool("rows"));
  EXPECT_EQ(p.get_number("gain"), 0.5);
  EXPECT_EQ(p.get_string("mode"), "a");
  ASSERT_TRUE(sdk::parse_params(nullptr, specs(), p, "m").ok());
  ASSERT_TRUE(sdk::parse_params(
                  nlohmann::json::parse(R"({"bits":3.0,"rows":true,"gain":1,"mode":"b"})"),
                  specs(), p, "m")
                  .ok());
  EXPECT_EQ(p.get_int("bits"), 3);
  EXPECT_TRUE(p.get_bool("rows"));
  EXPECT_EQ(p.get_number("gain"), 1.0);
  EXPECT_EQ(p.get_string("mode"), "b");
}

TEST(SdkParams, ClearMessages) {
  EXPECT_EQ(parse_msg(R"({"bits":"x"})"), R"(parameter 'bits' must be an integer in 1..16, got "x")");
  EXPECT_EQ(parse_msg(R"({"bits":17})"), "parameter 'bits' must be an integer in 1..16, got 17");
  EXPECT_EQ(parse_msg(R"({"bits":2.5})"), "parameter 'bits' must be an integer in 1..16, got 2.5");
  EXPECT_EQ(parse_msg(R"({"rows":1})"), "parameter 'rows' must be true or false, got 1");
  EXPECT_EQ(parse_msg(R"({"gain":-0.1})"), "parameter 'gain' must be a number in 0..1, got -0.1");
  EXPECT_EQ(parse_msg(R"({"mode":"c"})"), R"(parameter 'mode' must be one of "a", "b", got "c")");
  EXPECT_EQ(parse_msg(R"({"bitz":1})"),
            "unknown parameter 'bitz' for method 'm' (known: bits, rows, gain, mode)");
  EXPECT_EQ(parse_msg("[1,2]"), "params for method 'm' must be a JSON object, got [1,2]");
}

TEST(SdkParams, DescribeListsEverything) {
  const nlohmann::json d = sdk::describe_params(specs());
  ASSERT_EQ(d.size(), 4u);
  EXPECT_EQ(d[0]["name"], "bits");
  EXPECT_EQ(d[0]["type"], "int");
  EXPECT_EQ(d[0]["default"], 10);
  EXPECT_EQ(d[0]["min"], 1.0);
  EXPECT_EQ(d[0]["max"], 16.0);
  EXPECT_FALSE(d[1].contains("min"));
  EXPECT_EQ(d[3]["choices"], nlohmann::json({"a", "b"}));
}

// ---- rig ------------------------------------------------------------------

const char* kRig = R"({
  "projector": {"width": 1280, "height": 800,
                "intrinsics": {"width":1280,"height":800,"fx":1400,"fy":1401,"cx":639.5,"cy":399.5}},
  "cameras": [{"width": 640, "height": 480, "bit_depth": 12,
               "calibration": {"intrinsics": {"width":640,"height":480,"fx":800,"fy":800,"cx":319.5,"cy":239.5},
                               "cam_from_proj": {"rotation":[1,0,0,0,1,0,0,0,1], "translation_mm":[-150,0,5]}}},
              {"width": 320, "height": 240}],
  "threads": 3})";

TEST(SdkRig, ParsesTheFixedFormat) {
  sdk::Rig rig;
  const sdk::Error e = sdk::parse_rig(nlohmann::json::parse(kRig), rig);
  ASSERT_TRUE(e.ok()) << e.message;
  EXPECT_EQ(rig.projector_width, 1280u);
  EXPECT_EQ(rig.projector_height, 800u);
  EXPECT_TRUE(rig.projector_calibrated);
  EXPECT_EQ(rig.projector.fy, 1401.0);
  ASSERT_EQ(rig.cameras.size(), 2u);
  EXPECT_EQ(rig.cameras[0].bit_depth, 12u);
  EXPECT_TRUE(rig.cameras[0].calibrated);
  EXPECT_EQ(rig.cameras[0].calibration.intrinsics.cx, 319.5);
  EXPECT_EQ(rig.cameras[0].calibration.cam_from_proj.translation_mm.x, -150.0);
  EXPECT_FALSE(rig.cameras[1].calibrated);
  EXPECT_EQ(rig.cameras[1].bit_depth, 8u);
  EXPECT_EQ(rig.threads, 3u);
  EXPECT_TRUE(rig.can_triangulate(0));
  EXPECT_FALSE(rig.can_triangulate(1));
}

TEST(SdkRig, ErrorsNameTheField) {
  auto msg = [](const std::string& patch_key, const nlohmann::json& value) {
    nlohmann::json j = nlohmann::json::parse(kRig);
    j[nlohmann::json::json_pointer(patch_key)] = value;
    sdk::Rig rig;
    const sdk::Error e = sdk::parse_rig(j, rig);
    EXPECT_EQ(e.code, PROCAM_ERR_INVALID_ARGUMENT) << patch_key;
    return e.message;
  };
  EXPECT_EQ(msg("/cameras/0/bit_depth", "8"),
            R"(rig: cameras[0].bit_depth must be an integer in 1..16 or 32, got "8")");
  EXPECT_NE(msg("/projector/width", 0).find("projector.width"), std::string::npos);
  EXPECT_NE(msg("/cameras/0/calibration/intrinsics/width", 641).find("641x480"),
            std::string::npos);
  EXPECT_NE(msg("/cameras", nlohmann::json::array()).find("cameras"), std::string::npos);
  EXPECT_NE(msg("/threads", -1).find("threads"), std::string::npos);
  sdk::Rig rig;
  EXPECT_FALSE(sdk::parse_rig(nlohmann::json(), rig).ok());
  nlohmann::json j = nlohmann::json::parse(kRig);
  j["threads"] = 0;
  ASSERT_TRUE(sdk::parse_rig(j, rig).ok());
  EXPECT_GE(rig.threads, 1u);
}

// ---- plan / outputs ---------------------------------------------------------

TEST(SdkPlan, OwnsFramesAndSetsUnsetDefaults) {
  sdk::Plan plan;
  EXPECT_EQ(plan.add_frame("white", 4, 2), 0u);
  EXPECT_EQ(plan.add_frame("f", 4, 2, PROCAM_PIXEL_F32), 1u);
  plan.pattern_u8(0)[5] = 255;
  plan.pattern_f32(1)[7] = 0.5f;
  plan.settings(1).exposure_us = 1000;
  plan.set_note("why");
  const procam_plan* v = plan.view();
  ASSERT_EQ(v->frame_count, 2u);
  EXPECT_STREQ(v->note, "why");
  EXPECT_STREQ(v->frames[0].label, "white");
  EXPECT_EQ(static_cast<const uint8_t*>(v->frames[0].pattern.data)[5], 255);
  EXPECT_EQ(static_cast<const float*>(v->frames[1].pattern.data)[7], 0.5f);
  EXPECT_EQ(v->frames[1].pattern.stride_bytes, 16u);
  const procam_frame_settings& s = v->frames[0].settings;
  EXPECT_EQ(s.struct_size, sizeof(procam_frame_settings));
  EXPECT_EQ(s.exposure_us, 0.0);
  EXPECT_EQ(s.gain_db, -1.0);
  EXPECT_EQ(s.projector_focus_mm, 0.0);
  EXPECT_TRUE(std::isnan(s.polarizer_deg));
  EXPECT_TRUE(std::isnan(s.projector_polarizer_deg));
  EXPECT_EQ(v->frames[1].settings.exposure_us, 1000.0);
  EXPECT_THROW(plan.add_frame("empty", 0, 2), std::invalid_argument);
}

TEST(SdkOutputs, ValidatesAndViews) {
  sdk::Outputs out;
  out.add_image("depth_mm", "mm", "d", 2, 2, std::vector<float>{1, 2, 3, NAN});
  out.add_image("valid", "", "v", 2, 2, std::vector<uint8_t>{0, 255, 255, 0});
  out.add_scalar("decode_ms", "ms", "t", 1.5);
  out.add_points("points", "p", "x,y,z,intensity", 4, std::vector<float>(8, 1.0f));
  out.add_json("report", "r", R"({"a":1})");
  EXPECT_THROW(out.add_scalar("Bad-Name", "", "", 0), std::invalid_argument);
  EXPECT_THROW(out.add_scalar("decode_ms", "", "", 0), std::invalid_argument);
  EXPECT_THROW(out.add_image("x", "", "", 3, 3, std::vector<float>(4)), std::invalid_argument);
  EXPECT_THROW(out.add_points("q", "", "x,y", 2, {}), std::invalid_argument);
  EXPECT_THROW(out.add_points("q", "", "x,y,z", 3, std::vector<float>(4)), std::invalid_argument);
  ASSERT_EQ(out.size(), 5u);
  const procam_output* o = out.view();
  EXPECT_STREQ(o[0].name, "depth_mm");
  EXPECT_EQ(o[0].kind, static_cast<uint32_t>(PROCAM_OUTPUT_IMAGE));
  EXPECT_EQ(o[0].image.pixel_type, static_cast<uint32_t>(PROCAM_PIXEL_F32));
  EXPECT_EQ(static_cast<const float*>(o[0].image.data)[2], 3.0f);
  EXPECT_EQ(o[1].image.pixel_type, static_cast<uint32_t>(PROCAM_PIXEL_U8));
  EXPECT_EQ(o[2].scalar, 1.5);
  EXPECT_STREQ(o[2].unit, "ms");
  EXPECT_EQ(o[3].point_count, 2u);
  EXPECT_EQ(o[3].point_stride, 4u);
  EXPECT_STREQ(o[3].point_fields, "x,y,z,intensity");
  EXPECT_STREQ(o[4].json, R"({"a":1})");
}

// set_release: each image's storage (the very buffer the view pointed at)
// goes to the hooks when the Outputs is destroyed; points stay with it.
std::vector<const void*> g_released;
size_t g_released_f32 = 0, g_released_u8 = 0;
void take_f32(std::vector<float>&& v) noexcept {
  g_released.push_back(v.data());
  g_released_f32 += v.size();
}
void take_u8(std::vector<uint8_t>&& v) noexcept {
  g_released.push_back(v.data());
  g_released_u8 += v.size();
}

TEST(SdkOutputs, ReleaseHooksGetEveryImageOnDestruction) {
  const void* depth = nullptr;
  const void* valid = nullptr;
  {
    sdk::Outputs out;
    out.set_release(take_f32, take_u8);
    out.add_image("depth_mm", "mm", "d", 2, 2, std::vector<float>{1, 2, 3, 4});
    out.add_image("valid", "", "v", 2, 2, std::vector<uint8_t>{0, 255, 255, 0});
    out.add_points("points", "p", "x,y,z", 3, std::vector<float>(9, 1.0f));
    const procam_output* o = out.view();
    depth = o[0].image.data;
    valid = o[1].image.data;
    EXPECT_TRUE(g_released.empty());  // nothing before destruction
  }
  ASSERT_EQ(g_released.size(), 2u);
  EXPECT_EQ(g_released[0], depth);
  EXPECT_EQ(g_released[1], valid);
  EXPECT_EQ(g_released_f32, 4u);  // not the 9 point floats
  EXPECT_EQ(g_released_u8, 4u);
  { sdk::Outputs plain; plain.add_image("x", "", "", 1, 1, std::vector<float>{1}); }  // no hooks: freed
  EXPECT_EQ(g_released.size(), 2u);
}

TEST(SdkParallel, CoversEveryRowOnceAndRethrows) {
  for (uint32_t rows = 0; rows < 9; ++rows)
    for (uint32_t threads = 1; threads < 6; ++threads) {
      std::vector<std::atomic<int>> hits(rows);
      sdk::parallel_rows(rows, threads, [&](uint32_t y0, uint32_t y1) {
        for (uint32_t y = y0; y < y1; ++y) hits[y]++;
      });
      for (uint32_t y = 0; y < rows; ++y) ASSERT_EQ(hits[y].load(), 1) << rows << "/" << threads;
    }
  EXPECT_THROW(sdk::parallel_rows(10, 3,
                                  [](uint32_t y0, uint32_t) {
                                    if (y0 > 0) throw std::runtime_error("band failed");
                                  }),
               std::runtime_error);
}

// ---- the ABI wrapper, through a plugin defined here ---------------------------

// Behaviour switches for the test session (one test thread).
struct Knobs {
  bool throw_in_add = false;
  bool bad_alloc_in_end = false;
  bool fail_end = false;
  int rounds = 1;
  std::vector<float> input;  // what the factory copied of input "depth_mm"
  std::string input_error;   // or why it could not
};
Knobs g_knobs;

class TestSession final : public sdk::Session {
 public:
  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (round_ >= g_knobs.rounds) return sdk::ok();
    plan.add_frame("a", 2, 2);
    plan.add_frame("b", 2, 2);
    has_round = true;
    return sdk::ok();
  }
  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    if (g_knobs.throw_in_add) throw std::runtime_error("boom in add_frame");
    if (sdk::Error e = sdk::check_frame(&frame, 2, 2, 1, "frame " + std::to_string(index));
        !e.ok())
      return e;
    sum_ += static_cast<double>(sdk::pixel_value(frame, 0, 0));
    return sdk::ok();
  }
  sdk::Error end_round() override {
    if (g_knobs.bad_alloc_in_end) throw std::bad_alloc();
    if (g_knobs.fail_end) return sdk::internal_error("decode failed on purpose");
    ++round_;
    return sdk::ok();
  }
  sdk::Error outputs(sdk::Outputs& out) override {
    out.add_scalar("sum", "", "sum of first pixels", sum_);
    out.add_scalar("round", "", "rounds decoded", round_);
    return sdk::ok();
  }

 private:
  int round_ = 0;
  double sum_ = 0;
};

std::string test_describe() { return R"([{"name":"one"},{"name":"two"}])"; }
sdk::Error test_create(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  if (args.params.contains("fail")) return sdk::invalid_argument("factory says no");
  if (args.method == "two") {  // takes a 2x2 "depth_mm"
    if (sdk::Error e = args.inputs.image_f32("depth_mm", 2, 2, g_knobs.input); !e.ok()) {
      g_knobs.input_error = e.message;
      if (args.params.contains("need_input")) return e;
    }
  }
  out = std::make_unique<TestSession>();
  return sdk::ok();
}

}  // namespace

PROCAM_DEFINE_PLUGIN("sdk-test", "9.9.9", "one,two", test_describe, test_create);

namespace {

const procam_plugin_vtable* vt() { return procam_plugin_create(PROCAM_PLUGIN_ABI_VERSION); }

struct SdkSession : ::testing::Test {
  void SetUp() override { g_knobs = Knobs{}; }
  void TearDown() override {
    if (s) vt()->session_destroy(s);
  }
  void create(const char* method = "one", const char* params = "{}") {
    ASSERT_EQ(vt()->session_create(method, params, nullptr, &s, &err), PROCAM_OK) << err.message;
  }
  int add(uint32_t i, uint8_t value = 1) {
    px_[i % 2].assign(4, value);
    procam_image img = view(px_[i % 2].data(), 2, 2, 1, PROCAM_PIXEL_U8, 8, 2);
    return vt()->add_frame(s, i, &img, &err);
  }
  procam_session* s = nullptr;
  procam_error err{};
  std::vector<uint8_t> px_[2];
};

TEST(SdkAbi, InfoAndVtable) {
  EXPECT_EQ(procam_sdk_plugin_info_.magic, PROCAM_PLUGIN_MAGIC);
  EXPECT_EQ(procam_sdk_plugin_info_.abi_version, PROCAM_PLUGIN_ABI_VERSION);
  EXPECT_EQ(procam_sdk_plugin_info_.struct_size, sizeof(procam_plugin_info));
  EXPECT_STREQ(procam_sdk_plugin_info_.name, "sdk-test");
  EXPECT_STREQ(procam_sdk_plugin_info_.version, "9.9.9");
  EXPECT_STREQ(procam_sdk_plugin_info_.methods, "one,two");
  const procam_plugin_vtable* t = vt();
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->struct_size, sizeof(procam_plugin_vtable));
  EXPECT_EQ(procam_plugin_create(PROCAM_PLUGIN_ABI_VERSION + 1), nullptr);
  EXPECT_STREQ(t->describe(), test_describe().c_str());
}

TEST_F(SdkSession, UnknownMethodAndFactoryErrors) {
  EXPECT_EQ(vt()->session_create("three", "{}", nullptr, &s, &err), PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_STREQ(err.message, "unknown method 'three'; this plugin offers: one,two");
  EXPECT_EQ(s, nullptr);
  EXPECT_EQ(vt()->session_create("on", "{}", nullptr, &s, &err), PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(vt()->session_create("one", "{not json", nullptr, &s, &err),
            PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_STREQ(err.message, "params_json is not valid JSON");
  EXPECT_EQ(vt()->session_create("one", "[1]", nullptr, &s, &err), PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(vt()->session_create("two", R"({"fail":1})", nullptr, &s, &err),
            PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_STREQ(err.message, "factory says no");
  EXPECT_EQ(vt()->session_create("two", nullptr, nullptr, nullptr, &err),
            PROCAM_ERR_INVALID_ARGUMENT);
  create("two", nullptr);  // NULL params = {}
}

// ABI 2: session_create2 hands the inputs to the factory as CreateArgs::inputs;
// session_create is the same with none.
TEST_F(SdkSession, SessionCreate2PassesInputsToTheFactory) {
  ASSERT_NE(vt()->session_create2, nullptr);
  const float depth[4] = {500.f, std::numeric_limits<float>::infinity(), NAN, 700.f};
  procam_output in{};
  in.name = "depth_mm";
  in.kind = PROCAM_OUTPUT_IMAGE;
  in.unit = "mm";
  in.image = view(depth, 2, 2, 1, PROCAM_PIXEL_F32, 32, 2 * sizeof(float));
  ASSERT_EQ(vt()->session_create2("two", "{}", nullptr, &in, 1, &s, &err), PROCAM_OK) << err.message;
  ASSERT_EQ(g_knobs.input.size(), 4u) << g_knobs.input_error;
  EXPECT_EQ(g_knobs.input[0], 500.f);
  EXPECT_TRUE(std::isnan(g_knobs.input[1]));  // +inf is not a valid value: NaN
  EXPECT_TRUE(std::isnan(g_knobs.input[2]));
  EXPECT_EQ(g_knobs.input[3], 700.f);
  vt()->session_destroy(s);
  s = nullptr;
  // No inputs through either entry point: the factory's own error.
  EXPECT_EQ(vt()->session_create2("two", R"({"need_input":1})", nullptr, nullptr, 0, &s, &err),
            PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(err.message).find("input 'depth_mm' is missing"), std::string::npos) << err.message;
  EXPECT_EQ(vt()->session_create("two", R"({"need_input":1})", nullptr, &s, &err),
            PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(s, nullptr);
  // A count without an array is the host's bug, refused before the factory.
  EXPECT_EQ(vt()->session_create2("two", "{}", nullptr, nullptr, 3, &s, &err), PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_STREQ(err.message, "session_create2: input_count is 3 but inputs is NULL");
}

TEST_F(SdkSession, CallOrderIsChecked) {
  create();
  const procam_output* outs = nullptr;
  uint32_t count = 0;
  EXPECT_EQ(add(0), PROCAM_ERR_STATE);
  EXPECT_NE(std::string(err.message).find("next_plan"), std::string::npos) << err.message;
  EXPECT_EQ(vt()->end_round(s, &err), PROCAM_ERR_STATE);
  EXPECT_EQ(vt()->get_outputs(s, &outs, &count, &err), PROCAM_ERR_STATE);
  const procam_plan* plan = nullptr;
  ASSERT_EQ(vt()->next_plan(s, &plan, &err), 1);
  ASSERT_EQ(plan->frame_count, 2u);
  EXPECT_EQ(vt()->next_plan(s, &plan, &err), PROCAM_ERR_STATE);
  EXPECT_EQ(add(2), PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(err.message).find("out of range"), std::string::npos);
  ASSERT_EQ(add(1, 5), PROCAM_OK);
  EXPECT_EQ(add(1), PROCAM_ERR_STATE);
  EXPECT_NE(std::string(err.message).find("already added"), std::string::npos);
  EXPECT_EQ(vt()->end_round(s, &err), PROCAM_ERR_STATE);
  EXPECT_NE(std::string(err.message).find("indices 0"), std::string::npos) << err.message;
  EXPECT_EQ(vt()->get_outputs(s, &outs, &count, &err), PROCAM_ERR_STATE);
  // A bad frame is refused and not counted; the good one is accepted after.
  procam_image bad = view(nullptr, 2, 2, 1, PROCAM_PIXEL_U8, 8, 2);
  EXPECT_EQ(vt()->add_frame(s, 0, &bad, &err), PROCAM_ERR_BAD_FRAME);
  EXPECT_STREQ(err.message, "frame 0 (a): data pointer is NULL");
  px_[0].assign(9, 0);
  bad = view(px_[0].data(), 3, 3, 1, PROCAM_PIXEL_U8, 8, 3);
  EXPECT_EQ(vt()->add_frame(s, 0, &bad, &err), PROCAM_ERR_BAD_FRAME);
  ASSERT_EQ(add(0, 7), PROCAM_OK);
  ASSERT_EQ(vt()->end_round(s, &err), PROCAM_OK);
  EXPECT_EQ(vt()->end_round(s, &err), PROCAM_ERR_STATE);
  EXPECT_NE(std::string(err.message).find("twice"), std::string::npos);
  ASSERT_EQ(vt()->get_outputs(s, &outs, &count, &err), PROCAM_OK);
  ASSERT_EQ(count, 2u);
  EXPECT_EQ(outs[0].scalar, 12.0);
  const procam_output* again = nullptr;
  ASSERT_EQ(vt()->get_outputs(s, &again, &count, &err), PROCAM_OK);
  EXPECT_EQ(again, outs) << "no new round: the same outputs";
  EXPECT_EQ(vt()->next_plan(s, &plan, &err), 0);
  EXPECT_EQ(plan, nullptr);
  EXPECT_EQ(vt()->next_plan(s, &plan, &err), 0) << "done stays done";
  EXPECT_EQ(add(0), PROCAM_ERR_STATE);
  EXPECT_NE(std::string(err.message).find("finished"), std::string::npos);
}

TEST_F(SdkSession, EarlierOutputsStayValidAcrossRounds) {
  g_knobs.rounds = 2;
  create();
  const procam_plan* plan = nullptr;
  const procam_output* first = nullptr;
  uint32_t count = 0;
  ASSERT_EQ(vt()->next_plan(s, &plan, &err), 1);
  ASSERT_EQ(add(0, 1), PROCAM_OK);
  ASSERT_EQ(add(1, 2), PROCAM_OK);
  ASSERT_EQ(vt()->end_round(s, &err), PROCAM_OK);
  ASSERT_EQ(vt()->get_outputs(s, &first, &count, &err), PROCAM_OK);
  ASSERT_EQ(vt()->next_plan(s, &plan, &err), 1);
  ASSERT_EQ(add(0, 10), PROCAM_OK);
  ASSERT_EQ(add(1, 20), PROCAM_OK);
  ASSERT_EQ(vt()->end_round(s, &err), PROCAM_OK);
  const procam_output* second = nullptr;
  ASSERT_EQ(vt()->get_outputs(s, &second, &count, &err), PROCAM_OK);
  EXPECT_NE(first, second);
  EXPECT_EQ(first[0].scalar, 3.0);   // still readable (kept until destroy)
  EXPECT_EQ(second[0].scalar, 33.0);
  EXPECT_STREQ(first[1].name, "round");
}

TEST_F(SdkSession, ExceptionsBecomeCodesAndPoisonTheSession) {
  create();
  const procam_plan* plan = nullptr;
  ASSERT_EQ(vt()->next_plan(s, &plan, &err), 1);
  g_knobs.throw_in_add = true;
  EXPECT_EQ(add(0), PROCAM_ERR_INTERNAL);
  EXPECT_STREQ(err.message, "add_frame: internal error: boom in add_frame");
  g_knobs.throw_in_add = false;
  EXPECT_EQ(add(1), PROCAM_ERR_STATE);
  EXPECT_NE(std::string(err.message).find("unusable"), std::string::npos);
  EXPECT_NE(std::string(err.message).find("boom in add_frame"), std::string::npos);
}

TEST_F(SdkSession, BadAllocIsNoMemoryAndFailedEndRoundPoisons) {
  create();
  const procam_plan* plan = nullptr;
  ASSERT_EQ(vt()->next_plan(s, &plan, &err), 1);
  ASSERT_EQ(add(0), PROCAM_OK);
  ASSERT_EQ(add(1), PROCAM_OK);
  g_knobs.bad_alloc_in_end = true;
  EXPECT_EQ(vt()->end_round(s, &err), PROCAM_ERR_NO_MEMORY);
  EXPECT_STREQ(err.message, "end_round: out of memory");
  vt()->session_destroy(s);
  s = nullptr;
  g_knobs = Knobs{};
  g_knobs.fail_end = true;
  create();
  ASSERT_EQ(vt()->next_plan(s, &plan, &err), 1);
  ASSERT_EQ(add(0), PROCAM_OK);
  ASSERT_EQ(add(1), PROCAM_OK);
  EXPECT_EQ(vt()->end_round(s, &err), PROCAM_ERR_INTERNAL);
  EXPECT_STREQ(err.message, "decode failed on purpose");
  EXPECT_EQ(vt()->next_plan(s, &plan, nullptr), PROCAM_ERR_STATE);  // NULL err is fine
}

}  // namespace
