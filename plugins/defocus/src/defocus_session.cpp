// SPDX-License-Identifier: MIT
// Sessions of the defocus plugin (see defocus_session.hpp).
#include "defocus_session.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "calibration.hpp"
#include "e3_accumulator.hpp"
#include "focus_measures.hpp"
#include "sweep_plan.hpp"

namespace procam::defocus {
namespace {

enum class Method { multi_focal, two_focal, single_focal, invariance };

const CueKind* cue_of(Method m) {
  switch (m) {
    case Method::multi_focal: return &kMultiFocal;
    case Method::two_focal: return &kTwoFocal;
    case Method::single_focal: return &kSingleFocal;
    default: return nullptr;
  }
}

class SweepSession final : public sdk::Session {
 public:
  // `plane_depth` non-empty: a calibrate-* session, which makes the table of
  // `method` from the cue and the plane's depth instead of using one.
  SweepSession(Method method, const sdk::Rig& rig, SweepConfig config, sdk::CalibrationTable table,
               std::vector<PixelPair> pairs, std::vector<float> plane_depth = {})
      : method_(method),
        rig_(rig),
        config_(std::move(config)),
        table_(std::move(table)),
        pairs_(std::move(pairs)),
        plane_depth_(std::move(plane_depth)) {}

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (planned_) return sdk::ok();
    add_sweep_frames(plan, rig_.projector_width, rig_.projector_height, config_);
    plan.set_note(std::string("defocus ") + method_name() + ": period-24 stripes shifted 1 px per frame, 24 frames at each of " +
                  std::to_string(config_.focus_mm.size()) + " focus settings (frame = 24 * focus + shift)");
    planned_ = true;
    has_round = true;
    return sdk::ok();
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    sdk::ScopedMs timer(decode_ms_);
    const sdk::RigCamera& cam = rig_.cameras[0];
    if (sdk::Error e = sdk::check_frame(&frame, cam.width, cam.height, 1, "frame " + std::to_string(index)); !e.ok())
      return e;
    if (!acc_) {
      // The first frame fixes the format (U8 / U16 / F32); later frames must match.
      acc_ = std::make_unique<E3Accumulator>(cam.width, cam.height, static_cast<uint32_t>(config_.focus_mm.size()),
                                             frame.pixel_type, sdk::full_scale(frame), rig_.threads);
      // multi-focal: the last setting's fold happens inside the fbar pass
      // (fbar_depth_map), not as a pass of its own after the last frame.
      if (method_ == Method::multi_focal && !calibrating()) acc_->defer_final_fold(true);
    }
    return acc_->add(index / kPeriodPx, index % kPeriodPx, frame);
  }

  sdk::Error end_round() override {
    sdk::ScopedMs timer(decode_ms_);
    const uint32_t th = rig_.threads;
    Validity rule = config_.validity;
    rule.black_dn = config_.black_fraction * full_scale();
    // Map storage from the SDK's cache (pages already mapped when the last
    // scan's maps came back): every element is written below.
    const size_t n = size_t{acc_->width()} * acc_->height();
    sdk::take_map(cue_, n);
    if (cue_of(method_) != nullptr) sdk::take_map(depth_, n);
    if (method_ == Method::multi_focal) sdk::take_map(peak_, n);
    // multi-focal (not calibrating): the valid map comes out of the fbar
    // pass too (255 where depth is finite), not from a second read of depth.
    const bool fused_valid = method_ == Method::multi_focal && !calibrating();
    if (fused_valid) sdk::take_map(valid_map_, n);
    switch (method_) {
      case Method::multi_focal:
        cue_valid_ = fbar_depth_map(*acc_, rule, &table_, th, cue_, &depth_, &peak_, fused_valid ? &valid_map_ : nullptr,
                                    &valid_count_);
        break;
      case Method::invariance: cue_valid_ = fbar_map(*acc_, rule, th, cue_); break;
      case Method::two_focal: cue_valid_ = omega_map(*acc_, 0, 1, rule, th, cue_); break;
      case Method::single_focal: cue_valid_ = modulation_map(*acc_, 0, rule, th, cue_); break;
    }
    if (calibrating()) {
      // The multi-focal kernel fuses the table lookup; here the cue alone.
      if (method_ == Method::multi_focal) cue_valid_ = fbar_map(*acc_, rule, th, cue_);
      table_error_ = make_table(*cue_of(method_), cue_, plane_depth_, config_.focus_mm, config_.table_bins, table_);
      table_.made = {{"plugin", "defocus"}, {"method", std::string("calibrate-") + method_name()}};
      return sdk::ok();  // a failed fit is reported in outputs (the frames were fine)
    }
    if (method_ == Method::two_focal || method_ == Method::single_focal) depth_from_cue(table_, cue_, th, depth_);
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    sdk::ScopedMs timer(decode_ms_);
    const uint32_t w = rig_.cameras[0].width, h = rig_.cameras[0].height;
    const size_t n = size_t{w} * h;
    nlohmann::json report = {{"method", calibrating() ? std::string("calibrate-") + method_name() : method_name()},
                             {"focus_mm", config_.focus_mm},
                             {"model", model_text()},
                             {"prefilter_sigma_px", config_.prefilter_sigma_px},
                             {"black_dn", config_.black_fraction * full_scale()},
                             {"min_modulation", config_.validity.min_modulation}};
    size_t valid = 0;
    // The maps move into `out` (outputs() runs once per round) and go back to
    // the SDK's map cache when the host destroys the session.
    out.set_release(sdk::give_map, sdk::give_map);
    std::vector<uint8_t> valid_map = std::move(valid_map_);  // multi-focal: made in end_round
    if (valid_map.size() != n) sdk::take_map(valid_map, n);  // stale contents: every branch below writes every element
    if (calibrating()) {
      // A plane that gives no table (unlit, flat, out of the sweep) is a
      // finished scan without calibration_table; the report says why.
      if (table_error_.ok())
        out.add_json("calibration_table",
                     "table " + table_.name + " (procam-calibration-table v1): add it to the rig config's "
                     "calibration_tables (docs/calibration.md)",
                     sdk::to_json(table_).dump());
      else
        report["table_error"] = table_error_.message;
      valid = valid_where_finite(cue_, &plane_depth_, h, rig_.threads, valid_map);
      if (table_error_.ok())
        report["table"] = {{"name", table_.name}, {"samples", table_.samples.size()},
                           {"x_range", {table_.x_min(), table_.x_max()}}};
    } else if (const CueKind* kind = cue_of(method_)) {
      if (method_ == Method::multi_focal)
        valid = valid_count_;  // valid_map came from the fbar pass (same rule: depth finite)
      else
        valid = valid_where_finite(depth_, nullptr, h, rig_.threads, valid_map);
      out.add_image("depth_mm", "mm", "depth along the camera axis from the calibrated " + std::string(kind->x_name) +
                                          " table; NaN: invalid", w, h, std::move(depth_));
      report["table"] = {{"name", table_.name}, {"x_range", {table_.x_min(), table_.x_max()}}, {"made", table_.made}};
      report["cue_valid_pixels"] = cue_valid_;
    } else {
      valid = valid_where_finite(cue_, nullptr, h, rig_.threads, valid_map);
    }
    switch (method_) {
      case Method::multi_focal:
      case Method::invariance:
        out.add_image("fbar", "index", "focus index of the peak of E(3, f) (Eq. 2.9, Gaussian interpolation); NaN: no peak inside the sweep or no pattern", w, h, std::move(cue_));
        break;
      case Method::two_focal:
        out.add_image("omega", "", "E(3, f2) / E(3, f1) (Eq. 2.10); NaN: a setting without measurable pattern", w, h, std::move(cue_));
        break;
      case Method::single_focal:
        out.add_image("modulation", "", "E(3, f) / mean at the one focus setting (Zhang & Nayar 2006); NaN: invalid", w, h, std::move(cue_));
        break;
    }
    if (method_ == Method::invariance) {
      for (uint32_t f = 0; f < acc_->focus_count(); ++f)
        out.add_image("e3_f" + std::to_string(f) + "_dn", "DN",
                      "amplitude of the 3rd harmonic of the temporal profile at focus setting " + std::to_string(f) +
                          " (" + std::to_string(config_.focus_mm[f]) + " mm)",
                      w, h, acc_->e3(f));
      report["pairs"] = invariance_summary(*acc_, pairs_);
    } else {
      if (method_ != Method::multi_focal) {  // the multi-focal kernel made it in end_round
        peak_.assign(n, 0.f);
        for (uint32_t f = 0; f < acc_->focus_count(); ++f)
          for (size_t i = 0; i < n; ++i) peak_[i] = std::max(peak_[i], acc_->e3(f)[i]);
      }
      out.add_image("e3_peak_dn", "DN", "largest E(3, f) over the focus settings (pattern contrast)", w, h, std::move(peak_));
    }
    // The accumulator's map itself (outputs() runs once per round and
    // defocus has one round), not a 9 MB copy of it.
    out.add_image("mean_dn", "DN", "mean of the temporal profile (focus setting 0)", w, h, acc_->take_mean());
    out.add_image("valid", "", "255 where the method's result is valid, else 0", w, h, std::move(valid_map));
    sdk::StandardOutputs std_out;
    std_out.decode_ms = decode_ms_;
    std_out.pattern_count = config_.focus_mm.size() * kPeriodPx;
    std_out.valid_pixels = valid;
    std_out.total_pixels = n;
    std_out.report = std::move(report);
    sdk::add_standard_outputs(out, std_out);
    return sdk::ok();
  }

 private:
  Method method_;
  sdk::Rig rig_;
  SweepConfig config_;
  sdk::CalibrationTable table_;
  std::vector<PixelPair> pairs_;
  std::vector<float> plane_depth_;  // calibrate-*: the plane's depth (input depth_mm)
  sdk::Error table_error_;
  std::unique_ptr<E3Accumulator> acc_;
  std::vector<float> cue_, depth_, peak_;  // peak_: max_f E(3, f)
  std::vector<uint8_t> valid_map_;          // multi-focal: from the fbar pass
  size_t cue_valid_ = 0, valid_count_ = 0;
  bool planned_ = false;
  double decode_ms_ = 0;

  bool calibrating() const { return !plane_depth_.empty(); }
  double full_scale() const {
    const uint32_t bits = rig_.cameras[0].bit_depth;
    return bits >= 32 ? 1.0 : std::ldexp(1.0, static_cast<int>(bits)) - 1.0;
  }
  const char* method_name() const {
    switch (method_) {
      case Method::multi_focal: return "multi-focal";
      case Method::two_focal: return "two-focal";
      case Method::single_focal: return "single-focal";
      default: return "invariance";
    }
  }
  const char* model_text() const {
    switch (method_) {
      case Method::multi_focal:
        return "E(3,f) = P B(f) G (Eq. 2.6) with global blur G invariant to focus (sec. 2.3): the focus index of the "
               "peak of E (Eq. 2.9, Gaussian interpolation) is global-light invariant; depth from the calibrated table";
      case Method::two_focal:
        return "Omega = E(f2)/E(f1) = B(f2)/B(f1) (Eq. 2.10): G cancels; depth from the calibrated monotonic table";
      case Method::single_focal:
        return "Zhang & Nayar 2006 baseline: blur from E/mean at one setting; global light (G < 1, raised mean) "
               "biases it - the reference the global-invariant methods must beat";
      default:
        return "G_i(f)/alpha_j = E_i(f)/E_j(f) at pixel pairs of equal depth (Eq. 2.8): near-constant over f when "
               "global light is low-frequency (sec. 2.3.1)";
    }
  }
};

}  // namespace

std::string describe_methods() { return sdk::describe_methods(method_descriptions()); }

sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  SweepConfig config;
  std::vector<PixelPair> pairs;
  if (sdk::Error e = parse_sweep_config(args.method, args.params, rig, config, pairs); !e.ok()) return e;
  const bool calibrate = args.method.rfind("calibrate-", 0) == 0;
  const std::string base = calibrate ? args.method.substr(std::string("calibrate-").size()) : args.method;
  Method m = Method::invariance;
  if (base == "multi-focal") m = Method::multi_focal;
  else if (base == "two-focal") m = Method::two_focal;
  else if (base == "single-focal") m = Method::single_focal;
  sdk::CalibrationTable table;
  if (calibrate) {
    std::vector<float> depth;
    const sdk::RigCamera& cam = rig.cameras[0];
    if (sdk::Error e = args.inputs.image_f32("depth_mm", cam.width, cam.height, depth); !e.ok()) return e;
    out = std::make_unique<SweepSession>(m, rig, std::move(config), std::move(table), std::move(pairs),
                                         std::move(depth));
    return sdk::ok();
  }
  if (const CueKind* kind = cue_of(m))
    if (sdk::Error e = table_from_rig(rig, *kind, config.focus_mm, table); !e.ok()) return e;
  out = std::make_unique<SweepSession>(m, rig, std::move(config), std::move(table), std::move(pairs));
  return sdk::ok();
}

}  // namespace procam::defocus
