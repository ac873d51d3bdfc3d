// SPDX-License-Identifier: MIT
// Sessions of the single XOR / min-SW codes and of the ensemble with error
// detection and correction rounds (thesis §3.3–3.4; see codes_session.hpp).
#include "codes_session.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <utility>

#include "codes.hpp"
#include "correction.hpp"
#include "procam/sdk/map_cache.hpp"
#include "multi_round.hpp"
#include "streaming_session.hpp"
#include "subpixel.hpp"
#include "procam/sdk/triangulate.hpp"
#include "vote.hpp"

namespace procam::sl {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
struct Config {
  std::string method;
  bool inverse = true;
  bool black = true;
  double min_contrast = 0.03;
  double min_bit_margin = 0.1;
  double agree_px = 1.0;
  uint32_t correction_rounds = 0;
  double min_progress = 0.0005;
  uint32_t mask_dilate_px = 2;
  uint32_t mask_guard_px = 3;
  bool code_maps = false;
  double auto_tolerance = 0.001;
  uint32_t max_weak_error_px = 1;
};

const char* model_of(const std::string& m) {
  if (m == "xor02" || m == "xor04")
    return "long-range global light (inter-reflections, diffusion): high-frequency patterns only";
  if (m == "minsw") return "short-range global light (sub-surface scattering, defocus): wide stripes only";
  return "unknown mix of long- and short-range global light: four codes, per-pixel vote";
}

const char* why_of(const std::string& m) {
  if (m == "xor02")
    return "XOR-02 (thesis §3.3.1): every plane is a Gray plane XOR the stripe-width-2 base, so "
           "all patterns have stripes of width <= 2 and the global component is split evenly "
           "between a pattern and its inverse (beta ~ 0.5): inter-reflections cannot flip a bit. "
           "Fails where short-range effects blur width-2 stripes (translucent or defocused "
           "surfaces): the base plane's error propagates to every plane.";
  if (m == "xor04")
    return "XOR-04 (thesis §3.3.1): planes above the stripe-width-4 base are XORed with it, so "
           "stripes are at most 4 wide: robust to inter-reflections, a little less sensitive to "
           "blur than XOR-02.";
  if (m == "minsw")
    return "max-min-SW Gray code (thesis §3.3.2): every stripe is >= 8 code columns wide, so "
           "sub-surface scattering and defocus (which low-pass the pattern) keep alpha, beta >= "
           "0.5 and the bits decodable. Errs under long-range inter-reflections (wide stripes).";
  return "Ensemble (thesis §3.3.3): errors of codes built for different effects are nearly "
         "independent, so any two agreeing codes give the right column; where none agree the "
         "pixel is an error (§3.4) and, with correction_rounds > 0, is re-measured while the "
         "projector pixels of already-resolved points are switched off (after Xu & Aliaga), "
         "removing their global light.";
}

class CodesSession final : public StreamingSession<MultiCodeDecoder> {
 public:
  CodesSession(Config cfg, sdk::Rig rig) : cfg_(std::move(cfg)), rig_(std::move(rig)) {
    rig_.threads = std::clamp(rig_.threads, 1u, 64u);
    if (cfg_.method == "ensemble" || cfg_.method == "auto") {
      for (const char* id : kCodeIds) codes_.push_back(make_projected_code(id, rig_.projector_width));
    } else {
      codes_.push_back(make_projected_code(cfg_.method, rig_.projector_width));
    }
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    const size_t n = size_t{cam.width} * cam.height;
    coord_.assign(n, std::numeric_limits<float>::quiet_NaN());
    valid_.assign(n, 0);
    confidence_.assign(n, 0.0f);
    cls_.assign(n, kUnlit);
  }  ~CodesSession() override { recycle_members(); }
  CodesSession(const CodesSession&) = delete;
  CodesSession& operator=(const CodesSession&) = delete;


  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    has_round = false;
    std::vector<uint32_t> subset;  // code indices projected this round
    bool correction = false;
    if (round_ == 0) {
      if (auto_mode()) {
        subset = {kXor04, kMinsw};  // cheapest pair of complementary codes
      } else {
        for (uint32_t k = 0; k < codes_.size(); ++k) subset.push_back(k);
      }
    } else if (auto_mode() && round_ == 1) {
      const RoundStats& last = rounds_.back();
      const double frac = last.lit > 0 ? static_cast<double>(last.errors) / static_cast<double>(last.lit) : 0.0;
      if (frac < cfg_.auto_tolerance) {
        auto_why_ = "xor04 and minsw (built for opposite effects) agree on all but " + fmt_pct(frac) +
                    " of lit pixels (< auto_tolerance " + fmt_pct(cfg_.auto_tolerance) +
                    "): no global-light errors to resolve, so no further patterns";
        return sdk::ok();
      }
      auto_why_ = "xor04 and minsw disagree on " + fmt_pct(frac) +
                  " of lit pixels: projected gray and xor02 too and voted with all four codes";
      subset = {kGray, kXor02};
    } else {
      if (!want_more_round()) return sdk::ok();
      correction = true;
      for (uint32_t k = 0; k < codes_.size(); ++k) subset.push_back(k);
    }
    if (correction)  // projector pixels of resolved points off (correction.hpp)
      mask_ = correction_mask(rig_, coord_, valid_, cls_, cfg_.mask_dilate_px, cfg_.mask_guard_px);
    round_codes_ = subset;
    std::vector<ProjectedCode> codes;
    for (uint32_t k : subset) codes.push_back(codes_[k]);
    MultiLayout layout = make_multi_layout(codes, cfg_.inverse, cfg_.black);
    render_multi_plan(layout, codes, rig_.projector_width, rig_.projector_height,
                      correction ? &mask_ : nullptr, plan);
    std::string note = cfg_.method + ": " + std::to_string(layout.frames.size()) + " frames (";
    for (size_t j = 0; j < codes.size(); ++j) note += (j ? ", " : "") + codes[j].id;
    note += ")";
    if (correction) {
      ++corrections_done_;
      note += " — correction round " + std::to_string(corrections_done_) + ": " +
              std::to_string(errors_before_round()) +
              " error pixels re-measured with resolved projector pixels switched off";
    }
    plan.set_note(note);
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    decoder_.emplace(std::move(layout), codes, cam.width, cam.height, rig_.threads,
                     cfg_.max_weak_error_px,
                     codes_.size() > 1 ? MultiCodeDecoder::Output::vote
                                       : MultiCodeDecoder::Output::per_code);
    patterns_ += plan.size();
    ++round_;
    correction_round_ = correction;
    has_round = true;
    return sdk::ok();
  }

  sdk::Error end_round() override {
    const ScopedMs timed(decode_ms_);
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    const size_t n = size_t{cam.width} * cam.height;
    RoundStats stats;
    stats.round = round_;
    const bool first_pass = !correction_round_;
    if (codes_.size() == 1) {
      MultiResult& r = decoder_->finish(cfg_.min_contrast, cfg_.min_bit_margin);
      full_scale_ = r.full_scale;
      weak_[0] += r.weak[0];
      intensity_ = std::move(r.intensity);
      lit_ = std::move(r.lit);
      coord_ = std::move(r.codes[0].coord);
      valid_ = std::move(r.codes[0].valid);
      confidence_ = std::move(r.codes[0].confidence);
      for (size_t i = 0; i < n; ++i) cls_[i] = lit_[i] == 0 ? kUnlit : valid_[i] ? kAllAgree : kError;
      recycle_maps(std::move(r));
    } else {
      // Full four-code view in one decode + vote pass (vote.hpp): this
      // round's codes, earlier first-pass rounds' maps (auto), NaN maps for
      // codes not projected. Per-code maps are kept only where needed (auto's
      // second round, code_maps).
      const bool keep_maps = first_pass && (auto_mode() || cfg_.code_maps);
      if (keep_maps && stage_maps_.empty())
        stage_maps_.assign(kEnsembleCodes, std::vector<float>(n, std::numeric_limits<float>::quiet_NaN()));
      VoteSpec spec;
      spec.agree_px = static_cast<float>(cfg_.agree_px);
      for (size_t j = 0; j < round_codes_.size(); ++j) {
        spec.round_code[round_codes_[j]] = static_cast<int32_t>(j);
        if (keep_maps) spec.keep[round_codes_[j]] = stage_maps_[round_codes_[j]].data();
      }
      for (uint32_t k = 0; k < kEnsembleCodes; ++k)
        if (spec.round_code[k] < 0) spec.external[k] = stage_maps_.at(k).data();
      MultiResult& r = decoder_->finish_vote(cfg_.min_contrast, cfg_.min_bit_margin, spec);
      full_scale_ = r.full_scale;
      if (first_pass)
        for (size_t j = 0; j < round_codes_.size(); ++j) weak_[round_codes_[j]] += r.weak[j];
      if (round_ == 1) {
        intensity_ = std::move(r.intensity);
        lit_ = std::move(r.lit);
      }
      VoteMaps& v = r.vote;
      if (first_pass) {  // first pass (auto: first or second round): take all pixels
        coord_ = std::move(v.coord);
        valid_ = std::move(v.valid);
        confidence_ = std::move(v.confidence);
        cls_ = std::move(v.cls);
      } else {  // correction: only pixels still in error take the new result, where
        // their new projector pixel was lit and they keep enough of their
        // round-1 light (correction.hpp; r.intensity is the masked white frame)
        stats.resolved += merge_correction(rig_, mask_, v, r.intensity, intensity_, coord_, valid_,
                                           confidence_, cls_);
      }
      recycle_maps(std::move(r));  // what this round's result still holds
    }
    decoder_.reset();
    for (size_t i = 0; i < n; ++i) {
      stats.errors += cls_[i] == kError ? 1u : 0u;
      stats.lit += lit_[i] != 0 ? 1u : 0u;
    }
    rounds_.push_back(stats);
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    out.set_release(sdk::give_map, sdk::give_map);  // the next scan's decoder reuses the maps' pages
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    const uint32_t w = cam.width, h = cam.height;
    std::optional<sdk::DepthResult> depth;
    if (rig_.can_triangulate(0)) {
      const ScopedMs timed(decode_ms_);
      depth = sdk::triangulate_columns(cam.calibration, rig_.projector, w, h, coord_.data(),
                                       intensity_.data(), rig_.threads);
    }
    sdk::StandardOutputs standard;
    standard.decode_ms = decode_ms_;  // the triangulation above included
    standard.pattern_count = patterns_;
    std::array<size_t, kTransportClassCount> counts{};
    for (size_t i = 0; i < valid_.size(); ++i) {
      standard.valid_pixels += valid_[i] != 0 ? 1u : 0u;
      ++counts[std::min<size_t>(cls_[i], kTransportClassCount - 1)];
    }
    standard.total_pixels = valid_.size();
    const size_t lit = rounds_.empty() ? 0 : rounds_.back().lit;
    const size_t errors = rounds_.empty() ? 0 : rounds_.back().errors;
    std::vector<float> subpx(coord_.size());
    sdk::parallel_rows(h, rig_.threads, [&](uint32_t y0, uint32_t y1) {
      refine_columns(coord_.data(), w, y0, y1, SubpixelOptions{}, subpx.data());
    });
    out.add_image("proj_col_subpx", "px",
                  "sub-pixel refined column (line fit through stripe steps along the row, "
                  "subpixel.hpp); NaN: invalid",
                  w, h, std::move(subpx));
    out.add_image("proj_col_px", "px", "decoded projector column per camera pixel (NaN: invalid)",
                  w, h, std::move(coord_));
    out.add_image("valid", "", "255 where the column decoded validly, 0 where invalid", w, h,
                  std::move(valid_));
    const bool ensemble = codes_.size() > 1;
    out.add_image("confidence", "",
                  ensemble ? "(agreeing codes) / 4 for valid pixels, else 0"
                           : "min over bits of |L - L_inv| / (white - black), clipped to [0, 1]",
                  w, h, std::move(confidence_));
    if (ensemble)
      out.add_class_map("transport_class",
                        "light-transport class (thesis Fig. 3.1j): 0 unlit, 1 all codes agree, 2 only "
                        "XOR codes agree (inter-reflection), 3 only Gray codes agree (sub-surface), 4 "
                        "partial agreement, 5 error (no two codes agree)",
                        w, h, std::move(cls_),
                        {{kUnlit, transport_class_name(kUnlit), "no projector light reaches the pixel"},
                         {kAllAgree, transport_class_name(kAllAgree), "all four codes agree: direct light dominates"},
                         {kInterreflection, transport_class_name(kInterreflection),
                          "only the XOR codes agree: inter-reflections (long range)"},
                         {kSubsurface, transport_class_name(kSubsurface),
                          "only the Gray codes agree: sub-surface scattering or defocus (short range)"},
                         {kPartial, transport_class_name(kPartial), "some codes agree"},
                         {kError, transport_class_name(kError), "no two codes agree: error pixel (thesis §3.4)"}});
    if (cfg_.code_maps)
      for (size_t k = 0; k < stage_maps_.size(); ++k)
        out.add_image(std::string("proj_col_px_") + kCodeIds[k], "px",
                      std::string("first-pass column decoded by code ") + kCodeIds[k] +
                          " alone (NaN: invalid or not projected)",
                      w, h, std::move(stage_maps_[k]));
    sdk::add_depth_outputs(out, depth, w, h);
    out.add_scalar("error_fraction", "",
                   "lit pixels left as errors (no valid column; ensemble: no two codes agree) / lit",
                   lit > 0 ? static_cast<double>(errors) / static_cast<double>(lit) : 0.0);
    out.add_scalar("rounds", "", "capture rounds (1 + correction rounds run)",
                   static_cast<double>(rounds_.size()));
    nlohmann::json codes = nlohmann::json::array();
    for (size_t ci = 0; ci < codes_.size(); ++ci) {
      const ProjectedCode& c = codes_[ci];
      uint32_t min_sw = 0xFFFFFFFFu, max_sw = 0;
      for (uint32_t p = 0; p < c.bits(); ++p) {
        const RunLengths rl = interior_runs(c, p);
        if (rl.max_run == 0) continue;
        min_sw = std::min(min_sw, rl.min_run);
        max_sw = std::max(max_sw, rl.max_run);
      }
      const std::vector<uint32_t> bounds = plane_error_bounds(c);
      nlohmann::json tolerated = nlohmann::json::array();
      for (uint32_t k = 0; k < bounds.size(); ++k)
        if (cfg_.max_weak_error_px > 0 && bounds[k] <= cfg_.max_weak_error_px) tolerated.push_back(k);
      codes.push_back({{"id", c.id}, {"name", c.code.name}, {"bits", c.bits()},
                       {"code_columns", c.code.length}, {"max_span_px", c.max_span},
                       {"min_stripe_px", min_sw}, {"max_stripe_px", max_sw},
                       {"error_bound_px", bounds}, {"tolerated_weak_bits", tolerated},
                       {"weak_plane_pixels", weak_[ci]}});
    }
    nlohmann::json rounds = nlohmann::json::array();
    for (const RoundStats& s : rounds_)
      rounds.push_back({{"round", s.round}, {"error_pixels", s.errors}, {"resolved", s.resolved}});
    nlohmann::json classes = nlohmann::json::object();
    for (uint32_t c = 0; c < kTransportClassCount; ++c)
      classes[transport_class_name(static_cast<uint8_t>(c))] = counts[c];
    nlohmann::json& report = standard.report;
    report = {
        {"method", cfg_.method},
        {"codes", codes},
        {"patterns", patterns_},
        {"patterns_per_round", rounds_.empty() ? 0 : patterns_ / rounds_.size()},
        {"rounds", rounds},
        {"binarize", cfg_.inverse ? "inverse" : "white"},
        {"black_frame", cfg_.black},
        {"model", model_of(cfg_.method)},
        {"why", why_of(cfg_.method)},
        {"min_contrast", cfg_.min_contrast},
        {"min_bit_margin", cfg_.min_bit_margin},
        {"max_weak_error_px", cfg_.max_weak_error_px},
        {"input_full_scale", full_scale_},
        {"triangulated", depth.has_value()},
        {"camera_index", 0},
    };
    if (auto_mode()) {
      report["auto_tolerance"] = cfg_.auto_tolerance;
      report["auto_decision"] = auto_why_;
    }
    if (ensemble) {
      report["agree_px"] = cfg_.agree_px;
      report["correction_rounds_max"] = cfg_.correction_rounds;
      report["mask_dilate_px"] = cfg_.mask_dilate_px;
      report["mask_guard_px"] = cfg_.mask_guard_px;
      report["transport_classes"] = classes;
      if (stop_reason_.empty() && cfg_.correction_rounds > 0) stop_reason_ = "round limit";
      if (!stop_reason_.empty()) report["correction_stop"] = stop_reason_;
    }
    if (!depth) report["note"] = "rig has no calibration for projector and camera 0: no depth";
    sdk::add_standard_outputs(out, standard);
    return sdk::ok();
  }

 private:
  struct RoundStats {
    uint32_t round = 0;
    size_t errors = 0, resolved = 0, lit = 0;
  };


  size_t errors_before_round() const { return rounds_.empty() ? 0 : rounds_.back().errors; }

  // §3.4 stop rule (correction.hpp decide_correction).
  bool want_more_round() {
    const RoundStats& last = rounds_.back();
    CorrectionProgress p;
    p.ensemble = codes_.size() > 1;
    p.max_rounds = cfg_.correction_rounds;
    p.rounds_done = corrections_done_;
    p.can_triangulate = rig_.can_triangulate(0);
    p.errors = last.errors;
    p.lit = last.lit;
    p.resolved_last = last.resolved;
    p.min_progress = cfg_.min_progress;
    const CorrectionDecision d = decide_correction(p);
    if (d.stop_reason != nullptr) stop_reason_ = d.stop_reason;
    return d.more;
  }

  // Maps not handed to the host go back to the map cache (map_cache.hpp).
  void recycle_members() noexcept {
    for (std::vector<float>* v : {&coord_, &confidence_, &intensity_}) sdk::give_map(std::move(*v));
    for (std::vector<uint8_t>* v : {&valid_, &cls_, &lit_}) sdk::give_map(std::move(*v));
  }

  Config cfg_;
  sdk::Rig rig_;
  std::vector<ProjectedCode> codes_;
  std::vector<float> coord_, confidence_, intensity_;
  std::vector<uint8_t> valid_, cls_, lit_, mask_;
  std::vector<RoundStats> rounds_;
  std::vector<std::vector<float>> stage_maps_;  // per code: first-pass columns (NaN: not projected);
                                                // only for auto and code_maps
  std::array<size_t, kEnsembleCodes> weak_{};   // per code of codes_: pixels kept through a weak plane
  std::vector<uint32_t> round_codes_;            // code indices of the current round
  bool correction_round_ = false;
  uint32_t corrections_done_ = 0;
  std::string auto_why_;
  bool auto_mode() const { return cfg_.method == "auto"; }
  static std::string fmt_pct(double f) {
    char b[32];
    std::snprintf(b, sizeof b, "%.3f%%", 100.0 * f);
    return b;
  }
  std::string stop_reason_;
  uint32_t round_ = 0, patterns_ = 0;
  double full_scale_ = 0;
};

std::vector<sdk::ParamSpec> common_specs(bool ensemble) {
  std::vector<sdk::ParamSpec> s = {
      {"binarize", sdk::ParamType::string, ensemble ? "white" : "inverse", -kInf, kInf,
       {"inverse", "white"},
       ensemble ? "\"white\" (default, the thesis's 41-image ensemble): no inverse frames, "
                  "L_inv = white + black - L (black = 0 without black_frame); \"inverse\": "
                  "project every plane's inverse (twice the frames)"
                : "\"inverse\": project every plane and its inverse, bit = L > L_inv (Eq. 3.5); "
                  "\"white\": no inverses, L_inv = white + black - L (half the frames)"},
      {"min_contrast", sdk::ParamType::number, 0.03, 0.0, 1.0, {},
       "pixels with white - black below this fraction of full scale are unlit/invalid (~3 sigma "
       "of sensor noise at 8 bit, as for gray)"},
      {"min_bit_margin", sdk::ParamType::number, 0.1, 0.0, 1.0, {},
       "a code's decode is invalid when any strict bit's |L - L_inv| is below this fraction of "
       "white - black (near ties, blurred or global-light-dominated bits)"},
      {"max_weak_error_px", sdk::ParamType::integer, 1, 0.0, 1024.0, {}, kMaxWeakErrorHelp},
  };
  if (ensemble) {
    s.push_back({"black_frame", sdk::ParamType::boolean, false, -kInf, kInf, {},
                 "also project a black frame (B for the synthetic inverse); off by default as in "
                 "the thesis (41 images), since the projector black level is small"});
    s.push_back({"agree_px", sdk::ParamType::number, 1.0, 0.0, 64.0, {},
                 "two codes agree when their columns differ by at most this (px); 1 allows a "
                 "neighbouring column and the 0.5 px quantization of stretched min-SW columns"});
    s.push_back({"correction_rounds", sdk::ParamType::integer, 2, 0.0, 8.0, {},
                 "error-correction rounds at most (thesis §3.4: typically 1-2 suffice); each "
                 "re-projects the ensemble with resolved projector pixels switched off, and "
                 "runs only while error pixels remain"});
    s.push_back({"min_progress", sdk::ParamType::number, 0.0005, 0.0, 1.0, {},
                 "stop correcting when the error pixels, or the pixels the last round resolved, "
                 "are fewer than this fraction of lit pixels (0.05%: another 41 frames would "
                 "not change the error rate measurably)"});
    s.push_back({"code_maps", sdk::ParamType::boolean, false, -kInf, kInf, {},
                 "also output each code's own round-1 column map (proj_col_px_<code>) for inspection"});
    s.push_back({"mask_dilate_px", sdk::ParamType::integer, 2, 0.0, 16.0, {},
                 "switch off projector pixels within this distance of each resolved point's "
                 "projection, closing gaps where camera pixels sample the projector sparsely"});
    s.push_back({"mask_guard_px", sdk::ParamType::integer, 3, 0.0, 16.0, {},
                 "resolved camera pixels within this distance of an error pixel do not switch "
                 "their projector pixels off (they name the error pixel's own projector pixel "
                 "where the camera samples the projector densely)"});
  } else {
    s.push_back({"black_frame", sdk::ParamType::boolean, true, -kInf, kInf, {},
                 "project a black frame (B: contrast rule and synthetic inverse)"});
  }
  return s;
}

}  // namespace

const std::vector<sdk::ParamSpec>& codes_param_specs(const std::string& method) {
  static const std::vector<sdk::ParamSpec> single = common_specs(false);
  static const std::vector<sdk::ParamSpec> ensemble = common_specs(true);
  static const std::vector<sdk::ParamSpec> automatic = [] {
    std::vector<sdk::ParamSpec> s = common_specs(true);
    s.push_back({"auto_tolerance", sdk::ParamType::number, 0.001, 0.0, 1.0, {},
                 "after the first pass (xor04 + minsw), stop when they disagree on fewer than this "
                 "fraction of lit pixels (0.1%: below the ensemble's own residual error on easy "
                 "scenes); otherwise project gray + xor02 and vote with all four"});
    return s;
  }();
  if (method == "auto") return automatic;
  return method == "ensemble" ? ensemble : single;
}

sdk::MethodDescription describe_codes_method(const std::string& method) {
  sdk::MethodDescription d;
  std::string description, patterns;
  if (method == "xor02" || method == "xor04") {
    description = std::string("Logical XOR code ") + (method == "xor02" ? "XOR-02" : "XOR-04") +
                  " (thesis §3.3.1): Gray planes XOR the stripe-width-" +
                  (method == "xor02" ? "2" : "4") +
                  " base plane; for long-range effects (inter-reflections).";
    patterns = "2 + 2*bits (binarize=inverse) or 2 + bits (white), bits = ceil(log2 W)";
  } else if (method == "minsw") {
    description = "10-bit max-min-SW Gray code (thesis §3.3.2), stretched code columns for "
                  "W > 1024; for short-range effects (sub-surface scattering, defocus).";
    patterns = "2 + 2*10 (binarize=inverse) or 2 + 10 (white)";
    d.patterns = 22u;  // defaults: binarize=inverse, black_frame on; 10 bits at any width
  } else if (method == "auto") {
    description = "Model only what the scene needs: first xor04 + minsw (codes for opposite "
                  "global-light effects); where they disagree on more than auto_tolerance of lit "
                  "pixels, add gray + xor02 and vote (the ensemble), then correction rounds only "
                  "while error pixels remain. The report says which codes were used and why.";
    patterns = "1 + ceil(log2 W) + 10 (23 at W = 1280) on easy scenes; + 1 + 2*ceil(log2 W) for "
               "the rest of the ensemble; correction rounds as ensemble";
  } else {
    description = "Ensemble of gray, xor02, xor04 and minsw with per-pixel vote, light-transport "
                  "classification map, error detection and error-correction rounds (thesis "
                  "§3.3.3-3.4).";
    patterns = "1 + 3*ceil(log2 W) + 10 per round (41 for W = 1024, 44 for W = 1280); "
               "correction rounds repeat it";
  }
  d.name = method;
  d.summary = description;
  d.patterns_formula = patterns;  // patterns: null (depends on the projector width) except minsw
  d.outputs = {"proj_col_px", "proj_col_subpx", "valid", "confidence", "depth_mm", "points",
               "valid_fraction", "error_fraction", "decode_ms", "pattern_count", "rounds", "report"};
  if (method == "ensemble" || method == "auto") {
    d.outputs.push_back("transport_class");
    d.outputs.push_back("transport_class_legend");
  }
  d.rounds = 1;
  if (method == "ensemble") d.rounds_formula = "1 + up to correction_rounds";
  if (method == "auto") d.rounds_formula = "1-2 + up to correction_rounds";
  d.params = codes_param_specs(method);
  return d;
}

sdk::Error create_codes_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Params params;
  if (sdk::Error e = sdk::parse_params(args.params, codes_param_specs(args.method), params,
                                       args.method);
      !e.ok())
    return e;
  if (args.rig.is_null())
    return sdk::invalid_argument(args.method + " needs a rig description (rig_json)");
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  Config cfg;
  cfg.method = args.method;
  cfg.inverse = params.get_string("binarize") == "inverse";
  cfg.black = params.get_bool("black_frame");
  cfg.min_contrast = params.get_number("min_contrast");
  cfg.min_bit_margin = params.get_number("min_bit_margin");
  cfg.max_weak_error_px = static_cast<uint32_t>(params.get_int("max_weak_error_px"));
  if (args.method == "ensemble" || args.method == "auto") {
    if (args.method == "auto") cfg.auto_tolerance = params.get_number("auto_tolerance");
    cfg.agree_px = params.get_number("agree_px");
    cfg.correction_rounds = static_cast<uint32_t>(params.get_int("correction_rounds"));
    cfg.min_progress = params.get_number("min_progress");
    cfg.mask_dilate_px = static_cast<uint32_t>(params.get_int("mask_dilate_px"));
    cfg.mask_guard_px = static_cast<uint32_t>(params.get_int("mask_guard_px"));
    cfg.code_maps = params.get_bool("code_maps");
  }
  const uint32_t need = args.method == "xor04" ? 8u : args.method == "xor02" ? 4u : 1u;
  if (rig.projector_width < need)
    return sdk::invalid_argument(args.method + " needs a projector at least " +
                                 std::to_string(need) + " columns wide");
  if ((args.method == "ensemble" || args.method == "auto") && rig.projector_width < 8)
    return sdk::invalid_argument("ensemble needs a projector at least 8 columns wide");
  out = std::make_unique<CodesSession>(std::move(cfg), std::move(rig));
  return sdk::ok();
}

}  // namespace procam::sl
