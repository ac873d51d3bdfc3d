// SPDX-License-Identifier: MIT
// Conformance: what EVERY decoder plugin must do, whatever it computes. Loads
// every plugin in PROCAM_PLUGIN_DIR at run time (tests are listed when ctest
// runs, so plugins built after this binary are included) and checks:
//   ABI (each plugin, by dlopen, no host in between):
//     - procam_plugin_info: magic, ABI version, struct size, NUL-terminated
//       name/version/methods, name [a-z0-9-], file named procam-<name>.so;
//     - describe(): a JSON array with one object per info method, in order,
//       each with "name", a string "description", "params" (array of
//       {name, type, default, description}) and "patterns" absent, null or a
//       non-negative integer (proto/PROTOCOL.md "Method");
//   misuse (each method): unknown method and non-object params ->
//     INVALID_ARGUMENT; get_outputs before a round, add_frame before
//     next_plan, end_round with frames missing -> STATE; frame index out of
//     the plan -> INVALID_ARGUMENT; wrong-size frame -> BAD_FRAME; every
//     failure carries a message;
//   plans: >= 1 frame per round, at most 1000 rounds, patterns projector-sized
//     1-channel U8/U16/F32, labels 1..255 bytes without '/', '\' or control
//     characters; a plan stays valid (same bytes) until the next next_plan;
//   outputs: names [a-z0-9_]{1,64} and unique; a unit string, matching the
//     name's unit suffix (_mm mm, _px px, _ms ms, _us us, _deg deg, _dn DN);
//     F32 maps NaN or finite; points finite with x,y,z first; JSON parses;
//     outputs stay valid (same bytes) until session_destroy;
//   on the sim rig (host path, engine::run_scan, scenes "plane" and
//   "tilted-box"; a method that refuses the one-camera rig with
//   failed_precondition runs on the first shipped multi-camera rig it accepts,
//   suite::sim_rig_files: the two-camera stereo rig, the camera+light units
//   rig): the scan finishes, an integer describe "patterns" is the
//   first round's frame count, and the well-known outputs are sane where a
//   plugin has them (proj_col_px in [-0.5, W - 0.5] and F32 camera-sized,
//   valid 255 exactly where the column is finite, confidence in [0, 1],
//   depth_mm NaN or positive, pattern_count = frames, report names the
//   method); running twice on fresh rigs gives byte-identical outputs
//   (timings excepted: outputs in ms, and JSON keys ending in _ms).
// No accuracy thresholds here: tests/accuracy holds those.
#include <dlfcn.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "plugin_runs.hpp"
#include "procam/core/image.hpp"
#include "procam/plugin_abi.h"

namespace procam {
namespace {

using suite::MethodCase;

// ---------------------------------------------------------------- ABI level

// A plugin library opened directly; closed at destruction.
struct Lib {
  void* handle = nullptr;
  const procam_plugin_info* info = nullptr;
  const procam_plugin_vtable* vt = nullptr;
  std::string path;
  explicit Lib(const std::string& p) : path(p) {
    handle = dlopen(p.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) return;
    info = static_cast<const procam_plugin_info*>(dlsym(handle, PROCAM_PLUGIN_INFO_SYMBOL));
    auto create = reinterpret_cast<procam_plugin_create_fn>(dlsym(handle, PROCAM_PLUGIN_CREATE_SYMBOL));
    if (create != nullptr) vt = create(PROCAM_PLUGIN_ABI_VERSION);
  }
  ~Lib() {
    if (handle != nullptr) dlclose(handle);
  }
  Lib(const Lib&) = delete;
  Lib& operator=(const Lib&) = delete;
};

std::string plugin_file(const std::string& name) { return std::string(PROCAM_PLUGIN_DIR) + "/procam-" + name + ".so"; }

std::vector<std::string> all_plugins() {
  host::PluginHost host;
  host.load_directories({PROCAM_PLUGIN_DIR});
  std::vector<std::string> names;
  for (const auto& p : host.plugins()) names.push_back(p.name);
  return names;
}

bool nul_terminated(const char* s, size_t n) { return std::memchr(s, '\0', n) != nullptr; }

std::vector<std::string> split_csv(const std::string& s) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= s.size()) {
    size_t end = s.find(',', start);
    if (end == std::string::npos) end = s.size();
    out.push_back(s.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

TEST(ConformanceSetup, FindsPluginsAndRejectsNone) {
  host::PluginHost host;
  host.load_directories({PROCAM_PLUGIN_DIR});
  ASSERT_FALSE(host.plugins().empty()) << "no plugins in " << PROCAM_PLUGIN_DIR;
  for (const auto& r : host.rejected()) ADD_FAILURE() << "rejected plugin " << r.file << ": " << r.error.message();
}

class PluginAbi : public ::testing::TestWithParam<std::string> {};

TEST_P(PluginAbi, InfoAndDescribe) {
  Lib lib(plugin_file(GetParam()));
  ASSERT_NE(lib.handle, nullptr) << dlerror();
  ASSERT_NE(lib.info, nullptr);
  ASSERT_NE(lib.vt, nullptr);
  const procam_plugin_info& i = *lib.info;
  EXPECT_EQ(i.magic, PROCAM_PLUGIN_MAGIC);
  EXPECT_EQ(i.abi_version, PROCAM_PLUGIN_ABI_VERSION);
  EXPECT_EQ(i.struct_size, sizeof(procam_plugin_info));
  ASSERT_TRUE(nul_terminated(i.name, sizeof i.name) && nul_terminated(i.version, sizeof i.version) &&
              nul_terminated(i.methods, sizeof i.methods));
  EXPECT_TRUE(std::regex_match(i.name, std::regex("[a-z0-9][a-z0-9-]{0,62}"))) << i.name;
  EXPECT_EQ(std::string(i.name), GetParam()) << "the file is procam-<info.name>.so";
  EXPECT_GT(std::strlen(i.version), 0u);
  EXPECT_EQ(lib.vt->abi_version, PROCAM_PLUGIN_ABI_VERSION);
  EXPECT_EQ(lib.vt->struct_size, sizeof(procam_plugin_vtable));

  const std::vector<std::string> methods = split_csv(i.methods);
  ASSERT_NE(lib.vt->describe, nullptr);
  const nlohmann::json d = nlohmann::json::parse(lib.vt->describe(), nullptr, false);
  ASSERT_TRUE(d.is_array()) << lib.vt->describe();
  ASSERT_EQ(d.size(), methods.size()) << "one describe() object per method in info.methods";
  for (size_t k = 0; k < methods.size(); ++k) {
    SCOPED_TRACE(methods[k]);
    EXPECT_TRUE(std::regex_match(methods[k], std::regex("[a-z0-9_-]{1,63}")));
    const nlohmann::json& m = d[k];
    ASSERT_TRUE(m.is_object());
    EXPECT_EQ(m.value("name", ""), methods[k]) << "describe() in info.methods order";
    EXPECT_TRUE(m.contains("description") && m["description"].is_string());
    if (m.contains("patterns")) {
      EXPECT_TRUE(m["patterns"].is_null() || (m["patterns"].is_number_integer() && m["patterns"].get<int64_t>() >= 0))
          << "patterns must be an integer or null (proto/PROTOCOL.md), got " << m["patterns"].dump();
    }
    ASSERT_TRUE(m.contains("params") && m["params"].is_array());
    std::set<std::string> names;
    for (const auto& p : m["params"]) {
      ASSERT_TRUE(p.is_object());
      ASSERT_TRUE(p.contains("name") && p["name"].is_string()) << p.dump();
      EXPECT_TRUE(names.insert(p["name"].get<std::string>()).second) << "duplicate parameter " << p["name"];
      EXPECT_TRUE(p.contains("type") && p["type"].is_string()) << p.dump();
      EXPECT_TRUE(p.contains("default")) << p.dump();
      EXPECT_TRUE(p.contains("description") && p["description"].is_string()) << p.dump();
    }
  }
}

INSTANTIATE_TEST_SUITE_P(AllPlugins, PluginAbi, ::testing::ValuesIn(all_plugins()),
                         [](const ::testing::TestParamInfo<std::string>& i) { return suite::case_name(i.param, "abi"); });

// Frames for ABI-level runs: black, camera 0's size, U8 (the sim rig is 8-bit).
struct Frames {
  uint32_t w, h;
  std::vector<uint8_t> black;
  std::vector<uint8_t> small;  // one column short: the wrong size
  procam_image view() const {
    procam_image v{};
    v.width = w;
    v.height = h;
    v.channels = 1;
    v.pixel_type = PROCAM_PIXEL_U8;
    v.bit_depth = 8;
    v.stride_bytes = w;
    v.data = black.data();
    return v;
  }
  procam_image wrong() const {
    procam_image v = view();
    v.width = w - 1;
    v.stride_bytes = w - 1;
    v.data = small.data();
    return v;
  }
};

std::vector<uint8_t> pattern_bytes(const procam_image& p) {
  const size_t bps = p.pixel_type == PROCAM_PIXEL_U8 ? 1 : p.pixel_type == PROCAM_PIXEL_U16 ? 2 : 4;
  std::vector<uint8_t> b;
  for (uint32_t y = 0; y < p.height; ++y) {
    const auto* row = static_cast<const uint8_t*>(p.data) + size_t{y} * p.stride_bytes;
    b.insert(b.end(), row, row + size_t{p.width} * bps);
  }
  return b;
}

// Bytes an output points to (image rows, points, JSON text), for lifetime checks.
std::vector<uint8_t> output_bytes(const procam_output& o) {
  if (o.kind == PROCAM_OUTPUT_IMAGE) return pattern_bytes(o.image);
  if (o.kind == PROCAM_OUTPUT_POINTS) {
    const auto* p = reinterpret_cast<const uint8_t*>(o.points);
    return std::vector<uint8_t>(p, p + o.point_count * o.point_stride * sizeof(float));
  }
  if (o.kind == PROCAM_OUTPUT_JSON) return std::vector<uint8_t>(o.json, o.json + std::strlen(o.json));
  std::vector<uint8_t> s(sizeof o.scalar);
  std::memcpy(s.data(), &o.scalar, sizeof o.scalar);
  return s;
}

std::string expected_unit(const std::string& name) {
  static const std::map<std::string, std::string> units = {{"_mm", "mm"}, {"_px", "px"}, {"_ms", "ms"},
                                                           {"_us", "us"}, {"_deg", "deg"}, {"_dn", "DN"}};
  for (const auto& [suffix, unit] : units)
    if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
      return unit;
  return "";
}

// The per-output rules of the file comment, on the raw ABI array.
void check_outputs(const procam_output* outs, uint32_t count) {
  std::set<std::string> seen;
  for (uint32_t k = 0; k < count; ++k) {
    const procam_output& o = outs[k];
    ASSERT_NE(o.name, nullptr);
    const std::string name = o.name;
    SCOPED_TRACE(name);
    EXPECT_TRUE(std::regex_match(name, std::regex("[a-z0-9_]{1,64}")));
    EXPECT_TRUE(seen.insert(name).second) << "duplicate output name";
    ASSERT_NE(o.unit, nullptr);
    if (const std::string u = expected_unit(name); !u.empty()) {
      EXPECT_EQ(std::string(o.unit), u) << "unit of " << name;
    }
    switch (o.kind) {
      case PROCAM_OUTPUT_IMAGE: {
        ASSERT_NE(o.image.data, nullptr);
        ASSERT_GT(o.image.width, 0u);
        ASSERT_GT(o.image.height, 0u);
        ASSERT_EQ(o.image.channels, 1u);
        ASSERT_TRUE(o.image.pixel_type == PROCAM_PIXEL_U8 || o.image.pixel_type == PROCAM_PIXEL_U16 ||
                    o.image.pixel_type == PROCAM_PIXEL_F32);
        if (o.image.pixel_type == PROCAM_PIXEL_F32) {
          const Image m = Image::copy_of(o.image);
          for (size_t i = 0; i < m.pixel_count(); ++i)
            ASSERT_FALSE(std::isinf(m.ptr<float>()[i])) << "F32 maps hold NaN or finite values; pixel " << i;
        }
        break;
      }
      case PROCAM_OUTPUT_SCALAR:
        EXPECT_FALSE(std::isinf(o.scalar));
        break;
      case PROCAM_OUTPUT_POINTS:
        ASSERT_GE(o.point_stride, 3u);
        ASSERT_NE(o.point_fields, nullptr);
        EXPECT_EQ(std::string(o.point_fields).rfind("x,y,z", 0), 0u);
        if (o.point_count > 0) {
          ASSERT_NE(o.points, nullptr);
        }
        for (uint64_t p = 0; p < o.point_count * o.point_stride; ++p) ASSERT_TRUE(std::isfinite(o.points[p])) << p;
        break;
      case PROCAM_OUTPUT_JSON:
        ASSERT_NE(o.json, nullptr);
        EXPECT_FALSE(nlohmann::json::parse(o.json, nullptr, false).is_discarded());
        break;
      default:
        ADD_FAILURE() << "unknown output kind " << o.kind;
    }
  }
}

class MethodAbi : public ::testing::TestWithParam<MethodCase> {};

TEST_P(MethodAbi, MisuseCodesPlansAndLifetimes) {
  const MethodCase& c = GetParam();
  Lib lib(plugin_file(c.plugin));
  ASSERT_NE(lib.vt, nullptr) << dlerror();
  const procam_plugin_vtable& vt = *lib.vt;
  procam_error err{};
  procam_session* s = nullptr;
  const bool has_create2 =
      vt.struct_size > PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE && vt.session_create2 != nullptr;
  // The first shipped sim rig the method accepts (suite::sim_rig_files: a
  // method that needs two cameras or camera+light units runs on those rigs).
  std::unique_ptr<hw::Rig> rig;
  std::string rig_json;
  int created = PROCAM_ERR_FAILED_PRECONDITION;
  std::string refusals;
  for (const std::string& file : suite::sim_rig_files()) {
    rig = suite::sim_rig("plane", file);
    ASSERT_TRUE(rig);
    rig_json = suite::plugin_rig_json_for(*rig, file).dump();
    if (file == suite::sim_rig_files().front()) {
      EXPECT_EQ(vt.session_create("no-such-method", "{}", rig_json.c_str(), &s, &err), PROCAM_ERR_INVALID_ARGUMENT);
      EXPECT_NE(err.message[0], '\0');
      err = {};
      EXPECT_EQ(vt.session_create(c.method.c_str(), "[1]", rig_json.c_str(), &s, &err), PROCAM_ERR_INVALID_ARGUMENT)
          << "params must be a JSON object";
      EXPECT_NE(err.message[0], '\0');
      err = {};
    }
    // A method that declares required inputs (ABI 2) gets them from the sim's
    // truth (suite::required_inputs) through session_create2.
    std::vector<std::vector<float>> input_pixels;
    const std::vector<host::InputImage> inputs = suite::required_inputs(c.describe, *rig, input_pixels);
    std::vector<procam_output> in;
    for (const auto& i : inputs) {
      procam_output o{};
      o.name = i.name.c_str();
      o.unit = i.unit.c_str();
      o.description = i.description.c_str();
      o.kind = PROCAM_OUTPUT_IMAGE;
      o.image = i.image;
      in.push_back(o);
    }
    if (!in.empty()) {
      ASSERT_TRUE(has_create2) << "a method with required inputs needs session_create2";
    }
    created = !in.empty() ? vt.session_create2(c.method.c_str(), "{}", rig_json.c_str(), in.data(),
                                               static_cast<uint32_t>(in.size()), &s, &err)
                          : vt.session_create(c.method.c_str(), "{}", rig_json.c_str(), &s, &err);
    if (created != PROCAM_ERR_FAILED_PRECONDITION) break;
    // Needs rig data this rig lacks (e.g. a calibration table made on another
    // rig, a second camera): refused before any work, with a message, and no
    // session.
    EXPECT_NE(err.message[0], '\0') << "a refusal must say what is missing";
    EXPECT_EQ(s, nullptr);
    refusals += (refusals.empty() ? "" : "; ") + file + ": " + err.message;
    err = {};
  }
  if (created == PROCAM_ERR_FAILED_PRECONDITION)
    GTEST_SKIP() << "needs rig data no shipped sim rig has: " << refusals;
  const nlohmann::json rj = nlohmann::json::parse(rig_json);
  const uint32_t pw = rj["projector"]["width"], ph = rj["projector"]["height"];
  Frames f{rj["cameras"][0]["width"], rj["cameras"][0]["height"], {}, {}};
  f.black.assign(size_t{f.w} * f.h, 0);
  f.small.assign(size_t{f.w - 1} * f.h, 0);
  ASSERT_EQ(created, PROCAM_OK) << err.message;
  ASSERT_NE(s, nullptr);

  auto expect_fails = [&](int rc, int code, const char* what) {
    EXPECT_EQ(rc, code) << what;
    EXPECT_NE(err.message[0], '\0') << what << ": failure without a message";
    err = {};
  };
  const procam_output* outs = nullptr;
  uint32_t count = 0;
  const procam_image black = f.view(), wrong = f.wrong();
  expect_fails(vt.get_outputs(s, &outs, &count, &err), PROCAM_ERR_STATE, "get_outputs before a round");
  expect_fails(vt.add_frame(s, 0, &black, &err), PROCAM_ERR_STATE, "add_frame before next_plan");

  const std::regex label_ok("[^/\\\\\\x01-\\x1f\\x7f]{1,255}");
  uint32_t rounds = 0;
  bool first_round = true;
  for (;;) {
    const procam_plan* plan = nullptr;
    const int more = vt.next_plan(s, &plan, &err);
    ASSERT_GE(more, 0) << err.message;
    if (more == 0) break;
    ASSERT_LE(++rounds, 1000u) << "a session plans at most 1000 rounds";
    ASSERT_NE(plan, nullptr);
    ASSERT_GE(plan->frame_count, 1u) << "a round has at least one frame";
    if (first_round && c.describe.contains("patterns") && c.describe["patterns"].is_number_integer()) {
      EXPECT_EQ(plan->frame_count, c.describe["patterns"].get<uint32_t>()) << "describe() patterns vs the plan";
    }
    std::vector<std::vector<uint8_t>> before;
    for (uint32_t k = 0; k < plan->frame_count; ++k) {
      const procam_pattern_frame& fr = plan->frames[k];
      ASSERT_NE(fr.label, nullptr);
      EXPECT_TRUE(std::regex_match(fr.label, label_ok)) << "label '" << fr.label << "'";
      EXPECT_EQ(fr.settings.struct_size, sizeof(procam_frame_settings));
      ASSERT_EQ(fr.pattern.width, pw) << "patterns are projector-sized";
      ASSERT_EQ(fr.pattern.height, ph);
      ASSERT_EQ(fr.pattern.channels, 1u);
      ASSERT_TRUE(fr.pattern.pixel_type == PROCAM_PIXEL_U8 || fr.pattern.pixel_type == PROCAM_PIXEL_U16 ||
                  fr.pattern.pixel_type == PROCAM_PIXEL_F32);
      ASSERT_NE(fr.pattern.data, nullptr);
      before.push_back(pattern_bytes(fr.pattern));
    }
    if (first_round) {
      expect_fails(vt.add_frame(s, plan->frame_count, &black, &err), PROCAM_ERR_INVALID_ARGUMENT,
                   "frame index outside the plan");
      expect_fails(vt.add_frame(s, 0, &wrong, &err), PROCAM_ERR_BAD_FRAME, "frame one column short");
      expect_fails(vt.end_round(s, &err), PROCAM_ERR_STATE, "end_round with frames missing");
      first_round = false;
    }
    for (uint32_t k = 0; k < plan->frame_count; ++k) ASSERT_EQ(vt.add_frame(s, k, &black, &err), PROCAM_OK) << err.message;
    ASSERT_EQ(vt.end_round(s, &err), PROCAM_OK) << err.message;
    for (uint32_t k = 0; k < plan->frame_count; ++k)
      ASSERT_EQ(pattern_bytes(plan->frames[k].pattern), before[k]) << "plan changed before the next next_plan, frame " << k;
  }
  ASSERT_GE(rounds, 1u);
  ASSERT_EQ(vt.get_outputs(s, &outs, &count, &err), PROCAM_OK) << err.message;
  check_outputs(outs, count);
  std::vector<std::vector<uint8_t>> kept;
  for (uint32_t k = 0; k < count; ++k) kept.push_back(output_bytes(outs[k]));
  // More calls on the session must not invalidate what was handed out.
  const procam_plan* none = nullptr;
  EXPECT_EQ(vt.next_plan(s, &none, &err), 0) << "done stays done";
  const procam_output* again = nullptr;
  uint32_t again_n = 0;
  EXPECT_EQ(vt.get_outputs(s, &again, &again_n, &err), PROCAM_OK) << err.message;
  EXPECT_EQ(again_n, count);
  for (uint32_t k = 0; k < count; ++k) EXPECT_EQ(output_bytes(outs[k]), kept[k]) << "output " << outs[k].name << " changed";
  vt.session_destroy(s);
}

// ---------------------------------------------------------------- on the sim rig

struct SceneCase {
  MethodCase m;
  std::string scene;
};
void PrintTo(const SceneCase& c, std::ostream* os) { *os << c.m.plugin << "/" << c.m.method << " on " << c.scene; }

std::vector<SceneCase> all_scene_cases() {
  std::vector<SceneCase> cases;
  for (const auto& m : suite::all_methods())
    for (const char* scene : {"plane", "tilted-box"}) cases.push_back({m, scene});
  return cases;
}

class MethodOnSim : public ::testing::TestWithParam<SceneCase> {};

TEST_P(MethodOnSim, ScanFinishesWithSaneOutputs) {
  const SceneCase& c = GetParam();
  suite::SimRun run;
  const bool ran = suite::run_on_sim(c.m.plugin, c.m.method, c.scene, run);
  if (!run.skip_reason.empty()) GTEST_SKIP() << "needs rig data no shipped sim rig has: " << run.skip_reason;
  ASSERT_TRUE(ran);
  ASSERT_GE(run.outcome.rounds.size(), 1u);
  ASSERT_LE(run.outcome.rounds.size(), 1000u);
  for (const auto& r : run.outcome.rounds) EXPECT_GE(r.frames, 1u);
  EXPECT_GT(run.outcome.patterns, 0u);
  if (c.m.describe.contains("patterns") && c.m.describe["patterns"].is_number_integer()) {
    EXPECT_EQ(run.outcome.rounds[0].frames, c.m.describe["patterns"].get<size_t>());
  }

  const uint32_t cw = run.rig_json["cameras"][0]["width"], ch = run.rig_json["cameras"][0]["height"];
  const double pw = run.rig_json["projector"]["width"];
  const host::Output* col = suite::find_output(run.outputs, "proj_col_px");
  const host::Output* valid = suite::find_output(run.outputs, "valid");
  std::optional<Image> cols;
  if (col != nullptr) {
    ASSERT_EQ(col->kind, PROCAM_OUTPUT_IMAGE);
    ASSERT_EQ(col->image.pixel_type, PROCAM_PIXEL_F32);
    ASSERT_EQ(col->image.width, cw);
    ASSERT_EQ(col->image.height, ch);
    cols = Image::copy_of(col->image);
    for (uint32_t y = 0; y < ch; ++y)
      for (uint32_t x = 0; x < cw; ++x) {
        const float v = cols->at<float>(x, y);
        if (std::isnan(v)) continue;
        ASSERT_TRUE(std::isfinite(v) && v >= -0.5f && static_cast<double>(v) <= pw - 0.5) << x << "," << y << ": " << v;
      }
  }
  if (valid != nullptr && cols) {
    const Image vm = Image::copy_of(valid->image);
    for (uint32_t y = 0; y < ch; ++y)
      for (uint32_t x = 0; x < cw; ++x)
        ASSERT_EQ(vm.at<uint8_t>(x, y) == 255, std::isfinite(cols->at<float>(x, y))) << x << "," << y;
  }
  for (const auto& o : run.outputs) {
    if (o.name == "confidence") {
      const Image m = Image::copy_of(o.image);
      for (uint32_t y = 0; y < m.height(); ++y)
        for (uint32_t x = 0; x < m.width(); ++x) {
          const float v = m.at<float>(x, y);
          ASSERT_TRUE(std::isfinite(v) && v >= 0.0f && v <= 1.0f) << x << "," << y;
        }
    }
    if (o.name == "depth_mm") {
      const Image m = Image::copy_of(o.image);
      for (uint32_t y = 0; y < m.height(); ++y)
        for (uint32_t x = 0; x < m.width(); ++x) {
          const float v = m.at<float>(x, y);
          ASSERT_TRUE(std::isnan(v) || (std::isfinite(v) && v > 0.0f)) << x << "," << y;
        }
    }
    if (o.name == "pattern_count") {
      EXPECT_EQ(o.scalar, static_cast<double>(run.outcome.patterns));
    }
    if (o.name == "report") {
      const nlohmann::json r = nlohmann::json::parse(o.json, nullptr, false);
      ASSERT_FALSE(r.is_discarded());
      EXPECT_EQ(r.value("method", ""), c.m.method);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(AllPluginMethods, MethodOnSim, ::testing::ValuesIn(all_scene_cases()),
                         [](const ::testing::TestParamInfo<SceneCase>& i) {
                           return suite::case_name(i.param.m.plugin, i.param.m.method, i.param.scene);
                         });

INSTANTIATE_TEST_SUITE_P(AllPluginMethods, MethodAbi, ::testing::ValuesIn(suite::all_methods()),
                         [](const ::testing::TestParamInfo<MethodCase>& i) {
                           return suite::case_name(i.param.plugin, i.param.method);
                         });

// JSON without timing keys (names ending in "_ms"), recursively.
nlohmann::json without_timings(const nlohmann::json& j) {
  if (j.is_object()) {
    nlohmann::json o = nlohmann::json::object();
    for (auto it = j.begin(); it != j.end(); ++it)
      if (!(it.key().size() > 3 && it.key().ends_with("_ms"))) o[it.key()] = without_timings(it.value());
    return o;
  }
  if (j.is_array()) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& v : j) a.push_back(without_timings(v));
    return a;
  }
  return j;
}

class Determinism : public ::testing::TestWithParam<MethodCase> {};

TEST_P(Determinism, TwoRunsOnFreshRigsGiveIdenticalOutputs) {
  const MethodCase& c = GetParam();
  suite::SimRun a, b;
  const bool ran = suite::run_on_sim(c.plugin, c.method, "plane", a);
  if (!a.skip_reason.empty()) GTEST_SKIP() << "needs rig data no shipped sim rig has: " << a.skip_reason;
  ASSERT_TRUE(ran);
  ASSERT_TRUE(suite::run_on_sim(c.plugin, c.method, "plane", b));
  ASSERT_EQ(a.outputs.size(), b.outputs.size());
  for (size_t k = 0; k < a.outputs.size(); ++k) {
    const host::Output& x = a.outputs[k];
    const host::Output& y = b.outputs[k];
    SCOPED_TRACE(x.name);
    ASSERT_EQ(x.name, y.name);
    ASSERT_EQ(x.kind, y.kind);
    if (x.unit == "ms") continue;  // timings
    switch (x.kind) {
      case PROCAM_OUTPUT_IMAGE: {
        procam_output ox{}, oy{};
        ox.kind = oy.kind = PROCAM_OUTPUT_IMAGE;
        ox.image = x.image;
        oy.image = y.image;
        ASSERT_EQ(x.image.width, y.image.width);
        ASSERT_EQ(x.image.height, y.image.height);
        ASSERT_EQ(x.image.pixel_type, y.image.pixel_type);
        EXPECT_TRUE(output_bytes(ox) == output_bytes(oy)) << "image bytes differ";
        break;
      }
      case PROCAM_OUTPUT_SCALAR:
        EXPECT_EQ(std::memcmp(&x.scalar, &y.scalar, sizeof x.scalar), 0) << x.scalar << " vs " << y.scalar;
        break;
      case PROCAM_OUTPUT_POINTS:
        ASSERT_EQ(x.point_count, y.point_count);
        ASSERT_EQ(x.point_stride, y.point_stride);
        EXPECT_EQ(std::memcmp(x.points, y.points, x.point_count * x.point_stride * sizeof(float)), 0);
        break;
      default:
        EXPECT_EQ(without_timings(nlohmann::json::parse(x.json)), without_timings(nlohmann::json::parse(y.json)));
    }
  }
}

INSTANTIATE_TEST_SUITE_P(AllPluginMethods, Determinism, ::testing::ValuesIn(suite::all_methods()),
                         [](const ::testing::TestParamInfo<MethodCase>& i) {
                           return suite::case_name(i.param.plugin, i.param.method);
                         });

}  // namespace
}  // namespace procam
