// SPDX-License-Identifier: MIT
// The defocus plugin's parameters, method descriptions and plan (see sweep_plan.hpp).
#include "sweep_plan.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace procam::defocus {
namespace {

using sdk::ParamSpec;
using sdk::ParamType;

std::vector<ParamSpec> common_specs() {
  return {
      {"prefilter_sigma_px", ParamType::number, 1.0, 0.0, 4.0, {},
       "Gaussian pre-filter of the stripes in projector px (thesis sec. 2.4, footnote 5). 1 px keeps 73 % of the "
       "3rd harmonic (the signal) but cuts harmonics with periods under 2.7 px below 6 %, which camera sampling "
       "would alias into stripes in the depth map. 0: binary stripes."},
      {"black_fraction", ParamType::number, 0.02, 0.0, 0.5, {},
       "pixels whose mean is below this fraction of full scale are black or unlit: invalid"},
      {"min_modulation", ParamType::number, 0.02, 0.0, 1.0, {},
       "E(3, f) below this fraction of the mean counts as no pattern (about 3x the 8-bit sim's noise in E at "
       "mid-grey): such settings are never divided by or interpolated through"},
  };
}

std::vector<ParamSpec> sweep_specs() {
  auto s = common_specs();
  s.insert(s.begin(), {
      {"near_mm", ParamType::number, 600.0, 50.0, 1e5, {},
       "nearest focus setting, mm. Focus settings are uniform in 1/f from near_mm to far_mm; a depth is measured "
       "when its peak lies inside the sweep, i.e. about half a step inside either end. The defaults bracket the "
       "sim-colocated rig's working range around 800 mm (about 650-1090 mm valid) with one step to spare: set "
       "them to the scene's depth range widened by one step."},
      {"far_mm", ParamType::number, 1200.0, 50.0, 1e5, {}, "farthest focus setting, mm (see near_mm)"},
      {"focus_count", ParamType::integer, 6, 3, 32, {},
       "focus settings F (>= 3 for an inner peak). The thesis used 6-8; with the sim-colocated rig's 15 mm "
       "aperture, 6 settings over 600-1200 mm are spaced ~0.8 of E(f)'s Gaussian width, so the peak and both "
       "neighbours are well above noise"},
  });
  return s;
}

std::vector<ParamSpec> specs_of(const std::string& method) {
  if (method.rfind("calibrate-", 0) == 0) {  // the scan method's parameters, plus the table's resolution
    auto s = specs_of(method.substr(std::string("calibrate-").size()));
    s.push_back({"bins", ParamType::integer, 32, 2, 4096, {},
                 "table samples: the plane's pixels are split into this many equal-count bins by the cue, each "
                 "giving (median cue, median depth); 32 resolve the curve while each bin still holds thousands of "
                 "pixels of a 320x200 or larger camera"});
    return s;
  }
  if (method == "two-focal") {
    auto s = common_specs();
    s.insert(s.begin(), {
        {"f1_mm", ParamType::number, 700.0, 50.0, 1e5, {},
         "first focus setting (Omega's denominator), mm. 700 and 950 mm keep both E values measurable over "
         "~650-1100 mm with the sim-colocated rig's aperture; closer settings give a flatter Omega"},
        {"f2_mm", ParamType::number, 950.0, 50.0, 1e5, {}, "second focus setting (numerator), mm; != f1_mm"},
    });
    return s;
  }
  if (method == "single-focal") {
    auto s = common_specs();
    s.insert(s.begin(), {{"focus_mm", ParamType::number, 700.0, 50.0, 1e5, {},
                          "the one focus setting, mm: in front of the scene (Zhang & Nayar 2006), so the blur "
                          "grows monotonically with depth over the working range"}});
    return s;
  }
  auto s = sweep_specs();
  if (method == "invariance")
    s.push_back({"pairs", ParamType::string, "", 0, 0, {},
                 "pixel pairs for Eq. 2.8 as \"xB,yB,xA,yA;...\": B receives global light, A lies at the same depth "
                 "without it (e.g. on the paper sleeve above the candle's wax); empty: per-pixel maps only"});
  return s;
}

sdk::Error parse_pairs(const std::string& text, uint32_t w, uint32_t h, std::vector<PixelPair>& pairs) {
  pairs.clear();
  std::stringstream all(text);
  std::string item;
  while (std::getline(all, item, ';')) {
    if (item.find_first_not_of(" ") == std::string::npos) continue;
    long v[4];
    char c1 = 0, c2 = 0, c3 = 0;
    std::stringstream one(item);
    one >> v[0] >> c1 >> v[1] >> c2 >> v[2] >> c3 >> v[3];
    std::string rest;
    one >> rest;
    if (one.fail() && !one.eof()) one.clear();
    if (c1 != ',' || c2 != ',' || c3 != ',' || !rest.empty() || v[0] < 0 || v[1] < 0 || v[2] < 0 || v[3] < 0 ||
        v[0] >= long(w) || v[2] >= long(w) || v[1] >= long(h) || v[3] >= long(h))
      return sdk::invalid_argument("parameter 'pairs': \"" + item + "\" is not xB,yB,xA,yA inside the " +
                                   std::to_string(w) + "x" + std::to_string(h) + " camera image");
    pairs.push_back({uint32_t(v[0]), uint32_t(v[1]), uint32_t(v[2]), uint32_t(v[3])});
  }
  return sdk::ok();
}

const char* kOutputsCommon[] = {"mean_dn", "valid", "decode_ms", "pattern_count", "valid_fraction", "report"};

}  // namespace

double relative_variation(const std::vector<double>& v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  if (!(*hi > 0)) return std::numeric_limits<double>::quiet_NaN();
  return (*hi - *lo) / *hi;
}

std::vector<sdk::MethodDescription> method_descriptions() {
  auto with_common = [](std::vector<std::string> o) {
    for (const char* c : kOutputsCommon) o.emplace_back(c);
    return o;
  };
  std::vector<sdk::MethodDescription> d(7);
  d[0] = {"multi-focal",
          "depth under global light from a focal sweep (thesis sec. 2.4.1, Eq. 2.9): fbar = argmax_f E(3, f) by "
          "Gaussian interpolation, through table defocus.multi-focal",
          6 * 24, "24 * focus_count", 1, "", with_common({"depth_mm", "fbar", "e3_peak_dn"}), specs_of("multi-focal"), {}};
  d[1] = {"two-focal",
          "depth under global light from two focus settings (sec. 2.4.2, Eq. 2.10): Omega = E(f2)/E(f1) through "
          "table defocus.two-focal",
          48, "", 1, "", with_common({"depth_mm", "omega", "e3_peak_dn"}), specs_of("two-focal"), {}};
  d[2] = {"single-focal",
          "baseline (Zhang & Nayar 2006): depth from the blur E/mean at one focus setting through table "
          "defocus.single-focal; global light corrupts it",
          24, "", 1, "", with_common({"depth_mm", "modulation", "e3_peak_dn"}), specs_of("single-focal"), {}};
  d[3] = {"invariance",
          "diagnostic (sec. 2.3.2, Eq. 2.8): E(3, f) maps over a focal sweep, fbar, and G(f) = E_B/E_A at given "
          "pixel pairs of equal depth in the report",
          6 * 24, "24 * focus_count", 1, "", with_common({"fbar", "e3_f0_dn", "e3_f1_dn", "e3_f2_dn"}),
          specs_of("invariance"), {}};
  // Calibration methods (docs/calibration.md): the same sweep on a plane
  // whose depth comes in as input depth_mm; output the table.
  const char* bases[3] = {"multi-focal", "two-focal", "single-focal"};
  for (size_t k = 0; k < 3; ++k) {
    sdk::MethodDescription& c = d[4 + k];
    c = d[k];
    c.name = std::string("calibrate-") + bases[k];
    c.summary = std::string("calibration of ") + bases[k] + ": the same frames on an inclined matte plane plus its "
                "depth (input depth_mm, e.g. structured light's depth_mm of the plane); outputs the table " +
                "defocus." + bases[k] + " as calibration_table";
    c.outputs = with_common({"calibration_table", k == 0 ? "fbar" : (k == 1 ? "omega" : "modulation")});
    c.params = specs_of(c.name);
    c.inputs = {{"depth_mm", "image_f32", "mm", true,
                 "depth of every camera pixel of the calibration plane (NaN unknown): structured-light's depth_mm "
                 "of the same plane from a rig that can triangulate, or a known plane's depth"}};
  }
  return d;
}

sdk::Error parse_sweep_config(const std::string& method_name, const nlohmann::json& params, const sdk::Rig& rig,
                              SweepConfig& config, std::vector<PixelPair>& pairs) {
  sdk::Params p;
  if (sdk::Error e = sdk::parse_params(params, specs_of(method_name), p, method_name); !e.ok()) return e;
  const bool calibrate = method_name.rfind("calibrate-", 0) == 0;
  const std::string method = calibrate ? method_name.substr(std::string("calibrate-").size()) : method_name;
  config = SweepConfig{};
  config.prefilter_sigma_px = p.get_number("prefilter_sigma_px");
  config.black_fraction = p.get_number("black_fraction");
  config.validity.min_modulation = p.get_number("min_modulation");
  if (calibrate) config.table_bins = static_cast<size_t>(p.get_int("bins"));
  if (method == "two-focal") {
    const double f1 = p.get_number("f1_mm"), f2 = p.get_number("f2_mm");
    if (std::abs(f1 - f2) < 1e-6 * f1)
      return sdk::invalid_argument("parameters 'f1_mm' and 'f2_mm' must differ (both " + std::to_string(f1) +
                                   " mm): Omega compares two focus settings");
    config.focus_mm = {f1, f2};
  } else if (method == "single-focal") {
    config.focus_mm = {p.get_number("focus_mm")};
  } else {
    const double near = p.get_number("near_mm"), far = p.get_number("far_mm");
    if (!(far > near))
      return sdk::invalid_argument("parameter 'far_mm' (" + std::to_string(far) + ") must be above 'near_mm' (" +
                                   std::to_string(near) + ")");
    config.focus_mm = focus_sweep_mm(near, far, static_cast<uint32_t>(p.get_int("focus_count")));
  }
  pairs.clear();
  if (method == "invariance")
    return parse_pairs(p.get_string("pairs"), rig.cameras[0].width, rig.cameras[0].height, pairs);
  return sdk::ok();
}

void add_sweep_frames(sdk::Plan& plan, uint32_t proj_width, uint32_t proj_height, const SweepConfig& config) {
  for (size_t k = 0; k < config.focus_mm.size(); ++k)
    for (uint32_t t = 0; t < kPeriodPx; ++t) {
      const uint32_t i = plan.add_frame("focus " + std::to_string(k) + " shift " + std::to_string(t), proj_width,
                                        proj_height);
      sdk::smoothed_stripes(plan, i, sdk::StripeAxis::vertical, kPeriodPx, int64_t{t}, config.prefilter_sigma_px);
      plan.settings(i).projector_focus_mm = config.focus_mm[k];
    }
}

nlohmann::json invariance_summary(const E3Accumulator& acc, const std::vector<PixelPair>& pairs) {
  nlohmann::json out = nlohmann::json::array();
  const uint32_t w = acc.width();
  for (const PixelPair& pr : pairs) {
    const size_t b = size_t{pr.yb} * w + pr.xb, a = size_t{pr.ya} * w + pr.xa;
    std::vector<double> g, eb, ea;
    bool ok = !acc.saturated(pr.xa, pr.ya) && !acc.saturated(pr.xb, pr.yb);
    for (uint32_t f = 0; f < acc.focus_count(); ++f) {
      eb.push_back(acc.e3(f)[b]);
      ea.push_back(acc.e3(f)[a]);
      ok = ok && ea.back() > 0;
      g.push_back(ea.back() > 0 ? eb.back() / ea.back() : 0.0);
    }
    nlohmann::json j = {{"b", {pr.xb, pr.yb}}, {"a", {pr.xa, pr.ya}}, {"e3_b_dn", eb}, {"e3_a_dn", ea},
                        {"valid", ok}};
    if (ok) {
      j["g"] = g;  // Eq. 2.8: G_B(f) / alpha_A
      j["g_variation"] = relative_variation(g);
      j["e3_b_variation"] = relative_variation(eb);
    }
    out.push_back(std::move(j));
  }
  return out;
}

}  // namespace procam::defocus
