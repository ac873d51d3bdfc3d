// SPDX-License-Identifier: MIT
// The medium plugin's sessions (see medium_session.hpp).
#include "medium_session.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

#include "concentration.hpp"
#include "fit.hpp"
#include "hdr_merge.hpp"
#include "params.hpp"
#include "plot.hpp"
#include "procam/base/medium_regime.hpp"

namespace procam::medium {
namespace {

constexpr uint32_t kPlotW = 640, kPlotH = 400;
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

std::string exposure_label(double us) {
  char b[64];
  std::snprintf(b, sizeof b, "exposure %.6g us", us);
  return b;
}

nlohmann::json estimate_json(const Estimate& e) { return {{"value", e.value}, {"ci95", e.ci95}}; }

// What every method shares: the plan of one bracket, the frame checks and the HDR merge.
class BracketSession : public sdk::Session {
 public:
  BracketSession(Config cfg, const sdk::Rig& rig) : cfg_(std::move(cfg)), rig_(rig) {}

 protected:
  // One round: the bracket, white or a spot, `prefix` before each label.
  void plan_bracket(sdk::Plan& plan, const std::string& prefix) {
    const uint32_t pw = rig_.projector_width, ph = rig_.projector_height;
    const double cx = cfg_.spot_x_px < 0 ? 0.5 * (double(pw) - 1) : cfg_.spot_x_px;
    const double cy = cfg_.spot_y_px < 0 ? 0.5 * (double(ph) - 1) : cfg_.spot_y_px;
    const double r2 = cfg_.spot_radius_px * cfg_.spot_radius_px;
    for (const double t : cfg_.exposures_us) {
      const uint32_t i = plan.add_frame(prefix + exposure_label(t), pw, ph);
      sdk::fill_pattern(plan, i, [&](uint32_t x, uint32_t y) {
        if (!cfg_.spot) return 1.0;
        const double dx = double(x) - cx, dy = double(y) - cy;
        return dx * dx + dy * dy <= r2 ? 1.0 : 0.0;
      });
      plan.settings(i).exposure_us = t;
    }
    pattern_count_ += plan.size();
    HdrSettings hs = cfg_.hdr;
    hs.camera_bits = rig_.cameras[0].bit_depth;
    merge_.emplace(rig_.cameras[0].width, rig_.cameras[0].height, hs);
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    const sdk::ScopedMs timer(decode_ms_);
    if (sdk::Error e = merge_->add(frame, cfg_.exposures_us.at(index), rig_.threads); !e.ok())
      return sdk::Error{e.code, "frame " + std::to_string(index) + ": " + e.message};
    return sdk::ok();
  }

  nlohmann::json base_report() const {
    return {{"method", cfg_.method_name},
            {"params", cfg_.params.json()},
            {"patterns", pattern_count_},
            {"exposures_us", cfg_.exposures_us},
            {"hdr", {{"weights", "w = t (inverse variance of DN/t under shot noise): radiance = sum x / sum t over "
                                  "unsaturated frames; samples below floor get weight 1e-12 t^2 (least squares of x = L t)"},
                     {"full_scale_dn", merge_ ? merge_->full_scale() : 0.0},
                     {"response", cfg_.params.get_string("response")}}},
            {"geometry", {{"tank_depth_mm", cfg_.fit.tank.depth_mm},
                          {"bulb_depth_mm", cfg_.fit.tank.bulb_depth_mm},
                          {"bulb_x_px", cfg_.fit.bulb_x_px},
                          {"bulb_y_px", cfg_.fit.bulb_y_px},
                          {"bulb_radius_mm", cfg_.fit.bulb_radius_mm},
                          {"source_model", cfg_.fit.tank.bulb_radius_mm > 0
                                               ? "sphere: Lambertian, radius bulb_radius_mm, visible cap sampled (§4.3.3)"
                                               : "point: isotropic at the bulb centre"},
                          {"mm_per_px", cfg_.fit.mm_per_px}}}};
  }

  Config cfg_;
  sdk::Rig rig_;
  std::optional<HdrMerge> merge_;
  uint64_t pattern_count_ = 0;
  double decode_ms_ = 0;
};

// ---------------------------------------------------------------- measure

class MeasureSession final : public BracketSession {
 public:
  using BracketSession::BracketSession;

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (planned_) return sdk::ok();
    plan_bracket(plan, "");
    plan.set_note("measure: " + std::to_string(plan.size()) + " exposures of the lit tank (HDR), then the fit");
    planned_ = has_round = true;
    return sdk::ok();
  }

  sdk::Error end_round() override {
    const sdk::ScopedMs timer(decode_ms_);
    const uint32_t w = rig_.cameras[0].width, h = rig_.cameras[0].height;
    radiance_ = merge_->radiance();
    saturated_ = merge_->saturated_pixels();
    // Bins dark in every exposure are not fitted (min_signal): their mean is
    // biased up by the camera's clip at black and the merge's floor.
    const double t_max = *std::max_element(cfg_.exposures_us.begin(), cfg_.exposures_us.end());
    cfg_.fit.min_bin_radiance = cfg_.min_signal * merge_->full_scale() / t_max;
    profile_ = radial_profile(radiance_, w, h, cfg_.fit);
    fit_ = fit_profile(profile_, cfg_.fit, radiance_, w, h);
    // fit_residual: (E - fit) / max of the measured profile (Eq. 4.6's
    // normalisation of E), NaN where not fitted (mask, NaN radiance).
    residual_ = model_image(fit_, cfg_.fit, w, h);
    double emax = 0;
    for (const Bin& b : profile_.bins) emax = std::max(emax, b.mean);
    const double norm = emax > 0 ? 1.0 / emax : 1.0;
    for (size_t i = 0; i < residual_.size(); ++i)
      residual_[i] = std::isfinite(radiance_[i]) && std::isfinite(residual_[i])
                         ? static_cast<float>((double(radiance_[i]) - double(residual_[i])) * norm)
                         : kNaNf;
    std::vector<double> rho, meas;
    for (const Bin& b : profile_.bins) rho.push_back(b.rho_mm), meas.push_back(b.mean);
    plot_ = plot_series({{rho, meas, false, 128}, {rho, fit_.fit, true, 0}}, kPlotW, kPlotH, true, &range_);
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    const sdk::ScopedMs timer(decode_ms_);
    const uint32_t w = rig_.cameras[0].width, h = rig_.cameras[0].height;
    size_t valid = 0;
    for (float v : radiance_) valid += std::isfinite(v) ? 1u : 0u;
    out.add_image("radiance", "DN/us",
                  "HDR radiance map: linear DN per microsecond of exposure (NaN: saturated in every frame)", w, h,
                  std::move(radiance_));
    out.add_image("fit_residual", "",
                  "(measured - fitted radiance) / max of the measured radial profile (Eq. 4.6 scale; NaN: not fitted)",
                  w, h, std::move(residual_));
    out.add_image("profile_plot", "",
                  "radial profile, log radiance vs rho (mm): measured bins (gray dots), fit (black line); ranges in the "
                  "report", kPlotW, kPlotH, std::move(plot_));
    if (fit_.error.empty()) {
      if (std::isfinite(fit_.sigma.value))
        out.add_scalar("medium_extinction_per_mm", "1/mm", "extinction coefficient sigma (Eq. 4.2 fit)", fit_.sigma.value);
      if (fit_.beta_absolute && std::isfinite(fit_.beta.value))
        out.add_scalar("medium_scattering_per_mm", "1/mm", "scattering coefficient beta (Eq. 4.4-4.5)", fit_.beta.value);
      if (fit_.g_defined && std::isfinite(fit_.g.value))
        out.add_scalar("medium_hg_g", "", "Henyey-Greenstein asymmetry g", fit_.g.value);
    }
    sdk::StandardOutputs std_out;
    std_out.pattern_count = pattern_count_;
    std_out.total_pixels = size_t{w} * h;
    std_out.valid_pixels = valid;
    std_out.report = report();
    std_out.decode_ms = decode_ms_;
    sdk::add_standard_outputs(out, std_out);
    return sdk::ok();
  }

 private:
  nlohmann::json report() const {
    nlohmann::json r = base_report();
    r["hdr"]["saturated_pixels"] = saturated_;
    nlohmann::json f = {{"fitted_pixels", profile_.pixels},
                        {"bins", profile_.bins.size()},
                        {"bins_dropped", profile_.bins_dropped},
                        {"bins_dark", profile_.bins_dark},
                        {"pixels_dark", profile_.pixels_dark},
                        {"min_bin_radiance", cfg_.fit.min_bin_radiance}};
    if (!fit_.error.empty()) {
      f["error"] = fit_.error;
    } else {
      f["sigma_per_mm"] = estimate_json(fit_.sigma);
      f["beta_per_mm"] = estimate_json(fit_.beta);
      f["kappa_per_mm"] = estimate_json(fit_.kappa);
      f["g"] = estimate_json(fit_.g);
      f["g_defined"] = fit_.g_defined;
      f["model"] = fit_.model;
      f["model_reason"] = fit_.model_reason;
      f["beta_scale"] = fit_.beta_absolute ? "absolute" : "relative (I0 = 1)";
      f["source_intensity"] = fit_.source_intensity;
      f["beta_i0"] = fit_.scale;
      f["rms_percent"] = fit_.rms_percent;
      f["rms_normalized_percent"] = fit_.rms_normalized_percent;
      f["objective"] = cfg_.fit.objective == Objective::normalized ? "normalized (Eq. 4.6-4.7)" : "profiled";
      f["weights"] = cfg_.fit.weights == Weights::noise ? "noise" : "uniform";
      f["objective_value"] = fit_.objective;
      f["legendre_objective_value"] = fit_.legendre_objective;
      f["evaluations"] = fit_.evaluations;
      f["search"] = "Nelder-Mead in (ln sigma, atanh g) from the best 3 nodes of a 10 x 10 grid";
      f["ci_method"] = "95 %: 1.96 sqrt(diag(s^2 (J^T J)^-1)), J the Jacobian of the binned residuals in (sigma, g, "
                       "beta I0), s^2 = sum w res^2 / (bins - 3), w = n (uniform weights) or n / var (noise); "
                       "I0 taken as exact";
    }
    std::vector<std::string> notes = fit_.notes;
    if (fit_.error.empty() && fit_.beta_absolute && std::isfinite(fit_.beta.value)) {
      // Where the single-scattering model holds (thesis §4.2.3): the share of
      // the image's energy it misses at the fitted beta, from the sim's Monte
      // Carlo regime map (procam/base/medium_regime.hpp).
      const double depth = cfg_.fit.tank.depth_mm, beta = fit_.beta.value;
      const double missed = single_scattering_error(beta, depth), ok_beta = max_beta_for_error(cfg_.max_multiple_scattering, depth);
      f["multiple_scattering"] = {
          {"missed_energy_fraction", missed},
          {"max", cfg_.max_multiple_scattering},
          {"max_beta_per_mm", ok_beta},
          {"source", "Monte Carlo regime map of a tank of this depth, g ~ 0.9 (docs/media.md 'Regime of validity')"}};
      if (missed > cfg_.max_multiple_scattering && beta > 0) {
        char b[320];
        std::snprintf(b, sizeof b,
                      "multiple scattering: at beta = %.3g /mm single scattering misses ~%.0f %% of the image's energy "
                      "(above max_multiple_scattering = %.0f %%), so sigma, beta and g are biased; dilute to %.2g x "
                      "the current volume (beta <= %.2g /mm) and measure again",
                      beta, 100.0 * missed, 100.0 * cfg_.max_multiple_scattering, ok_beta / beta, ok_beta);
        notes.emplace_back(b);
      }
    }
    if (!notes.empty()) f["notes"] = notes;
    r["fit"] = f;
    nlohmann::json meas = nlohmann::json::array(), fit = nlohmann::json::array();
    for (size_t i = 0; i < profile_.bins.size(); ++i) {
      const Bin& b = profile_.bins[i];
      meas.push_back({b.rho_mm, b.mean, b.n});
      fit.push_back({b.rho_mm, i < fit_.fit.size() ? fit_.fit[i] : 0.0});
    }
    r["profile_measured"] = {{"columns", {"rho_mm", "radiance", "pixels"}}, {"rows", meas}};
    r["profile_fit"] = {{"columns", {"rho_mm", "radiance"}}, {"rows", fit}};
    r["profile_plot"] = {{"x_mm", {range_.x0, range_.x1}}, {"log10_radiance", {range_.y0, range_.y1}}};
    return r;
  }

  bool planned_ = false;
  std::vector<float> radiance_, residual_;
  std::vector<uint8_t> plot_;
  PlotRange range_;
  uint64_t saturated_ = 0;
  RadialProfile profile_;
  FitResult fit_;
};

// ---------------------------------------------------------------- concentration

class ConcentrationSession final : public BracketSession {
 public:
  using BracketSession::BracketSession;

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (round_ >= cfg_.volumes_ml.size()) return sdk::ok();
    char b[64];
    std::snprintf(b, sizeof b, "V %.6g ml ", cfg_.volumes_ml[round_]);
    plan_bracket(plan, b);
    plan.set_note(std::string("concentration: dilution ") + std::to_string(round_ + 1) + " of " +
                  std::to_string(cfg_.volumes_ml.size()) + " (" + b + "): fill the tank to this volume first");
    has_round = true;
    return sdk::ok();
  }

  sdk::Error end_round() override {
    const sdk::ScopedMs timer(decode_ms_);
    const uint32_t w = rig_.cameras[0].width, h = rig_.cameras[0].height;
    const std::vector<float> radiance = merge_->radiance();
    DilutionPoint p;
    p.volume_ml = cfg_.volumes_ml[round_];
    p.bulb_radiance = bulb_radiance(cfg_.fit, radiance, w, h);
    if (p.volume_ml == 0 && !(cfg_.fit.water_radiance > 0)) water_ = p.bulb_radiance;
    std::string why;
    const Estimate s = sigma_from_attenuation(cfg_.fit, water(), radiance, w, h, why);  // Eq. 4.3
    p.sigma_hat = s.value;
    p.sigma_hat_ci95 = s.ci95;
    p.note = why;
    points_.push_back(p);
    merge_.reset();
    ++round_;
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    const sdk::ScopedMs timer(decode_ms_);
    ConcentrationSettings s;
    s.linear_points = cfg_.linear_points;
    s.tolerance = cfg_.linearity_tolerance;
    s.max_sigma_per_mm = cfg_.max_sigma_per_mm;
    s.min_bulb_radiance = cfg_.min_bulb_radiance > 0 ? cfg_.min_bulb_radiance : 0.01 * water();
    const ConcentrationResult r = analyse_dilutions(points_, s);
    std::vector<double> v, sh, line;
    for (const DilutionPoint& p : r.points) {
      v.push_back(p.volume_ml);
      sh.push_back(p.sigma_hat);
      line.push_back(r.slope_per_ml * p.volume_ml);
    }
    PlotRange range;
    out.add_image("sigma_hat_plot", "",
                  "sigma-hat (1/mm) vs volume (ml), thesis Fig. 4.7: measured (black dots), the line through the origin "
                  "fit on the low volumes (gray); ranges in the report", kPlotW, kPlotH,
                  plot_series({{v, line, true, 160}, {v, sh, false, 0}}, kPlotW, kPlotH, false, &range));
    if (r.best >= 0)
      out.add_scalar("best_volume_ml", "ml", "the largest volume still linear, within the bound and bright enough",
                     r.points[size_t(r.best)].volume_ml);
    nlohmann::json rep = base_report();
    rep["water_radiance"] = water();
    rep["dilutions"] = r.to_json();
    rep["sigma_hat_plot"] = {{"volume_ml", {range.x0, range.x1}}, {"sigma_hat_per_mm", {range.y0, range.y1}}};
    rep["model"] = "Eq. 4.3 with radiance: bulb E = W exp(-sigma-hat l), l = B - sqrt(R^2 - s^2) per central pixel";
    sdk::StandardOutputs std_out;
    std_out.pattern_count = pattern_count_;
    std_out.total_pixels = r.points.size();
    std_out.valid_pixels = r.best >= 0 ? size_t(r.best) + 1 : 0;
    std_out.report = rep;
    std_out.decode_ms = decode_ms_;
    sdk::add_standard_outputs(out, std_out);
    return sdk::ok();
  }

 private:
  double water() const { return cfg_.fit.water_radiance > 0 ? cfg_.fit.water_radiance : water_; }
  size_t round_ = 0;
  double water_ = std::numeric_limits<double>::quiet_NaN();
  std::vector<DilutionPoint> points_;
};

}  // namespace

nlohmann::json describe_methods() {
  const auto describe = [](Method m, const char* name, const char* summary, const char* formula) {
    sdk::MethodDescription d;
    d.name = name;
    d.summary = summary;
    d.patterns = 25;  // the default bracket
    d.patterns_formula = formula;
    d.outputs = outputs_of(m);
    d.params = specs_for(m);
    return d;
  };
  sdk::MethodDescription c = describe(
      Method::concentration, "concentration",
      "one HDR bracket per dilution; sigma-hat from the bulb's attenuation (Eq. 4.3) vs volume, linearity, best volume, "
      "stop beyond single scattering (thesis §4.2.3-4.2.4)",
      "exposures per round");
  c.rounds = 6;  // default volumes_ml
  c.rounds_formula = "number of volumes_ml";
  return nlohmann::json::array({describe(Method::measure, "measure",
                                         "HDR bracket of the tank lit by a small bulb; sigma, beta, g (and kappa) by "
                                         "the single-scattering fit (thesis §4.2-4.4, Eq. 4.2-4.7)",
                                         "exposures")
                                    .to_json(),
                                c.to_json()});
}

sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  if (rig.cameras.empty()) return sdk::invalid_argument("the rig has no camera");
  Config cfg;
  if (sdk::Error e = parse_config(args.method, args.params, rig.cameras[0].width, rig.cameras[0].height, cfg); !e.ok())
    return e;
  cfg.threads = rig.threads;
  if (cfg.method == Method::measure)
    out = std::make_unique<MeasureSession>(std::move(cfg), rig);
  else
    out = std::make_unique<ConcentrationSession>(std::move(cfg), rig);
  return sdk::ok();
}

}  // namespace procam::medium
