// SPDX-License-Identifier: MIT
// ABI-level tests of procam-structured-light.so: dlopen()ed from
// PROCAM_PLUGIN_DIR like the host does. Checks the info struct (read from the
// ELF file without loading, and via dlsym), a full "gray" session on frames
// rendered here from the plan's own patterns with independent geometry, and
// the error codes/messages for misuse.
#include <dlfcn.h>
#include <elf.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/plugin_abi.h"

namespace {

const std::string kPluginPath = std::string(PROCAM_PLUGIN_DIR) + "/procam-structured-light.so";

// ---- reading procam_plugin_info from the file, without loading it ----------

template <class T>
T read_at(const std::vector<char>& f, size_t off) {
  T v;
  if (off + sizeof(T) > f.size()) throw std::runtime_error("ELF read out of bounds");
  std::memcpy(&v, f.data() + off, sizeof(T));
  return v;
}

// Returns the bytes of dynamic symbol `name` as stored in the file, or empty.
std::vector<char> symbol_bytes_from_file(const std::string& path, const std::string& name) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<char> f((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto eh = read_at<Elf64_Ehdr>(f, 0);
  if (std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0 || eh.e_ident[EI_CLASS] != ELFCLASS64)
    return {};
  std::vector<Elf64_Shdr> sh(eh.e_shnum);
  for (size_t i = 0; i < sh.size(); ++i)
    sh[i] = read_at<Elf64_Shdr>(f, eh.e_shoff + i * eh.e_shentsize);
  for (const Elf64_Shdr& s : sh) {
    if (s.sh_type != SHT_DYNSYM) continue;
    const Elf64_Shdr& strtab = sh.at(s.sh_link);
    for (size_t off = 0; off + sizeof(Elf64_Sym) <= s.sh_size; off += sizeof(Elf64_Sym)) {
      const auto sym = read_at<Elf64_Sym>(f, s.sh_offset + off);
      const char* nm = f.data() + strtab.sh_offset + sym.st_name;
      if (name != nm || sym.st_shndx == SHN_UNDEF || sym.st_shndx >= sh.size()) continue;
      const Elf64_Shdr& sec = sh[sym.st_shndx];
      if (sec.sh_type == SHT_NOBITS) return {};  // .bss: bytes not in the file
      const size_t at = sec.sh_offset + (sym.st_value - sec.sh_addr);
      return std::vector<char>(f.begin() + static_cast<std::ptrdiff_t>(at),
                               f.begin() + static_cast<std::ptrdiff_t>(at + sym.st_size));
    }
  }
  return {};
}

// ---- the loaded plugin ------------------------------------------------------

struct Plugin {
  void* handle = nullptr;
  const procam_plugin_info* info = nullptr;
  procam_plugin_create_fn create = nullptr;
  const procam_plugin_vtable* vt = nullptr;
  Plugin() {
    handle = dlopen(kPluginPath.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) return;
    info = static_cast<const procam_plugin_info*>(dlsym(handle, PROCAM_PLUGIN_INFO_SYMBOL));
    create = reinterpret_cast<procam_plugin_create_fn>(dlsym(handle, PROCAM_PLUGIN_CREATE_SYMBOL));
    if (create != nullptr) vt = create(PROCAM_PLUGIN_ABI_VERSION);
  }
  ~Plugin() {
    if (handle != nullptr) dlclose(handle);
  }
};

Plugin& plugin() {
  static Plugin p;
  return p;
}

TEST(PluginAbi, InfoReadableFromFileBeforeLoading) {
  const std::vector<char> bytes = symbol_bytes_from_file(kPluginPath, PROCAM_PLUGIN_INFO_SYMBOL);
  ASSERT_EQ(bytes.size(), sizeof(procam_plugin_info)) << kPluginPath;
  procam_plugin_info info;
  std::memcpy(&info, bytes.data(), sizeof info);
  EXPECT_EQ(info.magic, PROCAM_PLUGIN_MAGIC);
  EXPECT_EQ(info.abi_version, PROCAM_PLUGIN_ABI_VERSION);
  EXPECT_EQ(info.struct_size, sizeof(procam_plugin_info));
  EXPECT_STREQ(info.name, "structured-light");
  EXPECT_STREQ(info.version, "0.2.0");
  EXPECT_STREQ(info.methods, "gray,xor02,xor04,minsw,ensemble,auto,phase-shift,modulated-phase-shift");
  ASSERT_NE(plugin().handle, nullptr) << dlerror();
  ASSERT_NE(plugin().info, nullptr);
  EXPECT_EQ(std::memcmp(plugin().info, &info, sizeof info), 0) << "file bytes == loaded bytes";
}

TEST(PluginAbi, VtableComplete) {
  ASSERT_NE(plugin().create, nullptr);
  const procam_plugin_vtable* vt = plugin().vt;
  ASSERT_NE(vt, nullptr);
  EXPECT_EQ(vt->abi_version, PROCAM_PLUGIN_ABI_VERSION);
  EXPECT_EQ(vt->struct_size, sizeof(procam_plugin_vtable));
  EXPECT_TRUE(vt->describe && vt->session_create && vt->session_destroy && vt->next_plan &&
              vt->add_frame && vt->end_round && vt->get_outputs);
  EXPECT_EQ(plugin().create(PROCAM_PLUGIN_ABI_VERSION + 1), nullptr);
}

TEST(PluginAbi, DescribeListsGrayAndItsParams) {
  const nlohmann::json d = nlohmann::json::parse(plugin().vt->describe());
  ASSERT_TRUE(d.is_array());
  ASSERT_EQ(d.size(), 8u);
  const char* names[] = {"gray", "xor02", "xor04", "minsw", "ensemble", "auto", "phase-shift",
                         "modulated-phase-shift"};
  for (size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(d[i]["name"], names[i]);
    EXPECT_TRUE(d[i]["params"].is_array()) << names[i];
  }
  EXPECT_TRUE(d[0]["description"].is_string());
  // "patterns" is an integer or null (proto/PROTOCOL.md list_plugins): null
  // where the count depends on the projector width, which describe() cannot
  // know; the formula is in "patterns_formula".
  for (size_t i = 0; i < 8; ++i)
    EXPECT_TRUE(d[i]["patterns"].is_null() || d[i]["patterns"].is_number_unsigned()) << names[i];
  EXPECT_TRUE(d[0]["patterns"].is_null());
  EXPECT_TRUE(d[0]["patterns_formula"].is_string());
  // Fixed counts, from the methods' definitions: minsw = white + black + 10
  // planes with inverses (defaults binarize=inverse, black_frame on);
  // phase shifting = 3 frequencies x 6 shifts, modulated x 9 masks.
  EXPECT_EQ(d[3]["patterns"], 2 + 2 * 10);
  EXPECT_EQ(d[6]["patterns"], 3 * 6);
  EXPECT_EQ(d[7]["patterns"], 3 * 6 * 9);
  std::map<std::string, nlohmann::json> params;
  for (const auto& p : d[0]["params"]) params[p["name"].get<std::string>()] = p;
  ASSERT_EQ(params.size(), 14u);
  EXPECT_EQ(params["rows"]["type"], "bool");
  EXPECT_EQ(params["rows"]["default"], false);
  EXPECT_EQ(params["binarize"]["default"], "inverse");
  EXPECT_EQ(params["binarize"]["choices"], nlohmann::json({"inverse", "white"}));
  EXPECT_EQ(params["min_contrast"]["default"], 0.03);
  EXPECT_EQ(params["min_bit_margin"]["default"], 0.1);
  EXPECT_EQ(params["max_weak_error_px"]["type"], "int");
  EXPECT_EQ(params["max_weak_error_px"]["default"], 1);
  EXPECT_EQ(params["noise_k"]["type"], "number");
  EXPECT_EQ(params["noise_k"]["default"], 3.0);
  EXPECT_EQ(params["max_uncertainty_px"]["default"], 1.5);
  EXPECT_EQ(params["tie_intervals"]["type"], "bool");
  EXPECT_EQ(params["tie_intervals"]["default"], false);
  EXPECT_EQ(params["fill_passes"]["type"], "int");
  EXPECT_EQ(params["fill_passes"]["default"], 0);
  EXPECT_EQ(params["fill_min_neighbours"]["default"], 1);
  EXPECT_EQ(params["fill_extrapolate"]["default"], true);
  EXPECT_EQ(params["fill_ties"]["default"], true);
  // Stripe averaging (issue 16): on by its gate, which real 8-bit captures
  // open (22-32 %) and no sim scene does (<= 1.7 %).
  EXPECT_EQ(params["stripe_average"]["type"], "string");
  EXPECT_EQ(params["stripe_average"]["default"], "auto");
  EXPECT_EQ(params["stripe_average"]["choices"], nlohmann::json({"auto", "off", "on"}));
  EXPECT_EQ(params["stripe_average_gate"]["type"], "number");
  EXPECT_EQ(params["stripe_average_gate"]["default"], 0.10);
  for (auto& [name, p] : params) EXPECT_FALSE(p["description"].get<std::string>().empty()) << name;
}

// ---- a rendered scan ---------------------------------------------------------

// Rig: camera 320x240 (f 400), projector 640x400 (f 1000) 250 mm to the right,
// turned 25 degrees toward the camera. Scene: plane z = 400 + 0.2 x (mm).
constexpr uint32_t kCamW = 320, kCamH = 240, kProjW = 640, kProjH = 400;
constexpr double kAngle = -25.0 * M_PI / 180.0;

nlohmann::json rig_json(bool calibrated = true) {
  const double c = std::cos(kAngle), s = std::sin(kAngle);
  nlohmann::json proj_k = {{"width", kProjW}, {"height", kProjH}, {"fx", 1000.0},
                           {"fy", 1000.0},    {"cx", 319.5},      {"cy", 199.5}};
  nlohmann::json cam_k = {{"width", kCamW}, {"height", kCamH}, {"fx", 400.0},
                          {"fy", 400.0},    {"cx", 159.5},     {"cy", 119.5}};
  nlohmann::json cam = {{"width", kCamW}, {"height", kCamH}, {"bit_depth", 8}};
  nlohmann::json proj = {{"width", kProjW}, {"height", kProjH}};
  if (calibrated) {
    proj["intrinsics"] = proj_k;
    cam["calibration"] = {
        {"intrinsics", cam_k},
        {"cam_from_proj",
         {{"rotation", {c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c}}, {"translation_mm", {250.0, 0.0, 0.0}}}}};
  }
  return {{"projector", proj}, {"cameras", {cam}}, {"threads", 2}};
}

struct Truth {
  double z = 0;       // depth of the scene point, mm
  double u = 0, v = 0;  // continuous projector pixel it lies on
};

// Independent forward model (no procam code).
Truth truth_at(uint32_t x, uint32_t y) {
  const double dx = (x - 159.5) / 400.0, dy = (y - 119.5) / 400.0;
  const double s = 400.0 / (1.0 - 0.2 * dx);  // z = 400 + 0.2 * (s * dx)
  const double X[3] = {s * dx, s * dy, s};
  const double c = std::cos(kAngle), sn = std::sin(kAngle);
  const double d[3] = {X[0] - 250.0, X[1], X[2]};
  // x_p = R^T d with R = [[c,0,s],[0,1,0],[-s,0,c]].
  const double xp = c * d[0] - sn * d[2], yp = d[1], zp = sn * d[0] + c * d[2];
  return {s, 1000.0 * xp / zp + 319.5, 1000.0 * yp / zp + 199.5};
}

struct Frames {
  std::vector<std::vector<uint8_t>> pixels;
  std::vector<procam_image> views;
};

// Camera image of every plan frame: each pixel sees the projector pixel its
// scene point lies on (nearest pixel centre); black 12 DN, contrast 200 DN.
Frames render(const procam_plan* plan) {
  Frames f;
  f.pixels.resize(plan->frame_count);
  for (uint32_t i = 0; i < plan->frame_count; ++i) {
    const procam_image& pat = plan->frames[i].pattern;
    EXPECT_EQ(pat.width, kProjW);
    EXPECT_EQ(pat.height, kProjH);
    auto& px = f.pixels[i];
    px.assign(size_t{kCamW} * kCamH, 12);
    for (uint32_t y = 0; y < kCamH; ++y)
      for (uint32_t x = 0; x < kCamW; ++x) {
        const Truth t = truth_at(x, y);
        const double pu = std::round(t.u), pv = std::round(t.v);
        if (pu < 0 || pv < 0 || pu >= kProjW || pv >= kProjH) continue;
        const auto* row = static_cast<const uint8_t*>(pat.data) +
                          static_cast<size_t>(pv) * pat.stride_bytes;
        const double lit = row[static_cast<size_t>(pu)] / 255.0;
        px[size_t{y} * kCamW + x] = static_cast<uint8_t>(12 + std::lround(200 * lit));
      }
    procam_image img{};
    img.width = kCamW;
    img.height = kCamH;
    img.channels = 1;
    img.pixel_type = PROCAM_PIXEL_U8;
    img.bit_depth = 8;
    img.stride_bytes = kCamW;
    img.data = px.data();
    f.views.push_back(img);
  }
  return f;
}

struct Session {
  procam_session* s = nullptr;
  procam_error err{};
  ~Session() {
    if (s != nullptr) plugin().vt->session_destroy(s);
  }
  int create(const std::string& params, const nlohmann::json& rig) {
    const std::string r = rig.dump();
    return plugin().vt->session_create("gray", params.c_str(), r.c_str(), &s, &err);
  }
};

std::map<std::string, const procam_output*> by_name(const procam_output* o, uint32_t n) {
  std::map<std::string, const procam_output*> m;
  for (uint32_t i = 0; i < n; ++i) m[o[i].name] = &o[i];
  return m;
}

void run_scan(const std::string& params, bool rows, uint32_t expected_frames) {
  SCOPED_TRACE(params);
  const procam_plugin_vtable* vt = plugin().vt;
  Session sess;
  ASSERT_EQ(sess.create(params, rig_json()), PROCAM_OK) << sess.err.message;
  const procam_plan* plan = nullptr;
  ASSERT_EQ(vt->next_plan(sess.s, &plan, &sess.err), 1) << sess.err.message;
  ASSERT_EQ(plan->frame_count, expected_frames);
  EXPECT_STREQ(plan->frames[0].label, "white");
  EXPECT_STREQ(plan->frames[1].label, "black");
  EXPECT_STREQ(plan->frames[2].label, "col bit 9");
  Frames frames = render(plan);
  // Streaming in reverse order: any order is allowed.
  for (uint32_t i = plan->frame_count; i-- > 0;)
    ASSERT_EQ(vt->add_frame(sess.s, i, &frames.views[i], &sess.err), PROCAM_OK) << sess.err.message;
  ASSERT_EQ(vt->end_round(sess.s, &sess.err), PROCAM_OK) << sess.err.message;
  ASSERT_EQ(vt->next_plan(sess.s, &plan, &sess.err), 0) << "single round";
  const procam_output* outs = nullptr;
  uint32_t count = 0;
  ASSERT_EQ(vt->get_outputs(sess.s, &outs, &count, &sess.err), PROCAM_OK) << sess.err.message;
  auto o = by_name(outs, count);
  for (const char* name : {"proj_col_px", "valid", "confidence", "depth_mm", "points",
                           "valid_fraction", "decode_ms", "pattern_count", "report"})
    ASSERT_TRUE(o.count(name)) << name;
  EXPECT_EQ(o.count("proj_row_px"), rows ? 1u : 0u);
  const auto* col = static_cast<const float*>(o["proj_col_px"]->image.data);
  const auto* valid = static_cast<const uint8_t*>(o["valid"]->image.data);
  const auto* depth = static_cast<const float*>(o["depth_mm"]->image.data);
  const auto* conf = static_cast<const float*>(o["confidence"]->image.data);
  const float* row = rows ? static_cast<const float*>(o["proj_row_px"]->image.data) : nullptr;
  size_t n_valid = 0, n_inside = 0;
  double worst_dz = 0;
  for (uint32_t y = 0; y < kCamH; ++y)
    for (uint32_t x = 0; x < kCamW; ++x) {
      const size_t i = size_t{y} * kCamW + x;
      const Truth t = truth_at(x, y);
      ASSERT_TRUE(std::isfinite(conf[i]));
      const bool inside = t.u >= 0.5 && t.u <= kProjW - 1.5 && t.v >= 0.5 && t.v <= kProjH - 1.5;
      if (inside) {
        ++n_inside;
        ASSERT_EQ(valid[i], 255) << x << "," << y;
        ASSERT_EQ(col[i], static_cast<float>(std::round(t.u))) << x << "," << y;
        if (row != nullptr) {
          ASSERT_EQ(row[i], static_cast<float>(std::round(t.v))) << x << "," << y;
        }
      }
      if (valid[i]) {
        ++n_valid;
        ASSERT_TRUE(std::isfinite(depth[i]));
        worst_dz = std::max(worst_dz, std::abs(static_cast<double>(depth[i]) - t.z));
      } else {
        ASSERT_TRUE(std::isnan(col[i]));
        ASSERT_TRUE(std::isnan(depth[i]));
      }
    }
  EXPECT_GT(n_inside, size_t{kCamW} * kCamH / 2);
  // Integer columns are up to 0.5 px from the truth: here < 0.5 mm of depth.
  EXPECT_LT(worst_dz, 0.5);
  EXPECT_EQ(o["points"]->point_count, n_valid);
  EXPECT_EQ(o["points"]->point_stride, 4u);
  EXPECT_STREQ(o["points"]->point_fields, "x,y,z,intensity");
  for (uint64_t p = 0; p < o["points"]->point_count; ++p)
    ASSERT_NEAR(o["points"]->points[4 * p + 3], 212.0 / 255.0, 1e-6);
  EXPECT_NEAR(o["valid_fraction"]->scalar, static_cast<double>(n_valid) / (kCamW * kCamH), 1e-12);
  EXPECT_EQ(o["pattern_count"]->scalar, expected_frames);
  EXPECT_TRUE(std::isfinite(o["decode_ms"]->scalar));
  EXPECT_GT(o["decode_ms"]->scalar, 0.0);
  EXPECT_STREQ(o["decode_ms"]->unit, "ms");
  EXPECT_STREQ(o["depth_mm"]->unit, "mm");
  const nlohmann::json report = nlohmann::json::parse(o["report"]->json);
  EXPECT_EQ(report["method"], "gray");
  EXPECT_EQ(report["code"], "binary-reflected Gray");
  EXPECT_EQ(report["bits"], 10);
  EXPECT_EQ(report["patterns"], expected_frames);
  EXPECT_EQ(report["model"], "direct illumination only (no global-light handling)");
  EXPECT_TRUE(report["why"].is_string());
  // Stripe averaging (default auto): this crisp, noise-free render is no
  // noise-bound capture, so its gate stays shut; binarize=white keeps no pairs.
  const nlohmann::json& stripe = report["stripe_average"];
  ASSERT_TRUE(stripe.is_object());
  EXPECT_EQ(stripe["mode"], "auto");
  EXPECT_EQ(stripe["fired"], false);
  EXPECT_EQ(stripe["pixels_added"], 0);
  EXPECT_FALSE(stripe["summary"].get<std::string>().empty());
  if (params.find("white") != std::string::npos) {
    EXPECT_EQ(stripe["available"], false);
  }
  if (stripe["available"] == true) {
    EXPECT_LT(stripe["f_noise"].get<double>(), 0.10);
  }
}

TEST(PluginAbi, GrayScanInverse) { run_scan("{}", false, 2 + 2 * 10); }
TEST(PluginAbi, GrayScanWhiteWithRows) {
  run_scan(R"({"binarize":"white","rows":true})", true, 2 + 10 + 9);
}

TEST(PluginAbi, UncalibratedRigDecodesWithoutDepth) {
  const procam_plugin_vtable* vt = plugin().vt;
  Session sess;
  ASSERT_EQ(sess.create("{}", rig_json(false)), PROCAM_OK) << sess.err.message;
  const procam_plan* plan = nullptr;
  ASSERT_EQ(vt->next_plan(sess.s, &plan, &sess.err), 1);
  Frames frames = render(plan);
  for (uint32_t i = 0; i < plan->frame_count; ++i)
    ASSERT_EQ(vt->add_frame(sess.s, i, &frames.views[i], &sess.err), PROCAM_OK);
  ASSERT_EQ(vt->end_round(sess.s, &sess.err), PROCAM_OK);
  const procam_output* outs = nullptr;
  uint32_t count = 0;
  ASSERT_EQ(vt->get_outputs(sess.s, &outs, &count, &sess.err), PROCAM_OK);
  auto o = by_name(outs, count);
  EXPECT_TRUE(o.count("proj_col_px"));
  EXPECT_FALSE(o.count("depth_mm"));
  EXPECT_FALSE(o.count("points"));
  EXPECT_EQ(nlohmann::json::parse(o["report"]->json)["triangulated"], false);
}

// describe()'s integer "patterns" must be what a session with default params
// plans in its first round, on rigs of two projector widths (the count must not
// depend on the width, else describe() has to say null).
TEST(PluginAbi, DescribedPatternCountsMatchTheFirstPlan) {
  const nlohmann::json d = nlohmann::json::parse(plugin().vt->describe());
  size_t checked = 0;
  for (const nlohmann::json& m : d) {
    if (m["patterns"].is_null()) continue;
    for (uint32_t width : {kProjW, 1030u}) {  // 1030 > 1024: stretched min-SW columns
      nlohmann::json rig = rig_json(false);
      rig["projector"]["width"] = width;
      const std::string rig_text = rig.dump();
      const std::string method = m["name"].get<std::string>();
      procam_session* s = nullptr;
      procam_error err{};
      ASSERT_EQ(plugin().vt->session_create(method.c_str(), "{}", rig_text.c_str(), &s, &err), PROCAM_OK)
          << method << ": " << err.message;
      const procam_plan* plan = nullptr;
      ASSERT_EQ(plugin().vt->next_plan(s, &plan, &err), 1) << method;
      EXPECT_EQ(plan->frame_count, m["patterns"].get<uint32_t>()) << method << " at width " << width;
      plugin().vt->session_destroy(s);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 3u);  // minsw, phase-shift, modulated-phase-shift
}

// ---- misuse -------------------------------------------------------------------

std::string create_error(const char* method, const char* params, int expected_code) {
  procam_session* s = nullptr;
  procam_error err{};
  const std::string rig = rig_json().dump();
  EXPECT_EQ(plugin().vt->session_create(method, params, rig.c_str(), &s, &err), expected_code)
      << method << " " << params;
  EXPECT_EQ(s, nullptr);
  return err.message;
}

TEST(PluginAbi, CreateErrors) {
  EXPECT_EQ(create_error("grey", "{}", PROCAM_ERR_INVALID_ARGUMENT),
            "unknown method 'grey'; this plugin offers: gray,xor02,xor04,minsw,ensemble,auto,phase-shift,"
            "modulated-phase-shift");
  EXPECT_EQ(create_error("gray", R"({"bits":3})", PROCAM_ERR_INVALID_ARGUMENT),
            "unknown parameter 'bits' for method 'gray' (known: rows, binarize, min_contrast, "
            "min_bit_margin, max_weak_error_px, noise_k, max_uncertainty_px, tie_intervals, fill_passes, "
            "fill_min_neighbours, fill_extrapolate, fill_ties, stripe_average, stripe_average_gate)");
  EXPECT_EQ(create_error("gray", R"({"rows":"yes"})", PROCAM_ERR_INVALID_ARGUMENT),
            R"(parameter 'rows' must be true or false, got "yes")");
  EXPECT_EQ(create_error("gray", R"({"min_bit_margin":1.5})", PROCAM_ERR_INVALID_ARGUMENT),
            "parameter 'min_bit_margin' must be a number in 0..1, got 1.5");
  EXPECT_EQ(create_error("gray", R"({"binarize":"grey"})", PROCAM_ERR_INVALID_ARGUMENT),
            R"(parameter 'binarize' must be one of "inverse", "white", got "grey")");
  for (const char* method : {"gray", "xor02", "xor04", "minsw", "ensemble", "auto"})
    for (const char* bad : {R"({"max_weak_error_px":-1})", R"({"max_weak_error_px":1.5})",
                            R"({"max_weak_error_px":2000})", R"({"max_weak_error_px":"1"})"}) {
      const std::string m = create_error(method, bad, PROCAM_ERR_INVALID_ARGUMENT);
      EXPECT_NE(m.find("parameter 'max_weak_error_px'"), std::string::npos) << method << " " << m;
    }
  EXPECT_EQ(create_error("gray", "{oops", PROCAM_ERR_INVALID_ARGUMENT),
            "params_json is not valid JSON");
  procam_session* s = nullptr;
  procam_error err{};
  EXPECT_EQ(plugin().vt->session_create("gray", "{}", nullptr, &s, &err),
            PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(err.message).find("rig"), std::string::npos) << err.message;
  EXPECT_EQ(plugin().vt->session_create("gray", "{}", R"({"projector":{"width":640}})", &s, &err),
            PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_STREQ(err.message, "rig: projector.height is missing");
}

TEST(PluginAbi, SessionMisuse) {
  const procam_plugin_vtable* vt = plugin().vt;
  Session sess;
  ASSERT_EQ(sess.create("{}", rig_json()), PROCAM_OK) << sess.err.message;
  std::vector<uint8_t> small(100 * 100, 0);
  procam_image img{};
  img.width = 100;
  img.height = 100;
  img.channels = 1;
  img.pixel_type = PROCAM_PIXEL_U8;
  img.bit_depth = 8;
  img.stride_bytes = 100;
  img.data = small.data();
  EXPECT_EQ(vt->add_frame(sess.s, 0, &img, &sess.err), PROCAM_ERR_STATE);
  EXPECT_STREQ(sess.err.message, "add_frame: no round in progress; call next_plan first");
  const procam_plan* plan = nullptr;
  ASSERT_EQ(vt->next_plan(sess.s, &plan, &sess.err), 1);
  EXPECT_EQ(vt->add_frame(sess.s, 0, &img, &sess.err), PROCAM_ERR_BAD_FRAME);
  EXPECT_STREQ(sess.err.message, "frame 0 (white): expected 320x240 1ch, got 100x100 U8/8-bit 1ch");
  EXPECT_EQ(vt->add_frame(sess.s, 99, &img, &sess.err), PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(sess.err.message).find("out of range"), std::string::npos);
  Frames frames = render(plan);
  ASSERT_EQ(vt->add_frame(sess.s, 0, &frames.views[0], &sess.err), PROCAM_OK);
  std::vector<uint16_t> wide(size_t{kCamW} * kCamH, 0);
  procam_image u16 = frames.views[1];
  u16.pixel_type = PROCAM_PIXEL_U16;
  u16.bit_depth = 12;
  u16.stride_bytes = kCamW * 2;
  u16.data = wide.data();
  EXPECT_EQ(vt->add_frame(sess.s, 1, &u16, &sess.err), PROCAM_ERR_BAD_FRAME);
  EXPECT_NE(std::string(sess.err.message).find("U8/8-bit"), std::string::npos) << sess.err.message;
  EXPECT_EQ(vt->end_round(sess.s, &sess.err), PROCAM_ERR_STATE);
  EXPECT_NE(std::string(sess.err.message).find("not added"), std::string::npos);
  for (uint32_t i = 1; i < plan->frame_count; ++i)
    ASSERT_EQ(vt->add_frame(sess.s, i, &frames.views[i], &sess.err), PROCAM_OK) << sess.err.message;
  ASSERT_EQ(vt->end_round(sess.s, &sess.err), PROCAM_OK);
  EXPECT_EQ(vt->end_round(sess.s, &sess.err), PROCAM_ERR_STATE);
  EXPECT_NE(std::string(sess.err.message).find("twice"), std::string::npos) << sess.err.message;
  const procam_output* outs = nullptr;
  uint32_t count = 0;
  EXPECT_EQ(vt->get_outputs(sess.s, &outs, &count, &sess.err), PROCAM_OK) << sess.err.message;
}

}  // namespace
