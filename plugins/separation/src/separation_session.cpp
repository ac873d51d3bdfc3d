// SPDX-License-Identifier: MIT
// The separation plugin's sessions (see separation_session.hpp).
#include "separation_session.hpp"

#include <cmath>
#include <span>

#include "extrema.hpp"
#include "procam/sdk/calibration_table.hpp"
#include "separation.hpp"

namespace procam::separation {
namespace {

enum class Method { checker, checker_pair, multi_focal, one_focal, calibrate };

Method method_of(const std::string& m) {
  if (m == "checker-pair") return Method::checker_pair;
  if (m == "multi-focal") return Method::multi_focal;
  if (m == "one-focal-depth") return Method::one_focal;
  if (m == "calibrate-one-focal") return Method::calibrate;
  return Method::checker;
}

// ---- parameters -------------------------------------------------------------

using sdk::ParamSpec;
using sdk::ParamType;

// S3 and its calibration default to finer shifts (8 x 8 by 2 px): they divide
// by a β⁺ − β⁻ that depends on depth only, but β⁺ − β⁻ also depends on how
// close the best shift puts a square's centre to the pixel (within 1.5 px at
// a 3 px step, 1 px at 2 px); on the sim's V-groove that phase spread moved
// S3's median global error from 7 % to 4 % (sim_claims_test).
std::vector<ParamSpec> checker_geometry(bool fine = false) {
  if (fine)
    return {{"square_px", ParamType::integer, 8, 2, 256, {}, "checker square side in projector pixels, as S1"},
            {"shifts", ParamType::integer, 8, 2, 16, {},
             "shifts per axis; 8 (64 frames), finer than S1's 5: the one-focus contrast table holds for every pixel "
             "only when the best shift centres a square on it within ~1 px"},
            {"step_px", ParamType::integer, 2, 1, 64, {},
             "shift step in projector pixels; 2 (with 8 shifts every even offset of the 16 px period)"}};
  return {{"square_px", ParamType::integer, 8, 2, 256, {},
           "checker square side in projector pixels; 8 as in thesis §2.5 and Nayar et al. 2006: fine enough that "
           "inter-reflected light averages over many squares (half of it reaches every pixel), coarse enough to "
           "survive a little defocus and the camera's sampling"},
          {"shifts", ParamType::integer, 5, 2, 16, {},
           "shifts per axis (shifts x shifts frames per focus setting); 5 as in the thesis"},
          {"step_px", ParamType::integer, 3, 1, 64, {},
           "shift step in projector pixels; 3 as in the thesis; (shifts - 1) * step_px must be >= square_px so "
           "every pixel is fully lit and fully dark in some frame"}};
}

std::vector<ParamSpec> common_params() {
  return {{"black_frame", ParamType::boolean, true, 0, 0, {},
           "project one all-black frame last and subtract it: removes the projector's black level and ambient "
           "light from both components (without it ambient light is counted as global)"},
          {"black_level", ParamType::number, 0.01, 0.0, 0.5, {},
           "light the projector emits for pattern value 0, as a fraction of white; 0.01 (100:1, the simulated "
           "rig's value and a typical LCD/DLP); measure yours as (black frame) / (white frame) on a matte card in "
           "the dark"},
          {"dark_fraction", ParamType::number, 0.01, 0.0, 1.0, {},
           "pixels whose brightest normalised signal is below this fraction of full scale are invalid (too dark "
           "to separate: shadows, black surfaces); 0.01 is ~2.5 DN at 8 bits, about the sim's noise"}};
}

ParamSpec focus_param(const char* why) {
  return {"focus_mm", ParamType::number, 0.0, 0.0, 1e6, {}, why};
}

std::vector<ParamSpec> specs_for(Method m) {
  std::vector<ParamSpec> p;
  if (m == Method::checker_pair) {
    p.push_back({"square_px", ParamType::integer, 8, 2, 256, {},
                 "checker square side in projector pixels; the inverse is the board shifted by one square"});
  } else {
    p = checker_geometry(m == Method::one_focal || m == Method::calibrate);
  }
  for (ParamSpec& s : common_params()) p.push_back(std::move(s));
  switch (m) {
    case Method::checker:
    case Method::checker_pair:
      p.push_back(focus_param("projector focus for every frame, mm; 0 = the rig's default. S1 assumes the scene is "
                              "in focus: anything else under-estimates direct light (thesis Fig. 2.16)"));
      break;
    case Method::multi_focal:
      p.push_back({"focus_settings", ParamType::integer, 6, 3, 32, {},
                   "focus settings F (>= 3 for an interior extremum); 6 as the thesis used 6-8: the blur must "
                   "change by ~1 projector pixel or less between settings for the Gaussian interpolation to hold"});
      p.push_back({"focus_near_mm", ParamType::number, 600.0, 1.0, 1e6, {},
                   "nearest focus setting, mm; put it in front of the nearest scene point"});
      p.push_back({"focus_far_mm", ParamType::number, 1200.0, 1.0, 1e6, {},
                   "farthest focus setting, mm; behind the farthest scene point. Settings are equally spaced in "
                   "1/focus, where the thin-lens blur is linear"});
      p.push_back({"tie_fraction", ParamType::number, 0.005, 0.0, 1.0, {},
                   "an end setting may beat the best interior one by at most this fraction of full scale (noise) "
                   "and still count as an extremum inside the sweep; beyond it the pixel is invalid, never "
                   "extrapolated"});
      break;
    case Method::one_focal:
      p.push_back(focus_param("projector focus, mm (0 = rig default); must be the focus the calibration table "
                              "was made at"));
      p.push_back({"min_contrast", ParamType::number, 0.1, 0.001, 1.0, {},
                   "smallest beta+ - beta- (Eq. 2.17's denominator) accepted; below it noise is amplified more "
                   "than 10x and the pixel is invalid"});
      break;
    case Method::calibrate:
      p.push_back(focus_param("projector focus, mm (0 = rig default); scans that use the table must use the same"));
      p.push_back({"bins", ParamType::integer, 24, 2, 1000, {},
                   "depth bins of the table (equal pixel counts, median per bin)"});
      p.push_back({"window_px", ParamType::integer, 0, 0, 1024, {},
                   "camera pixels over which beta+ - beta- is averaged before the fit (it depends on where a pixel "
                   "falls on the checker grid); 0 = one pattern period, 2 * square_px, right for about one camera "
                   "pixel per projector pixel; 1 = no averaging"});
      break;
  }
  return p;
}

// ---- the session ------------------------------------------------------------

struct Config {
  Method method = Method::checker;
  std::string method_name;
  uint32_t square = 8, shifts = 5, step = 3;
  bool black_frame = true;
  std::vector<double> focus_mm;  // per focus slot; 0 = rig default
  Settings settings;
  uint32_t bins = 24;
  uint32_t window = 16;  // calibration: contrast averaging window, camera px
  sdk::Params params;
};

enum class Role : uint8_t { checker, white, black };

class SeparationSession final : public sdk::Session {
 public:
  SeparationSession(Config cfg, const sdk::Rig& rig, std::vector<float> depth, sdk::CalibrationTable table)
      : cfg_(std::move(cfg)), rig_(rig), depth_(std::move(depth)), table_(std::move(table)) {
    const auto& cam = rig_.cameras[0];
    for (size_t k = 0; k < cfg_.focus_mm.size(); ++k) per_focus_.emplace_back(cam.width, cam.height);
    white_ = Extrema(cam.width, cam.height);
    black_ = Extrema(cam.width, cam.height);
  }

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (planned_) return sdk::ok();
    const uint32_t pw = rig_.projector_width, ph = rig_.projector_height;
    for (size_t k = 0; k < cfg_.focus_mm.size(); ++k) {
      const std::string label = cfg_.focus_mm.size() > 1 ? "focus " + std::to_string(k) + " checker" : "checker";
      const uint32_t first = plan.size();
      if (cfg_.method == Method::checker_pair) {
        plan.add_frame(label, pw, ph);
        sdk::checkerboard(plan, first, cfg_.square, 0, 0);
        plan.add_frame(label + " inverse", pw, ph);
        sdk::checkerboard(plan, first + 1, cfg_.square, cfg_.square, 0);
      } else {
        sdk::add_shifted_checkerboards(plan, label, pw, ph, cfg_.square, cfg_.shifts, cfg_.step);
      }
      for (uint32_t i = first; i < plan.size(); ++i) {
        plan.settings(i).projector_focus_mm = cfg_.focus_mm[k];
        roles_.push_back({Role::checker, uint32_t(k)});
      }
    }
    if (needs_white()) {
      const uint32_t i = plan.add_frame("white", pw, ph);
      sdk::fill_pattern(plan, i, [](uint32_t, uint32_t) { return 1.0; });
      plan.settings(i).projector_focus_mm = cfg_.focus_mm[0];
      roles_.push_back({Role::white, 0});
    }
    if (cfg_.black_frame) {
      const uint32_t i = plan.add_frame("black", pw, ph);  // zero-filled
      plan.settings(i).projector_focus_mm = cfg_.focus_mm[0];
      roles_.push_back({Role::black, 0});
    }
    plan.set_note(cfg_.method_name + ": " + std::to_string(plan.size()) + " frames (see report)");
    pattern_count_ = plan.size();
    planned_ = has_round = true;
    return sdk::ok();
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    const sdk::ScopedMs timer(decode_ms_);
    const auto& cam = rig_.cameras[0];
    const auto [role, slot] = roles_.at(index);
    if (sdk::Error e = sdk::check_frame(&frame, cam.width, cam.height, 1, "frame " + std::to_string(index)); !e.ok())
      return e;
    if (seen_type_ == 0) {
      seen_type_ = frame.pixel_type;
      cfg_.settings.full_scale = sdk::full_scale(frame);
      cfg_.settings.integer_frames = frame.pixel_type != PROCAM_PIXEL_F32;
    } else if (frame.pixel_type != seen_type_ || sdk::full_scale(frame) != cfg_.settings.full_scale) {
      return sdk::bad_frame("frame " + std::to_string(index) + " is " + sdk::describe_image(frame) +
                            " but earlier frames of this scan differ: keep one camera mode for the whole scan");
    }
    Extrema& target = role == Role::checker ? per_focus_[slot] : (role == Role::white ? white_ : black_);
    return target.add(frame, rig_.threads);
  }

  sdk::Error end_round() override {
    const sdk::ScopedMs timer(decode_ms_);
    const Extrema* black = cfg_.black_frame ? &black_ : nullptr;
    switch (cfg_.method) {
      case Method::checker:
      case Method::checker_pair: separate_checker(per_focus_[0], black, cfg_.settings, maps_); break;
      case Method::multi_focal: separate_multi_focal(per_focus_, black, cfg_.settings, maps_); break;
      case Method::one_focal:
        separate_one_focal(per_focus_[0], white_, black, depth_, table_, cfg_.settings, maps_);
        break;
      case Method::calibrate: return calibrate();
    }
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    const sdk::ScopedMs timer(decode_ms_);
    const auto& cam = rig_.cameras[0];
    sdk::StandardOutputs std_out;
    std_out.pattern_count = pattern_count_;
    std_out.total_pixels = size_t{cam.width} * cam.height;
    std_out.report = report();
    if (cfg_.method == Method::calibrate) {
      std_out.valid_pixels = calibration_pixels_;
      if (!table_json_.is_null())
        out.add_json("calibration_table",
                   "table 'separation.one-focal-depth': beta+ - beta- (Eq. 2.19) against depth, for one-focal-depth",
                   table_json_.dump());
    } else {
      std_out.valid_pixels = maps_.valid;
      // The maps move into the outputs (outputs() runs once per round; the
      // SDK keeps the result) and go back to the map cache at session_destroy.
      out.set_release(sdk::give_map, sdk::give_map);
      out.add_image("direct_dn", "DN", "direct component L_d under full-white light (NaN: invalid)", cam.width,
                    cam.height, std::move(maps_.direct));
      out.add_image("global_dn", "DN", "global component L_g under full-white light (NaN: invalid)", cam.width,
                    cam.height, std::move(maps_.global));
      if (!maps_.best_focus.empty()) out.add_image("best_focus_mm", "mm", best_focus_description(), cam.width,
                                                   cam.height, best_focus_mm());
    }
    std_out.decode_ms = decode_ms_;
    sdk::add_standard_outputs(out, std_out);
    return sdk::ok();
  }

 private:
  bool needs_white() const { return cfg_.method == Method::one_focal || cfg_.method == Method::calibrate; }

  static std::string best_focus_description() {
    return "focus setting at which e+ peaks (Gaussian interpolation, thesis §2.5.1), mm; NaN: invalid";
  }

  // Fractional slot index -> focus in mm: slots are equally spaced in 1/focus.
  std::vector<float> best_focus_mm() const {
    std::vector<float> mm(maps_.best_focus.size(), kNaN);
    const double u0 = 1.0 / cfg_.focus_mm.front(), u1 = 1.0 / cfg_.focus_mm.back();
    const double du = (u1 - u0) / double(cfg_.focus_mm.size() - 1);
    for (size_t i = 0; i < mm.size(); ++i)
      if (std::isfinite(maps_.best_focus[i])) mm[i] = static_cast<float>(1.0 / (u0 + du * double(maps_.best_focus[i])));
    return mm;
  }

  sdk::Error calibrate() {
    std::vector<float> depths, contrasts;
    plane_contrast_samples(per_focus_[0], white_, cfg_.black_frame ? &black_ : nullptr, depth_, cfg_.settings,
                           cfg_.window, depths, contrasts);
    calibration_pixels_ = 0;
    for (float c : contrasts) calibration_pixels_ += std::isfinite(c) ? 1u : 0u;
    sdk::CalibrationTable t;
    t.name = kOneFocalTable;
    t.x_name = "depth";
    t.x_unit = "mm";
    t.y_name = "contrast";
    t.y_unit = "ratio";
    t.extra = {{"focus_mm", cfg_.focus_mm[0]}, {"square_px", cfg_.square}, {"shifts", cfg_.shifts},
               {"step_px", cfg_.step}, {"quantity", "beta+ - beta- (thesis Eq. 2.19)"}};
    t.made = {{"plugin", "separation"}, {"method", "calibrate-one-focal"}};
    // A plane that gives no table (unlit, flat, wrong focus) is a finished
    // scan without a calibration_table: the report says why (table_error),
    // and `procam calibrate` passes that on.
    if (sdk::Error e = sdk::fit_monotonic(depths, contrasts, cfg_.bins, t); !e.ok()) {
      table_error_ = "calibrate-one-focal: " + e.message +
                     " (scan a matte plane with no global light, tilted across the depths to calibrate, with the "
                     "focal plane in front of all of it)";
      return sdk::ok();
    }
    table_json_ = sdk::to_json(t);
    return sdk::ok();
  }

  nlohmann::json report() const {
    nlohmann::json r = {{"method", cfg_.method_name}, {"params", cfg_.params.json()},
                        {"patterns", pattern_count_}, {"focus_settings_mm", cfg_.focus_mm}};
    if (!table_error_.empty()) r["table_error"] = table_error_;
    switch (cfg_.method) {
      case Method::checker:
      case Method::checker_pair:
        r["model"] = "S1, Nayar et al. 2006 (thesis §2.5, Eq. 2.15-2.16 with beta+ = 1, beta- = 0): "
                     "direct = max - min, global = 2 min over the checker frames; assumes the scene is in focus";
        break;
      case Method::multi_focal:
        r["model"] = "S2 (thesis §2.5.1): per focus setting the max/min images e+(f), e-(f); their extrema over f "
                     "by Gaussian interpolation are the in-focus max/min (Eq. 2.15-2.16): direct = e+ - e-, "
                     "global = 2 e-; O(pixels x F) state";
        break;
      case Method::one_focal:
        r["model"] = "S3 (thesis §2.5.2): direct = (e+ - e-) / (beta+ - beta-)(depth) (Eq. 2.17), global = "
                     "white - direct (Eq. 2.18); beta+ - beta- from table 'separation.one-focal-depth'";
        r["table_samples"] = table_.samples.size();
        break;
      case Method::calibrate:
        r["model"] = "Eq. 2.19 on a plane without global light: beta+ - beta- = (e+ - e-) / e, fitted against "
                     "depth (binned medians, strictly monotonic)";
        r["pixels_used"] = calibration_pixels_;
        break;
    }
    r["normalisation"] = cfg_.black_frame ? "(frame - black frame) / (1 - black_level)"
                                          : "no black frame: Nayar et al.'s black-level correction; ambient counts "
                                            "as global";
    return r;
  }

  Config cfg_;
  sdk::Rig rig_;
  std::vector<float> depth_;
  sdk::CalibrationTable table_;
  std::vector<std::pair<Role, uint32_t>> roles_;  // per planned frame: role, focus slot
  std::vector<Extrema> per_focus_;
  Extrema white_, black_;
  uint32_t seen_type_ = 0;
  bool planned_ = false;
  uint64_t pattern_count_ = 0;
  double decode_ms_ = 0;
  Maps maps_;
  size_t calibration_pixels_ = 0;
  std::string table_error_;  // calibrate: why no table could be fitted (empty: fitted)
  nlohmann::json table_json_;
};

std::vector<std::string> outputs_of(Method m) {
  std::vector<std::string> o;
  if (m == Method::calibrate)
    o = {"calibration_table"};
  else
    o = {"direct_dn", "global_dn"};
  if (m == Method::multi_focal) o.push_back("best_focus_mm");
  for (const char* s : {"decode_ms", "pattern_count", "valid_fraction", "report"}) o.emplace_back(s);
  return o;
}

}  // namespace

nlohmann::json describe_methods() {
  struct M {
    const char* name;
    Method m;
    const char* summary;
    uint32_t patterns;
    const char* formula;
  };
  const M methods[] = {
      {"checker", Method::checker,
       "S1 (Nayar et al. 2006): direct/global from the max and min of 8x8 checkers shifted 5x5 times by 3 px; "
       "assumes the scene is in focus",
       26, "shifts^2 + black_frame"},
      {"checker-pair", Method::checker_pair, "S1 with two frames: a checkerboard and its inverse", 3,
       "2 + black_frame"},
      {"multi-focal", Method::multi_focal,
       "S2 (thesis §2.5.1): the checkers at F focus settings; extrema over focus by Gaussian interpolation give "
       "the in-focus max/min, so defocus does not bias the separation",
       151, "focus_settings * shifts^2 + black_frame"},
      {"one-focal-depth", Method::one_focal,
       "S3 (thesis §2.5.2): one focus setting, a white frame and a depth map (input depth_mm); beta+ - beta- from "
       "the rig's calibration table 'separation.one-focal-depth'",
       66, "shifts^2 + 1 white + black_frame"},
      {"calibrate-one-focal", Method::calibrate,
       "makes the table one-focal-depth needs (Eq. 2.19) from a scan of a matte plane and its depth map (input "
       "depth_mm); outputs calibration_table",
       66, "shifts^2 + 1 white + black_frame"},
  };
  nlohmann::json a = nlohmann::json::array();
  for (const M& m : methods) {
    sdk::MethodDescription d;
    d.name = m.name;
    d.summary = m.summary;
    d.patterns = m.patterns;
    d.patterns_formula = m.formula;
    d.outputs = outputs_of(m.m);
    d.params = specs_for(m.m);
    if (m.m == Method::one_focal || m.m == Method::calibrate)
      d.inputs = {{"depth_mm", "image_f32", "mm", true,
                   "depth of every camera pixel (NaN unknown), e.g. structured-light's depth_mm of the same scene "
                   "from the same rig; S3 looks up beta+ - beta- at it (Eq. 2.17), calibration pairs it with the "
                   "plane's contrast (Eq. 2.19)"}};
    nlohmann::json j = d.to_json();
    if (m.m == Method::one_focal) j["calibration_tables"] = nlohmann::json::array({kOneFocalTable});
    a.push_back(std::move(j));
  }
  return a;
}

sdk::Error create_session_with_depth(const sdk::CreateArgs& args, std::optional<std::vector<float>> depth_mm,
                                     std::unique_ptr<sdk::Session>& out) {
  Config cfg;
  cfg.method = method_of(args.method);
  cfg.method_name = args.method;
  if (sdk::Error e = sdk::parse_params(args.params, specs_for(cfg.method), cfg.params, args.method); !e.ok())
    return e;
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  const sdk::Params& p = cfg.params;
  cfg.square = static_cast<uint32_t>(p.get_int("square_px"));
  if (cfg.method != Method::checker_pair) {
    cfg.shifts = static_cast<uint32_t>(p.get_int("shifts"));
    cfg.step = static_cast<uint32_t>(p.get_int("step_px"));
    if ((cfg.shifts - 1) * cfg.step < cfg.square)
      return sdk::invalid_argument("(shifts - 1) * step_px = " + std::to_string((cfg.shifts - 1) * cfg.step) +
                                   " is below square_px = " + std::to_string(cfg.square) +
                                   ": some pixels would never be fully lit or fully dark; use more shifts or a "
                                   "larger step");
  }
  cfg.black_frame = p.get_bool("black_frame");
  cfg.settings.black_level = p.get_number("black_level");
  cfg.settings.dark_fraction = p.get_number("dark_fraction");
  cfg.settings.threads = rig.threads;
  if (cfg.method == Method::multi_focal) {
    const double near = p.get_number("focus_near_mm"), far = p.get_number("focus_far_mm");
    if (!(far > near))
      return sdk::invalid_argument("focus_far_mm (" + std::to_string(far) + ") must be above focus_near_mm (" +
                                   std::to_string(near) + ")");
    const auto n = static_cast<uint32_t>(p.get_int("focus_settings"));
    for (uint32_t k = 0; k < n; ++k)  // equally spaced in 1/focus (thin-lens blur is linear in it)
      cfg.focus_mm.push_back(1.0 / (1.0 / near + (1.0 / far - 1.0 / near) * double(k) / double(n - 1)));
    cfg.settings.tie_fraction = p.get_number("tie_fraction");
  } else {
    cfg.focus_mm = {p.get_number("focus_mm")};
  }
  const bool takes_depth = cfg.method == Method::one_focal || cfg.method == Method::calibrate;
  std::vector<float> depth;
  if (takes_depth) {
    if (!depth_mm)
      return sdk::invalid_argument("method '" + args.method +
                                   "' needs input 'depth_mm' (a depth map of the same scene from the same rig, "
                                   "e.g. structured-light's depth_mm of a finished scan): pass it as a scan input");
    const size_t n = size_t{rig.cameras[0].width} * rig.cameras[0].height;
    if (depth_mm->size() != n)
      return sdk::invalid_argument("input 'depth_mm' has " + std::to_string(depth_mm->size()) +
                                   " pixels but camera 0 has " + std::to_string(n) +
                                   ": use a depth map from a scan with the same camera");
    depth = std::move(*depth_mm);
  }
  sdk::CalibrationTable table;
  if (cfg.method == Method::one_focal) {
    cfg.settings.min_contrast = p.get_number("min_contrast");
    const nlohmann::json* j = rig.table(kOneFocalTable);
    if (j == nullptr)
      return sdk::failed_precondition(std::string("rig has no calibration table '") + kOneFocalTable +
                                   "': run method calibrate-one-focal of plugin separation on a tilted matte plane "
                                   "with its depth map as input, at the same focus_mm (docs/calibration.md)");
    if (sdk::Error e = sdk::parse_table(*j, table); !e.ok()) return e;
    if (table.x_unit != "mm" || table.y_name != "contrast")
      return sdk::invalid_argument(std::string("calibration table '") + kOneFocalTable +
                                   "' must map depth (mm) to contrast; re-make it with calibrate-one-focal");
    const double made_at = table.extra.value("focus_mm", -1.0);
    if (made_at >= 0 && std::abs(made_at - cfg.focus_mm[0]) > 1e-6)
      return sdk::invalid_argument("calibration table '" + std::string(kOneFocalTable) + "' was made at focus_mm " +
                                   std::to_string(made_at) + " but this scan uses focus_mm " +
                                   std::to_string(cfg.focus_mm[0]) + ": use the table's focus or re-calibrate");
  }
  if (cfg.method == Method::calibrate) {
    cfg.bins = static_cast<uint32_t>(p.get_int("bins"));
    const auto window = static_cast<uint32_t>(p.get_int("window_px"));
    cfg.window = window == 0 ? 2 * cfg.square : window;
  }
  out = std::make_unique<SeparationSession>(std::move(cfg), rig, std::move(depth), std::move(table));
  return sdk::ok();
}

sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  const Method m = method_of(args.method);
  if (m != Method::one_focal && m != Method::calibrate) return create_session_with_depth(args, std::nullopt, out);
  // Scan input depth_mm (plugin ABI 2), copied while the host's views are valid.
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  std::vector<float> depth;
  if (sdk::Error e = args.inputs.image_f32("depth_mm", rig.cameras[0].width, rig.cameras[0].height, depth); !e.ok())
    return e;
  return create_session_with_depth(args, std::move(depth), out);
}

}  // namespace procam::separation
