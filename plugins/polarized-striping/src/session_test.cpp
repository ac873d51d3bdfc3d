// SPDX-License-Identifier: MIT
// The four methods end to end on frames synthesised from the thesis's own
// closed forms (independent of the code under test):
//   flood            E = S + B                              (Eq. 5.1–5.2)
//   best / worst     E_b,w = S/2 + B(1 -/+ p)/2             (Eq. 5.4–5.5)
//   stripe k         SI_k = lit_k D + A + B; polarised: lit_k D/2 + A/2 + B(1 -/+ p)/2
// with known per-pixel D, A, B and p; lit_k is read from the plan's pattern
// (the light the projector emits). Rig: camera pixel (x, y) sees projector
// pixel (x - disparity, y) on a fronto-parallel plane, so the true projector
// column and depth (z = f b / disparity) are closed forms. Frames get
// Gaussian noise and are quantised like the camera (8/12/16 bit, or F32).
#include "polarized_striping_session.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace procam::polarized_striping {
namespace {

constexpr uint32_t kPW = 128, kPH = 12;     // projector
constexpr uint32_t kDisp = 80;              // camera x = projector x + 80 on the plane
constexpr uint32_t kCW = kPW + kDisp, kCH = kPH;
constexpr uint32_t kMediumRows = 3;         // rows 0..2 see medium only (D = A = 0)
constexpr double kF = 400, kBaseline = 100; // mm; plane at z = f b / disparity = 500 mm
constexpr double kNoise = 0.002;            // true noise sigma, fraction of full scale

nlohmann::json rig(uint32_t bits, bool calibrated) {
  nlohmann::json cam = {{"width", kCW}, {"height", kCH}, {"bit_depth", bits}};
  nlohmann::json proj = {{"width", kPW}, {"height", kPH}};
  if (calibrated) {
    proj["intrinsics"] = {{"width", kPW}, {"height", kPH}, {"fx", kF}, {"fy", kF}, {"cx", 63.5}, {"cy", 5.5}};
    // Camera = projector intrinsics shifted by the disparity in cx, projector
    // centre at x = +100 mm in the camera frame: pixel x sees projector column
    // c = x - f b / z = x - 80 at z = 500.
    cam["calibration"] = {
        {"intrinsics", {{"width", kCW}, {"height", kCH}, {"fx", kF}, {"fy", kF}, {"cx", 63.5}, {"cy", 5.5}}},
        {"cam_from_proj", {{"rotation", {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}}, {"translation_mm", {kBaseline, 0.0, 0.0}}}}};
  }
  return {{"projector", proj}, {"cameras", {cam}}, {"threads", 2}};
}

// Truth per camera pixel, fractions of full scale.
struct Truth {
  double p = 0.8, a_level = 0.0;
  bool uniform_b = false;
  int black_from = -1, black_to = -1;      // camera columns with D = 0 (black paint)
  int clip_row = -1;                       // this row: backscatter far above full scale
  bool object(uint32_t x, uint32_t y) const { return y >= kMediumRows && x >= kDisp; }
  double d(uint32_t x, uint32_t y) const {
    if (!object(x, y) || (int(x) >= black_from && int(x) < black_to)) return 0;
    return 0.20 + 0.15 * double((x * 7 + y * 3) % 5) / 4.0;  // a texture
  }
  double a(uint32_t x, uint32_t y) const { return object(x, y) ? a_level : 0.0; }
  double b(uint32_t x, uint32_t y) const {
    if (int(y) == clip_row) return 1.5;
    return uniform_b ? 0.30 : 0.25 + 0.0005 * x + 0.004 * y;
  }
};

enum class Kind { flood, best, worst };

// Frame i of the plan as the camera records it, in `type` / `bits`.
struct Frame {
  std::vector<uint8_t> u8;
  std::vector<uint16_t> u16;
  std::vector<float> f32;
  procam_image view;
};

Frame render(const sdk::Plan& plan, uint32_t i, const Truth& t, uint32_t type, uint32_t bits, std::mt19937& rng) {
  const procam_frame_settings& s = plan.settings(i);
  Kind kind = Kind::flood;
  if (std::isfinite(s.polarizer_deg)) {
    // Crossed to the projector polariser = best (Eq. 5.4), parallel = worst (Eq. 5.5).
    const double rel = std::fmod(std::abs(s.polarizer_deg - s.projector_polarizer_deg), 180.0);
    kind = std::abs(rel - 90.0) < 1e-9 ? Kind::best : Kind::worst;
  }
  const auto pat = plan.pattern_u8(i);
  std::normal_distribution<double> noise(0.0, kNoise);
  const double fs = type == PROCAM_PIXEL_F32 ? 1.0 : double((1u << bits) - 1);
  Frame f;
  const size_t n = size_t{kCW} * kCH;
  f.u8.resize(n);
  f.u16.resize(n);
  f.f32.resize(n);
  for (uint32_t y = 0; y < kCH; ++y)
    for (uint32_t x = 0; x < kCW; ++x) {
      const double lit = x >= kDisp ? pat[size_t{y} * kPW + (x - kDisp)] / 255.0 : 0.0;
      const double d = lit * t.d(x, y), a = t.a(x, y), b = t.b(x, y);
      double v = 0;
      switch (kind) {
        case Kind::flood: v = d + a + b; break;
        case Kind::best: v = (d + a) / 2 + b * (1 - t.p) / 2; break;
        case Kind::worst: v = (d + a) / 2 + b * (1 + t.p) / 2; break;
      }
      v = std::clamp((v + noise(rng)) * fs, 0.0, fs);
      const size_t k = size_t{y} * kCW + x;
      f.u8[k] = static_cast<uint8_t>(std::lround(v));
      f.u16[k] = static_cast<uint16_t>(std::lround(v));
      f.f32[k] = static_cast<float>(v);
    }
  if (type == PROCAM_PIXEL_U8) {
    f.view = sdk::gray_view(f.u8.data(), kCW, kCH, bits);
  } else if (type == PROCAM_PIXEL_U16) {
    f.view = sdk::gray_view(f.u16.data(), kCW, kCH, bits);
  } else {
    f.view = sdk::gray_view(f.f32.data(), kCW, kCH);
  }
  return f;
}

// An F32 output map read as double (the tests compute in double).
struct Map {
  const float* p = nullptr;
  double operator[](size_t i) const { return double(p[i]); }
  explicit operator bool() const { return p != nullptr; }
};

struct ScanRun {
  sdk::Plan plan;
  mutable sdk::Outputs out;
  double fs = 255;
  const procam_output* find(const char* name) const {
    for (size_t i = 0; i < out.size(); ++i)
      if (std::strcmp(out.view()[i].name, name) == 0) return &out.view()[i];
    return nullptr;
  }
  Map map(const char* name) const {
    const procam_output* o = find(name);
    return {o ? static_cast<const float*>(o->image.data) : nullptr};
  }
  nlohmann::json report() const { return nlohmann::json::parse(find("report")->json); }
};

void scan(const std::string& method, nlohmann::json params, const Truth& t, ScanRun& r, uint32_t type = PROCAM_PIXEL_U8,
          uint32_t bits = 8, bool calibrated = false) {
  std::unique_ptr<sdk::Session> s;
  sdk::Error e = create_session({method, std::move(params), rig(bits, calibrated)}, s);
  ASSERT_TRUE(e.ok()) << e.message;
  bool has = false;
  ASSERT_TRUE(s->next_plan(r.plan, has).ok());
  ASSERT_TRUE(has);
  std::mt19937 rng(42);
  r.fs = type == PROCAM_PIXEL_F32 ? 1.0 : double((1u << bits) - 1);
  for (uint32_t i = r.plan.size(); i-- > 0;) {  // reverse order: any order must do
    const Frame f = render(r.plan, i, t, type, bits, rng);
    e = s->add_frame(i, f.view);
    ASSERT_TRUE(e.ok()) << e.message;
  }
  e = s->end_round();
  ASSERT_TRUE(e.ok()) << e.message;
  ASSERT_TRUE(s->outputs(r.out).ok());
}

// Valid pixels are finite; invalid ones NaN (never inf) in every F32 map.
void expect_no_inf(const ScanRun& r) {
  for (size_t i = 0; i < r.out.size(); ++i) {
    const procam_output& o = r.out.view()[i];
    if (o.kind != PROCAM_OUTPUT_IMAGE || o.image.pixel_type != PROCAM_PIXEL_F32) continue;
    const auto* m = static_cast<const float*>(o.image.data);
    for (size_t k = 0; k < size_t{o.image.width} * o.image.height; ++k) ASSERT_FALSE(std::isinf(m[k])) << o.name;
  }
}

TEST(Plan, FrameCountsLabelsAndPolarisers) {
  const char* methods[] = {"flood", "polarized-flood", "striping", "polarized-striping"};
  const uint32_t counts[] = {1, 2, 16, 32};
  const nlohmann::json d = describe_methods();
  for (size_t m = 0; m < 4; ++m) {
    std::unique_ptr<sdk::Session> s;
    const nlohmann::json params = m >= 2 ? nlohmann::json{{"stripes", 16}} : nlohmann::json::object();
    ASSERT_TRUE(create_session({methods[m], params, rig(8, false)}, s).ok());
    sdk::Plan plan;
    bool has = false;
    ASSERT_TRUE(s->next_plan(plan, has).ok());
    EXPECT_EQ(plan.size(), counts[m]) << methods[m];
    EXPECT_EQ(d[m]["name"], methods[m]);
    for (uint32_t i = 0; i < plan.size(); ++i) {
      const procam_frame_settings& st = plan.settings(i);
      const bool polarised = m == 1 || m == 3;
      EXPECT_EQ(std::isfinite(st.polarizer_deg), polarised);
      EXPECT_EQ(std::isfinite(st.projector_polarizer_deg), polarised);
      if (polarised) {  // even frames best (crossed, +90), odd frames worst (parallel)
        EXPECT_DOUBLE_EQ(st.projector_polarizer_deg, 0.0);
        EXPECT_DOUBLE_EQ(st.polarizer_deg, i % 2 == 0 ? 90.0 : 0.0) << i;
      }
    }
  }
  // describe(): default patterns = stripes 64 (x 2 analysers).
  EXPECT_EQ(d[2]["patterns"], 64);
  EXPECT_EQ(d[3]["patterns"], 128);
}

TEST(Params, RejectWhatCannotWork) {
  std::unique_ptr<sdk::Session> s;
  EXPECT_EQ(create_session({"striping", {{"stripes", 200}}, rig(8, false)}, s).code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(create_session({"striping", {{"stripes", 16}, {"stripe_px", 9}}, rig(8, false)}, s).code,
            PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(create_session({"flood", {{"p", 0.5}}, rig(8, false)}, s).code, PROCAM_ERR_INVALID_ARGUMENT);
  EXPECT_EQ(create_session({"striping", {{"maps", "quality"}}, rig(8, false)}, s).code, PROCAM_ERR_INVALID_ARGUMENT);
}

// The output contract (param maps): by default each method hands over the
// core maps only (image_dn, enhanced_dn, backscatter_dn; striping adds
// stripe_index and, calibrated, depth_mm/points); "all" adds cqm,
// snr_weight, gqm and stripe_col_px. The core maps, depth and the report
// are the same bits either way. image_dn is U8 for 8-bit striping scans
// (the composite is a frame value) and F32 otherwise.
TEST(Outputs, CoreMapsByDefaultAllOnRequest) {
  const char* methods[] = {"flood", "polarized-flood", "striping", "polarized-striping"};
  Truth t;
  t.a_level = 0.05;
  for (const char* m : methods)
    for (uint32_t bits : {8u, 12u}) {
      const bool striping = std::string(m).find("striping") != std::string::npos;
      const nlohmann::json base = striping ? nlohmann::json{{"stripes", 16}} : nlohmann::json::object();
      nlohmann::json all = base;
      all["maps"] = "all";
      const uint32_t type = bits == 8 ? PROCAM_PIXEL_U8 : PROCAM_PIXEL_U16;
      ScanRun core_run, all_run;
      scan(m, base, t, core_run, type, bits, striping);
      scan(m, all, t, all_run, type, bits, striping);
      const std::string label = std::string(m) + " " + std::to_string(bits) + "-bit";
      for (const char* name : {"cqm", "snr_weight", "gqm", "stripe_col_px"})
        EXPECT_EQ(core_run.find(name), nullptr) << label << ": " << name << " is opt-in";
      for (const char* name : {"cqm", "snr_weight"}) EXPECT_NE(all_run.find(name), nullptr) << label << " " << name;
      EXPECT_EQ(all_run.find("gqm") != nullptr, std::string(m) == "polarized-striping") << label;
      EXPECT_EQ(all_run.find("stripe_col_px") != nullptr, striping) << label;
      std::vector<const char*> kept = {"image_dn", "enhanced_dn", "backscatter_dn"};
      if (striping) kept.insert(kept.end(), {"stripe_index", "depth_mm"});
      for (const char* name : kept) {
        const procam_output* a = core_run.find(name);
        const procam_output* b = all_run.find(name);
        ASSERT_TRUE(a && b) << label << " " << name;
        ASSERT_EQ(a->image.pixel_type, b->image.pixel_type) << label << " " << name;
        const size_t bytes = size_t{a->image.width} * a->image.height * sdk::bytes_per_sample(a->image.pixel_type);
        EXPECT_EQ(std::memcmp(a->image.data, b->image.data, bytes), 0) << label << " " << name << ": same bits";
      }
      const uint32_t image_type = core_run.find("image_dn")->image.pixel_type;
      EXPECT_EQ(image_type, uint32_t(striping && bits == 8 ? PROCAM_PIXEL_U8 : PROCAM_PIXEL_F32)) << label;
      nlohmann::json qa = core_run.report(), qb = all_run.report();
      EXPECT_EQ(qa["quality"], qb["quality"]) << label << ": the report's means do not depend on the maps";
      EXPECT_FALSE(qa["quality"]["cqm_mean"].is_null()) << label;
      EXPECT_EQ(qa["params"]["maps"], "core");
    }
}

// Flood: uniform backscatter, the medium-only rows give B; S^ = E - B^.
TEST(Flood, SignalAndBackscatterFromTheDarkestPixels) {
  Truth t;
  t.uniform_b = true;
  ScanRun r;
  scan("flood", {{"maps", "all"}}, t, r);
  const Map s = r.map("enhanced_dn"), b = r.map("backscatter_dn"), cq = r.map("cqm");
  ASSERT_TRUE(s && b && cq);
  double worst = 0;
  for (uint32_t y = 0; y < kCH; ++y)
    for (uint32_t x = kDisp; x < kCW; ++x) {
      const size_t i = size_t{y} * kCW + x;
      const double S = t.d(x, y), B = t.b(x, y);
      worst = std::max(worst, std::abs(s[i] / r.fs - S));
      EXPECT_NEAR(b[i] / r.fs, B, 4 * kNoise + 0.5 / r.fs);             // 2 % quantile: ~ -2 sigma
      EXPECT_NEAR(cq[i], S / (S + B), 0.03);                              // Eq. 5.8, p = 0
    }
  EXPECT_LT(worst, 8 * kNoise + 1.0 / r.fs);
  expect_no_inf(r);
}

// Polarised flood with p estimated: p^, S^ (Eq. 5.6), B^ and CQM against truth.
TEST(PolarizedFlood, EstimatedDopAndSignal) {
  for (double p : {0.5, 0.8}) {
    Truth t;
    t.p = p;
    ScanRun r;
    scan("polarized-flood", {{"maps", "all"}}, t, r);
    const double p_est = r.find("dop")->scalar;
    EXPECT_NEAR(p_est, p, 0.03);
    double max_s = 0;
    const Map s = r.map("enhanced_dn"), b = r.map("backscatter_dn"), cq = r.map("cqm");
    double err_sum = 0;
    size_t n = 0;
    for (uint32_t y = 0; y < kCH; ++y)
      for (uint32_t x = 0; x < kCW; ++x) {
        const size_t i = size_t{y} * kCW + x;
        const double S = t.d(x, y) + t.a(x, y), B = t.b(x, y);
        ASSERT_TRUE(std::isfinite(s[i]));
        // Noise sqrt(2 + 2/p^2) sigma plus B dp / p from the p error.
        const double tol = 5 * kNoise * std::sqrt(2 + 2 / (p * p)) + B * 0.03 / p + 2.0 / r.fs;
        EXPECT_NEAR(s[i] / r.fs, S, tol) << x << "," << y;
        EXPECT_NEAR(b[i] / r.fs, B, tol) << x << "," << y;
        // Eq. 5.8; dCQM <= dS / (S + B(1 - p)) for an error dS of S^.
        EXPECT_NEAR(cq[i], S / (S + B * (1 - p)), tol / (S + B * (1 - p))) << x << "," << y;
        err_sum += std::abs(s[i] / r.fs - S);
        max_s = std::max(max_s, std::abs(s[i] / r.fs - S));
        ++n;
      }
    EXPECT_LT(err_sum / double(n), 3 * kNoise + 1.0 / r.fs);
    std::printf("polarized-flood p = %.1f, 8-bit, noise 0.002 FS: p^ = %.4f; |S^ - S| mean %.4f max %.4f FS\n", p, p_est,
                err_sum / double(n), max_s);
    const nlohmann::json q = r.report()["quality"];
    EXPECT_GT(q["enhanced"]["rms_contrast"].get<double>(), q["image"]["rms_contrast"].get<double>())
        << "Eq. 5.6 removes the backscatter the best image keeps: more contrast";
  }
}

// p -> 1 (given): S^ = 2 E_b is exact. p -> 0 (below p_min): Eq. 5.6 not
// applied, S^ = E_b + E_w, B^ unknown (NaN), never inf.
TEST(PolarizedFlood, DopNearOneAndNearZero) {
  Truth t;
  t.p = 1.0;
  ScanRun r1;
  scan("polarized-flood", {{"p", 1.0}}, t, r1);
  const Map s1 = r1.map("enhanced_dn");
  for (uint32_t y = 0; y < kCH; ++y)
    for (uint32_t x = 0; x < kCW; ++x)
      EXPECT_NEAR(s1[size_t{y} * kCW + x] / r1.fs, t.d(x, y), 5 * kNoise * 2 + 1.0 / r1.fs);
  t.p = 0.01;
  ScanRun r0;
  scan("polarized-flood", {{"p", 0.01}}, t, r0);
  EXPECT_EQ(r0.find("dop")->scalar, 0.0);
  const Map s0 = r0.map("enhanced_dn"), b0 = r0.map("backscatter_dn");
  for (uint32_t y = 0; y < kCH; ++y)
    for (uint32_t x = 0; x < kCW; ++x) {
      const size_t i = size_t{y} * kCW + x;
      EXPECT_NEAR(s0[i] / r0.fs, t.d(x, y) + t.b(x, y), 10 * kNoise + 1.0 / r0.fs);
      EXPECT_TRUE(std::isnan(b0[i]));
    }
  EXPECT_TRUE(r0.report().contains("notes"));
  expect_no_inf(r0);
}

// Which stripe lights camera pixel x (from the plan's patterns), or -1.
std::vector<int> true_stripes(const sdk::Plan& plan, uint32_t frames_per_stripe) {
  std::vector<int> k(kCW, -1);
  for (uint32_t i = 0; i < plan.size(); i += frames_per_stripe) {
    const auto pat = plan.pattern_u8(i);
    for (uint32_t x = kDisp; x < kCW; ++x)
      if (pat[x - kDisp] == 255) k[x] = int(i / frames_per_stripe);
  }
  return k;
}

// Striping (A = 0): every lit pixel gets its own stripe, gaps and medium-only
// pixels none; D^ = D, B^ = B, CQM = D / (D + B); depth = f b / (x - column).
TEST(Striping, StripeMapSignalBackscatterAndDepth) {
  Truth t;
  ScanRun r;
  scan("striping", {{"stripes", 16}, {"maps", "all"}}, t, r, PROCAM_PIXEL_U8, 8, true);
  const std::vector<int> truth_k = true_stripes(r.plan, 1);
  const Map k = r.map("stripe_index"), col = r.map("stripe_col_px"), s = r.map("enhanced_dn"),
              b = r.map("backscatter_dn"), cq = r.map("cqm"), z = r.map("depth_mm");
  ASSERT_TRUE(k && col && s && b && cq && z);
  size_t lit = 0;
  for (uint32_t y = 0; y < kCH; ++y)
    for (uint32_t x = 0; x < kCW; ++x) {
      const size_t i = size_t{y} * kCW + x;
      const bool expect = truth_k[x] >= 0 && t.object(x, y);
      ASSERT_EQ(std::isfinite(k[i]), expect) << x << "," << y;
      EXPECT_NEAR(b[i] / r.fs, t.b(x, y), 4 * kNoise + 1.0 / r.fs);
      if (!expect) continue;
      ++lit;
      EXPECT_EQ(k[i], double(truth_k[x]));
      // The lit run of the pattern: its centre column, and the depth its plane gives.
      const auto pat = r.plan.pattern_u8(uint32_t(truth_k[x]));
      double first = -1, last = -1;
      for (uint32_t c = 0; c < kPW; ++c)
        if (pat[c] == 255) last = c, first = first < 0 ? c : first;
      const double centre = (first + last) / 2;
      EXPECT_NEAR(col[i], centre, 1e-4);
      EXPECT_NEAR(z[i], kF * kBaseline / (double(x) - centre), 1e-3 * z[i]);
      EXPECT_NEAR(s[i] / r.fs, t.d(x, y), 6 * kNoise + 1.0 / r.fs);
      EXPECT_NEAR(cq[i], t.d(x, y) / (t.d(x, y) + t.b(x, y)), 0.03);  // Eq. 5.8 with A = 0, p = 0
    }
  EXPECT_GT(lit, 100u);
  EXPECT_TRUE(r.report()["quality"]["gqm_mean"].is_null()) << "unpolarised: A and B are not separable";
  expect_no_inf(r);
}

// Hard cases: a black band (zero signal under its stripes) and a row whose
// backscatter clips: both invalid, never a wrong stripe; 8/12/16-bit and F32
// frames give the same stripes.
TEST(Striping, ZeroSignalSaturatedBackscatterAndBitDepths) {
  Truth t;
  t.black_from = 120;
  t.black_to = 150;
  t.clip_row = 7;
  const std::pair<uint32_t, uint32_t> formats[] = {{PROCAM_PIXEL_U8, 8}, {PROCAM_PIXEL_U16, 12},
                                                   {PROCAM_PIXEL_U16, 16}, {PROCAM_PIXEL_F32, 32}};
  for (const auto& [type, bits] : formats) {
    ScanRun r;
    scan("striping", {{"stripes", 16}}, t, r, type, bits);
    const std::vector<int> truth_k = true_stripes(r.plan, 1);
    const Map k = r.map("stripe_index"), s = r.map("enhanced_dn"), b = r.map("backscatter_dn");
    size_t valid = 0;
    for (uint32_t y = 0; y < kCH; ++y)
      for (uint32_t x = 0; x < kCW; ++x) {
        const size_t i = size_t{y} * kCW + x;
        const bool expect = truth_k[x] >= 0 && t.d(x, y) > 0 && int(y) != t.clip_row;
        ASSERT_EQ(std::isfinite(k[i]), expect) << bits << " bit " << x << "," << y;
        ASSERT_EQ(std::isfinite(s[i]), expect);
        if (int(y) == t.clip_row) {
          EXPECT_TRUE(std::isnan(b[i]));
        }
        if (!expect) continue;
        ++valid;
        EXPECT_EQ(k[i], double(truth_k[x]));
        EXPECT_NEAR(s[i] / r.fs, t.d(x, y), 6 * kNoise + 1.0 / r.fs) << bits;
      }
    EXPECT_GT(valid, 80u) << bits;
    EXPECT_NEAR(r.find("valid_fraction")->scalar, double(valid) / double(kCW * kCH), 1e-9);
    expect_no_inf(r);
  }
}

// Polarised striping with indirect light A: p^, D^, A^ (through S^ = D^ + A^),
// B^ and the quality measures against Eq. 5.8–5.10 on the truth.
// 8-bit frames take the packed state, 12-bit ones the general one.
class PolarizedStriping : public ::testing::TestWithParam<std::pair<uint32_t, uint32_t>> {};

TEST_P(PolarizedStriping, SeparatesDirectIndirectAndBackscatter) {
  const auto [type, bits] = GetParam();
  Truth t;
  t.a_level = 0.05;
  ScanRun r;
  scan("polarized-striping", {{"stripes", 16}, {"maps", "all"}}, t, r, type, bits);
  EXPECT_NEAR(r.find("dop")->scalar, t.p, 0.03);
  const std::vector<int> truth_k = true_stripes(r.plan, 2);
  const Map k = r.map("stripe_index"), s = r.map("enhanced_dn"), b = r.map("backscatter_dn"),
              cq = r.map("cqm"), gq = r.map("gqm"), w = r.map("snr_weight");
  ASSERT_TRUE(k && s && b && cq && gq && w);
  const nlohmann::json rep = r.report();
  const double mu = rep["snr_weight"]["mu_dn"], z = rep["snr_weight"]["z_dn"];
  size_t lit = 0;
  double err_s = 0, err_b = 0, err_cqm = 0, err_gqm = 0;  // worst |estimate - truth| over stripe pixels
  for (uint32_t y = 0; y < kCH; ++y)
    for (uint32_t x = 0; x < kCW; ++x) {
      const size_t i = size_t{y} * kCW + x;
      const bool expect = truth_k[x] >= 0 && t.object(x, y);
      ASSERT_EQ(std::isfinite(k[i]), expect) << x << "," << y;
      const double D = t.d(x, y), A = t.a(x, y), B = t.b(x, y), p = t.p;
      EXPECT_NEAR(b[i] / r.fs, B, 0.03 * B / p + 4 * kNoise + 1.0 / r.fs);
      if (!expect) continue;
      ++lit;
      EXPECT_EQ(k[i], double(truth_k[x]));
      err_s = std::max(err_s, std::abs(s[i] / r.fs - (D + A)));
      err_b = std::max(err_b, std::abs(b[i] / r.fs - B));
      err_cqm = std::max(err_cqm, std::abs(cq[i] - (D + A) / (D + A + B * (1 - p))));
      err_gqm = std::max(err_gqm, std::abs(gq[i] - (D + B * (1 - p)) / (D + A + B * (1 - p))));
      EXPECT_NEAR(s[i] / r.fs, D + A, 0.03 * B / p + 12 * kNoise + 2.0 / r.fs);
      EXPECT_NEAR(cq[i], (D + A) / (D + A + B * (1 - p)), 0.03);                   // Eq. 5.8
      EXPECT_NEAR(gq[i], (D + B * (1 - p)) / (D + A + B * (1 - p)), 0.03);         // Eq. 5.9
      EXPECT_NEAR(w[i], 1 / (1 + std::exp(-((D + A) * r.fs - mu) / z)), 0.01);     // Eq. 5.10
    }
  EXPECT_GT(lit, 100u);
  std::printf("polarized-striping %u-bit, noise 0.002 FS: |p^ - p| %.4f; max |S^ - S| %.4f FS, |B^ - B| %.4f FS, "
              "|CQM^ - CQM| %.4f, |GQM^ - GQM| %.4f over %zu stripe pixels\n",
              bits, std::abs(r.find("dop")->scalar - t.p), err_s, err_b, err_cqm, err_gqm, lit);
  const nlohmann::json q = rep["quality"];
  EXPECT_GT(q["cqm_mean"].get<double>(), 0.5);
  EXPECT_FALSE(q["gqm_w_mean"].is_null());
  expect_no_inf(r);
}

INSTANTIATE_TEST_SUITE_P(Formats, PolarizedStriping,
                         ::testing::Values(std::pair<uint32_t, uint32_t>{PROCAM_PIXEL_U8, 8},
                                           std::pair<uint32_t, uint32_t>{PROCAM_PIXEL_U16, 12}));

}  // namespace
}  // namespace procam::polarized_striping
