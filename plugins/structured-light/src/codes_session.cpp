// SPDX-License-Identifier: MIT
// Sessions of the single XOR / min-SW codes and of the ensemble with error
// detection and correction rounds (thesis §3.3–3.4; see codes_session.hpp).
#include "codes_session.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <span>
#include <limits>
#include <mutex>
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
  double min_round_gain = 0.002;
  double min_acceptance = 0.7;
  bool recheck_claims = true;
  double probe_margin = 0.5;
  uint32_t max_weak_error_px = 1;
  // Single codes only (the vote has no intervals): the noise rule and
  // uncertain-plane intervals of gray (decode.hpp, MultiCodeDecoder::
  // set_uncertain_output).
  double noise_k = 3.0;
  double max_uncertainty_px = 0.5;  // one stripe edge; why not gray's 1.5: docs/structured-light.md
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
         "independent, so any two agreeing codes give the right column (except gray with an XOR "
         "code, which share the Gray structure: against a dissenting code that pair is a "
         "conflict); where none agree the pixel is an error (§3.4) and, with correction_rounds > "
         "0, is re-measured while the projector pixels of already-resolved points are switched "
         "off (after Xu & Aliaga), when a 3-frame probe predicts the round pays.";
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
    class_counts_[kUnlit] = n;  // as count_pixels would find before any round
  }  ~CodesSession() override { recycle_members(); }
  CodesSession(const CodesSession&) = delete;
  CodesSession& operator=(const CodesSession&) = delete;


  // Frames: the probe's two frames are kept (the next correction round's
  // masked white and masked finest xor02 plane); auto's first-step white is
  // kept for the second step. A round leaves frames it already holds out of
  // its plan and feeds the copies to its decoder: plan frame i is decoder
  // frame plan_to_decoder_[i].
  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    const ScopedMs timed(decode_ms_);
    if (step_ == Step::probe) {
      if (index >= probe_.size())
        return sdk::invalid_argument("correction probe: frame index " + std::to_string(index) + " (the probe has 3 frames)");
      probe_[index].store(frame);
      return sdk::ok();
    }
    if (!decoder_ || !round_open_) return sdk::state_error("add_frame outside a round");
    if (index >= plan_to_decoder_.size())
      return sdk::invalid_argument("frame index " + std::to_string(index) + " beyond the round's " +
                                   std::to_string(plan_to_decoder_.size()) + " frames");
    if (keep_white_ && index == 0) white_.store(frame);
    return decoder_->add_frame(plan_to_decoder_[index], frame);
  }

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    has_round = false;
    std::vector<uint32_t> subset;  // code indices projected this round
    Step step = Step::first;
    std::vector<std::pair<uint32_t, const FrameCopy*>> reuse;  // layout frame <- kept copy
    if (round_ == 0) {
      if (auto_mode()) {
        subset = {kXor04, kMinsw};  // cheapest pair of complementary codes
      } else {
        for (uint32_t k = 0; k < codes_.size(); ++k) subset.push_back(k);
      }
      keep_white_ = auto_mode();
    } else if (auto_mode() && step_ == Step::first) {
      // Step 2 of auto: gray + xor02 can only resolve pixels where xor04 and
      // minsw dispute the column (all others are settled), so the predicted
      // gain is the disputed fraction.
      const RoundStats& last = rounds_.back();
      const double frac = fraction(last.errors, last.lit);
      nlohmann::json st = {{"step", "add gray + xor02 (ensemble vote)"}, {"predicted_gain", frac},
                           {"threshold", cfg_.auto_tolerance}, {"flagged_before", frac}};
      if (frac < cfg_.auto_tolerance) {
        auto_why_ = "xor04 and minsw (built for opposite effects) agree on all but " + fmt_pct(frac) +
                    " of lit pixels (< auto_tolerance " + fmt_pct(cfg_.auto_tolerance) +
                    "): no global-light errors to resolve, so no further patterns";
        st["taken"] = false;
        steps_.push_back(st);
        return sdk::ok();
      }
      auto_why_ = "xor04 and minsw disagree on " + fmt_pct(frac) +
                  " of lit pixels: projected gray and xor02 too and voted with all four codes";
      st["taken"] = true;
      steps_.push_back(st);
      subset = {kGray, kXor02};
      step = Step::codes;
      reuse.push_back({0, &white_});
      keep_white_ = false;
    } else if (step_ == Step::probe) {
      // The probe measured what the mask takes away (correction.hpp
      // forecast_round): project the round only when it is expected to pay.
      const double gain = forecast_.predicted_gain();
      nlohmann::json& st = steps_.back();
      st["predicted_gain"] = gain;
      st["threshold"] = cfg_.min_round_gain;
      if (gain < cfg_.min_round_gain) {
        stop_reason_ = "predicted gain " + fmt_pct(gain) + " of lit pixels (fixable flagged pixels) below min_round_gain " +
                       fmt_pct(cfg_.min_round_gain) + ": round skipped";
        st["taken"] = false;
        return sdk::ok();
      }
      st["taken"] = true;
      step = Step::correction;
      for (uint32_t k = 0; k < codes_.size(); ++k) subset.push_back(k);
      reuse.push_back({0, &probe_[0]});  // + the xor02 plane, below
    } else {
      if (!want_more_round()) return sdk::ok();
      // Three-frame probe: the next round's masked white and masked finest
      // xor02 plane (stripes 2 px wide) with its inverse, to predict what it
      // can fix (correction.hpp forecast_round).
      mask_ = correction_mask(rig_, coord_, valid_, cls_, cfg_.mask_dilate_px, cfg_.mask_guard_px);
      const ProjectedCode& x02 = codes_[kXor02];
      const MultiLayout pl = make_multi_layout({x02}, true, false);  // white, (plane, inverse) per plane
      std::vector<uint8_t> skip(pl.frames.size(), 1);
      skip[0] = 0;
      skip[pl.frames.size() - 2] = 0;  // plane bits-1: the stripe-width-2 base
      skip[pl.frames.size() - 1] = 0;  // and its inverse
      render_multi_plan(pl, {x02}, rig_.projector_width, rig_.projector_height, &mask_, plan, &skip);
      plan.set_note(cfg_.method + ": correction probe (3 frames: masked white, masked finest xor02 plane "
                    "and its inverse) — predicts what the next correction round can fix before projecting "
                    "it; the round reuses the white and the plane");
      steps_.push_back({{"step", "correction round " + std::to_string(corrections_done_ + 1)},
                        {"flagged_before", fraction(errors_before_round(), rounds_.back().lit)}});
      step_ = Step::probe;
      patterns_ += plan.size();
      ++round_;
      has_round = true;
      return sdk::ok();
    }
    const bool correction = step == Step::correction;
    round_codes_ = subset;
    std::vector<ProjectedCode> codes;
    for (uint32_t k : subset) codes.push_back(codes_[k]);
    MultiLayout layout = make_multi_layout(codes, cfg_.inverse, cfg_.black);
    if (correction)  // the probe's plane (and inverse): xor02's last (finest) plane
      for (uint32_t f = 0; f < layout.frames.size(); ++f) {
        const MultiFrame& mf = layout.frames[f];
        if (subset[mf.code] != kXor02 || mf.plane + 1 != layout.bits[mf.code]) continue;
        if (mf.kind == FrameKind::plane) reuse.push_back({f, &probe_[1]});
        if (mf.kind == FrameKind::inverse) reuse.push_back({f, &probe_[2]});
      }
    std::vector<uint8_t> skip(layout.frames.size(), 0);
    for (const auto& r : reuse) skip[r.first] = 1;
    plan_to_decoder_.clear();
    for (uint32_t f = 0; f < layout.frames.size(); ++f)
      if (skip[f] == 0) plan_to_decoder_.push_back(f);
    render_multi_plan(layout, codes, rig_.projector_width, rig_.projector_height,
                      correction ? &mask_ : nullptr, plan, &skip);
    std::string note = cfg_.method + ": " + std::to_string(plan.size()) + " frames (";
    for (size_t j = 0; j < codes.size(); ++j) note += (j ? ", " : "") + codes[j].id;
    note += ")";
    if (!reuse.empty()) note += ", " + std::to_string(reuse.size()) + " frame(s) reused from the previous round";
    if (correction) {
      ++corrections_done_;
      note += " — correction round " + std::to_string(corrections_done_) + ": " +
              std::to_string(errors_before_round()) +
              " flagged pixels re-measured with resolved projector pixels switched off";
    }
    plan.set_note(note);
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    decoder_.emplace(std::move(layout), codes, cam.width, cam.height, rig_.threads,
                     cfg_.max_weak_error_px,
                     codes_.size() > 1 ? MultiCodeDecoder::Output::vote
                                       : MultiCodeDecoder::Output::per_code);
    if (codes_.size() == 1 && cfg_.max_uncertainty_px > 0)
      decoder_->set_uncertain_output(true, static_cast<float>(cfg_.max_uncertainty_px));
    for (const auto& r : reuse) {
      if (r.second->empty()) return sdk::state_error("a kept frame of the previous round is missing");
      if (sdk::Error e = decoder_->add_frame(r.first, r.second->image()); !e.ok()) return e;
    }
    round_open_ = true;
    patterns_ += plan.size();
    ++round_;
    step_ = step;
    has_round = true;
    return sdk::ok();
  }

  sdk::Error end_round() override {
    const ScopedMs timed(decode_ms_);
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    const size_t n = size_t{cam.width} * cam.height;
    RoundStats stats;
    stats.round = round_;
    if (step_ == Step::probe) {  // the forecast of the next correction round
      for (const FrameCopy& c : probe_)
        if (c.empty()) return sdk::state_error("correction probe: a frame did not arrive");
      const std::vector<float> masked = probe_[0].intensity(), plane = probe_[1].intensity(),
                               inverse = probe_[2].intensity();
      forecast_ = forecast_round(rig_, mask_, coord_, cls_, lit_, masked, intensity_, plane, inverse,
                                 static_cast<float>(cfg_.probe_margin), static_cast<float>(cfg_.min_contrast),
                                 cfg_.black, cfg_.code_maps ? &forecast_map_ : nullptr);
      nlohmann::json& st = steps_.back();
      st["probe"] = {{"flagged", forecast_.flagged}, {"own_light_off", forecast_.own_light_off},
                     {"unchanged", forecast_.unchanged}, {"fine_stripes_lost", forecast_.blurred},
                     {"too_dark_under_mask", forecast_.too_dark}, {"fixable", forecast_.fixable}};
      stats.kind = "probe";
      stats.errors = errors_before_round();
      stats.lit = rounds_.back().lit;
      rounds_.push_back(stats);
      return sdk::ok();
    }
    const bool first_pass = step_ != Step::correction;
    stats.kind = step_ == Step::correction ? "correction" : step_ == Step::codes ? "codes" : "first";
    if (codes_.size() == 1) {
      MultiResult& r = decoder_->finish(cfg_.min_contrast, cfg_.min_bit_margin, cfg_.noise_k);
      full_scale_ = r.full_scale;
      weak_[0] += r.weak[0];
      noise_ = r.noise;
      noise_k_used_ = r.noise_k;
      uncertainty_ = std::move(r.codes[0].uncertainty);
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
      // codes not projected. Per-code maps are kept in the first pass: auto's
      // second step votes with them, and the conflict rule reads them.
      // Kept only where read later: auto (its second step votes with the
      // first step's maps) and code_maps (an output); the conflict rule runs
      // in the vote itself (VoteSpec::conflicts; issue 17: 4 x 9 MB fewer
      // writes after the last frame).
      const bool keep_maps = first_pass && (auto_mode() || cfg_.code_maps);
      if (keep_maps && stage_maps_.empty()) {  // written whole by the vote for this round's
        stage_maps_.resize(kEnsembleCodes);     // codes; NaN for the others (auto's first step)
        for (uint32_t k = 0; k < kEnsembleCodes; ++k) {
          sdk::take_map(stage_maps_[k], n);
          if (std::find(round_codes_.begin(), round_codes_.end(), k) == round_codes_.end())
            std::fill(stage_maps_[k].begin(), stage_maps_[k].end(), std::numeric_limits<float>::quiet_NaN());
        }
      }
      VoteSpec spec;
      spec.agree_px = static_cast<float>(cfg_.agree_px);
      for (size_t j = 0; j < round_codes_.size(); ++j) {
        spec.round_code[round_codes_[j]] = static_cast<int32_t>(j);
        if (keep_maps) spec.keep[round_codes_[j]] = stage_maps_[round_codes_[j]].data();
      }
      for (uint32_t k = 0; k < kEnsembleCodes; ++k)
        if (spec.round_code[k] < 0) spec.external[k] = stage_maps_.at(k).data();
      // Conflict rule (correction.hpp) once all four codes are in the vote.
      spec.conflicts = first_pass && (!auto_mode() || step_ == Step::codes);
      // The pixel counts in the vote's own pass where the session keeps the
      // vote's maps as they are: the first round's lit, valid and classes
      // (auto's second step keeps round 1's lit; a correction merges).
      spec.count = first_pass && round_ == 1;
      MultiResult& r = decoder_->finish_vote(cfg_.min_contrast, cfg_.min_bit_margin, spec);
      fused_counts_ = spec.count;
      if (fused_counts_) {
        stats.errors += r.counts.flagged;
        stats.lit += r.counts.lit;
        valid_count_ = r.counts.valid;
        std::copy(std::begin(r.counts.cls), std::end(r.counts.cls), class_counts_.begin());
      }
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
        conflicts_ = r.conflicts;
      } else {  // correction: flagged pixels take the new result where every
        // ground-truth-free test passes, and refuted first-pass claims are
        // replaced or made invalid (correction.hpp merge_correction;
        // r.intensity is the masked white frame)
        // The merge keeps the previous values of every pixel it changes, to
        // take the round's flagged-pixel answers back when its acceptance
        // rate is too low (below).
        std::vector<MergeUndo> undo;
        MergeCounts mc;
        stats.resolved += merge_correction(rig_, mask_, v, r.intensity, intensity_, coord_, valid_,
                                           confidence_, cls_, cfg_.recheck_claims, &mc, &undo);
        stats.refuted = mc.refuted;
        stats.refuted_moved = mc.refuted_moved;
        stats.acceptance = forecast_.fixable > 0 ? fraction(stats.resolved, forecast_.fixable) : 0.0;
        // Issue 18, "if the round's acceptance rate is low, stop": a round
        // whose answers passed the tests for fewer than min_acceptance of the
        // pixels its probe called fixable is discarded whole, not only the
        // last one (decide_correction then stops). Its probe's model (the
        // mask removes their global light) failed for most of them, so the
        // answers that did pass are suspect too: on the steel ball (0.62)
        // they were wrong 2.0 % of the time against the scene's 0.87 %.
        // Refuted claims (recheck_claims) are not taken back: their test does
        // not rest on the probe's model (a valid pixel decodes under the mask,
        // all four codes agreeing, elsewhere), and the value they had is known
        // to be a global path's.
        stats.discarded = stats.acceptance < cfg_.min_acceptance;
        for (const MergeUndo& u : undo) {
          if (stats.discarded && u.was_flagged) {
            coord_[u.i] = u.coord;
            confidence_[u.i] = u.confidence;
            valid_[u.i] = u.valid;
            cls_[u.i] = u.cls;
          } else if (valid_[u.i] != 0) {
            if (resolved_in_.size() != n) resolved_in_.assign(n, 0);
            resolved_in_[u.i] = static_cast<uint8_t>(corrections_done_);
          }
        }
      }
      recycle_maps(std::move(r));  // what this round's result still holds
    }
    // The decoder (its thread pool, its per-code state) is destroyed by the
    // next round's emplace or with the session, not here: joining its threads
    // and freeing its memory took 6-10 ms of the time after the last frame at
    // load ~12 (issue 17).
    round_open_ = false;
    if (!fused_counts_) count_pixels(stats);  // else counted by the vote, above
    fused_counts_ = false;
    if (step_ != Step::first && !steps_.empty()) {  // measured change of the step
      nlohmann::json& st = steps_.back();
      st["flagged_after"] = fraction(stats.errors, stats.lit);
      st["measured_change"] = st["flagged_after"].get<double>() - st["flagged_before"].get<double>();
      if (step_ == Step::correction) {
        st["resolved"] = stats.resolved;
        st["acceptance"] = stats.acceptance;
        st["discarded"] = stats.discarded;
        st["refuted"] = stats.refuted;
        st["refuted_moved"] = stats.refuted_moved;
      }
    }
    rounds_.push_back(stats);
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    out.set_release(sdk::give_map, sdk::give_map);  // the next scan's decoder reuses the maps' pages
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    const uint32_t w = cam.width, h = cam.height;
    // Recycled map storage (map_cache.hpp): refine_columns writes every
    // pixel, so stale contents are fine, and a fresh 9 MB vector here was
    // zeroed and page-faulted on every scan's outputs().
    std::vector<float> subpx;
    sdk::take_map(subpx, coord_.size());
    // Issue 18 (session 11): where the vote is not unanimous (confidence < 1:
    // fewer than four codes agree pairwise), the reported column is the
    // refined column rounded to the nearest half column (the key grid of
    // proj_col_px), not the vote's value. Codes can share a bias of about a
    // column under sub-surface light (marble: gray and xor04 outvote min-SW;
    // every gross error of the ensemble there, 3 084 pixels, was such a
    // partial-class pixel, while the refined column was > 1 off on 0.0001 %
    // of pixels). refine_columns clamps to +-1 column of the voted value and
    // keeps it where the row gives no consistent neighbours, so this moves a
    // value by at most one column. Unanimous pixels keep their median (the
    // refined column was worse there near creases: val-room-corner).
    // Runs before triangulation, so depth uses the reported column.
    // One pass (issue 17): each band of rows is refined and then reported
    // while it is in cache. Both are row-local -- refine_columns reads only
    // the pixel's own row of coord_, report_columns writes only that pixel
    // -- so a band's report cannot change what another band refines, and
    // the result is the same as refining the whole map first. The bands run
    // on the decoder's threads (MultiCodeDecoder::pool), several per thread
    // so a thread that is not scheduled delays only its band.
    const bool reported = codes_.size() > 1;
    const auto refine_and_report = [&](uint32_t y0, uint32_t y1) {
      refine_columns(coord_.data(), w, y0, y1, SubpixelOptions{}, subpx.data());
      if (!reported) return;
      const size_t b = size_t{y0} * w, e = size_t{y1} * w;
      report_columns(coord_.data() + b, valid_.data() + b, confidence_.data() + b, subpx.data() + b, e - b);
    };
    if (decoder_)
      decoder_->pool().run(h, refine_and_report);
    else
      sdk::parallel_rows(h, rig_.threads, refine_and_report);
    std::optional<sdk::DepthResult> depth;
    if (rig_.can_triangulate(0)) {
      const ScopedMs timed(decode_ms_);
      depth = sdk::triangulate_columns(cam.calibration, rig_.projector, w, h, coord_.data(),
                                       intensity_.data(), rig_.threads);
    }
    sdk::StandardOutputs standard;
    standard.decode_ms = decode_ms_;  // the triangulation above included
    standard.pattern_count = patterns_;
    const std::array<size_t, kTransportClassCount>& counts = class_counts_;  // of the last end_round
    standard.valid_pixels = valid_count_;
    standard.total_pixels = valid_.size();
    const size_t lit = rounds_.empty() ? 0 : rounds_.back().lit;
    const size_t errors = rounds_.empty() ? 0 : rounds_.back().errors;
    out.add_image("proj_col_subpx", "px",
                  "sub-pixel refined column (line fit through stripe steps along the row, "
                  "subpixel.hpp); NaN: invalid",
                  w, h, std::move(subpx));
    out.add_image("proj_col_px", "px", "decoded projector column per camera pixel (NaN: invalid)",
                  w, h, std::move(coord_));
    if (!uncertainty_.empty())
      out.add_image("proj_col_uncertainty_px", "px",
                    "half-width of the column interval the uncertain planes allow (proj_col_px is "
                    "its centre); 0: every plane certain; NaN: invalid",
                    w, h, std::move(uncertainty_));
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
                        "partial agreement, 5 error (no two codes agree), 6 conflict (a correlated pair "
                        "against a dissenting code, e.g. a mirror path)",
                        w, h, std::move(cls_),
                        {{kUnlit, transport_class_name(kUnlit), "no projector light reaches the pixel"},
                         {kAllAgree, transport_class_name(kAllAgree), "all four codes agree: direct light dominates"},
                         {kInterreflection, transport_class_name(kInterreflection),
                          "only the XOR codes agree: inter-reflections (long range)"},
                         {kSubsurface, transport_class_name(kSubsurface),
                          "only the Gray codes agree: sub-surface scattering or defocus (short range)"},
                         {kPartial, transport_class_name(kPartial), "some codes agree"},
                         {kError, transport_class_name(kError), "no two codes agree: error pixel (thesis §3.4)"},
                         {kConflict, transport_class_name(kConflict),
                          "only gray and an XOR code agree while another code disagrees: two light paths "
                          "(e.g. a mirror reflection) compete; left invalid rather than voted"}});
    if (!resolved_in_.empty())
      out.add_image("resolved_in_round", "",
                    "correction round whose answer a pixel took (1, 2, ...); 0: first-pass value or invalid",
                    w, h, std::move(resolved_in_));
    if (!forecast_map_.empty())
      out.add_image("correction_forecast", "",
                    "the last correction probe's verdict per pixel (code_maps): 0 not flagged, 1 own "
                    "light switched off, 2 light unchanged, 3 fine stripes still lost, 4 fixable, "
                    "5 too dark under the mask (masked white below min_contrast: the round cannot decode it)",
                    w, h, std::move(forecast_map_));
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
    for (const RoundStats& s : rounds_) {
      nlohmann::json r = {{"round", s.round}, {"kind", s.kind}, {"flagged_pixels", s.errors}};
      if (std::string(s.kind) == "correction") {
        r["resolved"] = s.resolved;
        r["acceptance"] = s.acceptance;
        r["discarded"] = s.discarded;
      }
      rounds.push_back(r);
    }
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
    if (!ensemble) {
      report["noise_k"] = cfg_.noise_k;
      report["max_uncertainty_px"] = cfg_.max_uncertainty_px;
      report["noise"] = {{"measured", noise_.measured}, {"k_used", noise_k_used_}, {"a", noise_.a},
                         {"b", noise_.b}, {"pairs", noise_.pairs}, {"sample_pixels", noise_.pixels}};
    }
    if (auto_mode()) {
      report["auto_tolerance"] = cfg_.auto_tolerance;
      report["auto_decision"] = auto_why_;
    }
    if (ensemble) {
      report["agree_px"] = cfg_.agree_px;
      report["correction_rounds_max"] = cfg_.correction_rounds;
      report["mask_dilate_px"] = cfg_.mask_dilate_px;
      report["mask_guard_px"] = cfg_.mask_guard_px;
      report["min_round_gain"] = cfg_.min_round_gain;
      report["min_acceptance"] = cfg_.min_acceptance;
      report["recheck_claims"] = cfg_.recheck_claims;
      report["conflicts"] = conflicts_;
      report["steps"] = steps_;
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
    const char* kind = "first";  // first, codes (auto's second step), probe, correction
    size_t errors = 0, resolved = 0, lit = 0;  // errors: flagged pixels (errors + conflicts)
    double acceptance = 1.0;                   // correction: resolved / forecast fixable
    bool discarded = false;                    // correction: acceptance < min_acceptance, taken back
    size_t refuted = 0, refuted_moved = 0;     // correction: first-pass claims refuted (merge_correction)
  };
  enum class Step { first, codes, probe, correction };

  // A copy of one camera frame (the host's memory is call-scoped).
  class FrameCopy {
   public:
    void store(const procam_image& f) {
      img_ = f;
      const size_t bpp = f.pixel_type == PROCAM_PIXEL_U8 ? 1 : f.pixel_type == PROCAM_PIXEL_U16 ? 2 : 4;
      const size_t row = size_t{f.width} * f.channels * bpp;
      bytes_.resize(row * f.height);
      for (uint32_t y = 0; y < f.height; ++y)
        std::memcpy(bytes_.data() + y * row, static_cast<const uint8_t*>(f.data) + y * f.stride_bytes, row);
      img_.stride_bytes = row;
      img_.data = bytes_.data();
    }
    bool empty() const { return bytes_.empty(); }
    const procam_image& image() const { return img_; }
    // Channel 0 / full scale (2^bit_depth - 1; F32: 1) per pixel.
    std::vector<float> intensity() const {
      const size_t n = size_t{img_.width} * img_.height;
      std::vector<float> out(n);
      const double fs = img_.pixel_type == PROCAM_PIXEL_F32 ? 1.0 : std::ldexp(1.0, static_cast<int>(img_.bit_depth)) - 1.0;
      const size_t c = img_.channels;
      for (size_t i = 0; i < n; ++i) {
        double v = 0;
        if (img_.pixel_type == PROCAM_PIXEL_U8) v = bytes_[i * c];
        else if (img_.pixel_type == PROCAM_PIXEL_U16) v = reinterpret_cast<const uint16_t*>(bytes_.data())[i * c];
        else v = reinterpret_cast<const float*>(bytes_.data())[i * c];
        out[i] = static_cast<float>(v / fs);
      }
      return out;
    }

   private:
    procam_image img_{};
    std::vector<uint8_t> bytes_;
  };
  static double fraction(size_t a, size_t b) { return b > 0 ? static_cast<double>(a) / static_cast<double>(b) : 0.0; }


  // The per-pixel counts of a finished round, one pass in row bands:
  // stats.errors (flagged pixels) and stats.lit, and for outputs() the valid
  // pixels and the transport-class histogram (class_counts_, valid_count_).
  void count_pixels(RoundStats& stats) {
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    struct Counts {
      size_t errors = 0, lit = 0, valid = 0;
      std::array<size_t, kTransportClassCount> cls{};
    } total;
    std::mutex mutex;
    sdk::parallel_rows(cam.height, rig_.threads, [&](uint32_t y0, uint32_t y1) {
      Counts c;
      for (size_t i = size_t{y0} * cam.width, e = size_t{y1} * cam.width; i < e; ++i) {
        c.errors += flagged(cls_[i]) ? 1u : 0u;
        c.lit += lit_[i] != 0 ? 1u : 0u;
        c.valid += valid_[i] != 0 ? 1u : 0u;
        ++c.cls[std::min<size_t>(cls_[i], kTransportClassCount - 1)];
      }
      const std::lock_guard<std::mutex> lock(mutex);
      total.errors += c.errors;
      total.lit += c.lit;
      total.valid += c.valid;
      for (size_t k = 0; k < kTransportClassCount; ++k) total.cls[k] += c.cls[k];
    });
    stats.errors += total.errors;
    stats.lit += total.lit;
    valid_count_ = total.valid;
    class_counts_ = total.cls;
  }

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
    p.acceptance_last = last.acceptance;
    p.min_acceptance = cfg_.min_acceptance;
    const CorrectionDecision d = decide_correction(p);
    if (d.stop_reason != nullptr) stop_reason_ = d.stop_reason;
    return d.more;
  }

  // Maps not handed to the host go back to the map cache (map_cache.hpp).
  void recycle_members() noexcept {
    for (std::vector<float>* v : {&coord_, &confidence_, &intensity_}) sdk::give_map(std::move(*v));
    for (std::vector<uint8_t>* v : {&valid_, &cls_, &lit_}) sdk::give_map(std::move(*v));
    for (std::vector<float>& v : stage_maps_) sdk::give_map(std::move(v));
  }

  Config cfg_;
  sdk::Rig rig_;
  std::vector<ProjectedCode> codes_;
  std::vector<float> coord_, confidence_, intensity_;
  std::vector<float> uncertainty_;  // single codes with intervals: proj_col_uncertainty_px
  NoiseFit noise_;                  // single codes: the capture's fitted noise
  double noise_k_used_ = 0;
  std::vector<uint8_t> valid_, cls_, lit_, mask_;
  std::vector<RoundStats> rounds_;
  std::vector<std::vector<float>> stage_maps_;  // per code: first-pass columns (NaN: not projected);
                                                // only for auto and code_maps
  std::array<size_t, kEnsembleCodes> weak_{};   // per code of codes_: pixels kept through a weak plane
  std::vector<uint32_t> round_codes_;            // code indices of the current round
  Step step_ = Step::first;        // kind of the current (or last) round
  FrameCopy white_;                // auto's first-step white
  std::array<FrameCopy, 3> probe_; // the probe's masked white, finest xor02 plane, its inverse
  bool keep_white_ = false;
  std::vector<uint32_t> plan_to_decoder_;  // this round's plan frame -> decoder (layout) frame
  bool round_open_ = false;        // decoder_ takes frames: between next_plan and end_round
  bool fused_counts_ = false;      // end_round: finish_vote counted the pixels (VoteSpec::count)
  RoundForecast forecast_;         // of the last probe
  size_t conflicts_ = 0;           // pixels labelled kConflict by the first pass
  size_t valid_count_ = 0;         // valid pixels after the last end_round (count_pixels)
  std::array<size_t, kTransportClassCount> class_counts_{};  // transport classes, likewise
  std::vector<uint8_t> resolved_in_;  // per pixel: the correction round it was resolved in (0: none)
  std::vector<uint8_t> forecast_map_;  // code_maps: the last probe's per-pixel verdict
  nlohmann::json steps_ = nlohmann::json::array();  // per step: predicted gain, measured change
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
  if (!ensemble) {
    s.push_back({"noise_k", sdk::ParamType::number, 3.0, 0.0, 100.0, {},
                 "a bit is also rejected when |L - L_inv| <= noise_k * sigma_d, sigma_d^2 = a + b * "
                 "(white + black) fitted to this capture's pattern/inverse pairs; 3 lets a pure-noise "
                 "bit through 0.27% of the time (Gaussian). 0 = off; binarize=white has no pairs to "
                 "measure and skips it (as for gray)"});
    s.push_back({"max_uncertainty_px", sdk::ParamType::number, 0.5, 0.0, 512.0, {},
                 "a pixel with uncertain planes (at most 3 strict ones, plus the tolerated weak "
                 "ones) gets the interval of every column its uncertain bits allow when the "
                 "candidates are neighbouring code words and the half-width is at most this "
                 "(proj_col_px = its centre, proj_col_uncertainty_px = the half-width), and is "
                 "invalid otherwise; min-SW spreads its stripe edges over all planes, so without "
                 "this every pixel near any edge is lost. 0.5 = one blurred stripe edge (two "
                 "neighbouring columns, centre within a column of the truth): on the sim it keeps "
                 "up to 8 points more of min-SW's lit pixels, its gross-error rate moving by at "
                 "most +0.08 points; 1.5 keeps more but raises XOR-04's errors up to 28x "
                 "(docs/structured-light.md). 0 = exact pixels only"});
  }
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
    s.push_back({"min_round_gain", sdk::ParamType::number, 0.002, 0.0, 1.0, {},
                 "before each correction round a three-frame probe (the round's masked white and "
                 "finest xor02 plane with its inverse) counts the flagged pixels it can fix (own "
                 "light kept, >= 10% of their light switched off, direct-dominated once masked); "
                 "the round is projected only when they are at least this fraction "
                 "of lit pixels (0.2%: a round costs as many patterns as the first pass)"});
    s.push_back({"probe_margin", sdk::ParamType::number, 0.5, 0.0, 1.0, {},
                 "a flagged pixel counts as fixable only when the probe's masked finest xor02 "
                 "plane (2 px stripes) and its inverse differ by at least this fraction of its masked "
                 "white (0.5: direct light >= the global light and ambient the mask leaves)"});
    s.push_back({"min_acceptance", sdk::ParamType::number, 0.7, 0.0, 1.0, {},
                 "a correction round whose new values passed the no-ground-truth tests "
                 "(all four codes agree, light kept and reduced, column clear of the mask) for "
                 "fewer than this fraction of the pixels its probe predicted fixable is discarded "
                 "(its flagged pixels' values taken back) and correcting stops"});
    s.push_back({"recheck_claims", sdk::ParamType::boolean, true, -kInf, kInf, {},
                 "in a correction round, a valid pixel that decodes under the mask with all four "
                 "codes agreeing more than 2 columns from its first-pass column was lit by a global "
                 "(mirror) path in the first pass (a right column would still win, or go dark with "
                 "its projector pixel off): it takes the round's column if that passes the merge's "
                 "geometric tests, else it becomes invalid"});
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
                  "global-light effects); where they dispute more than auto_tolerance of lit "
                  "pixels, add gray + xor02 and vote (the ensemble), then correction rounds only "
                  "when a 3-frame probe predicts they pay. The report gives per step the "
                  "predicted gain and the measured change.";
    patterns = "1 + ceil(log2 W) + 10 (22 at W = 1280) on easy scenes; + 2*ceil(log2 W) (the "
               "ensemble's 44 in all) where codes dispute; + 3 per correction probe and "
               "3*ceil(log2 W) + 9 per round taken (42 at 1280), as ensemble";
  } else {
    description = "Ensemble of gray, xor02, xor04 and minsw with per-pixel vote, light-transport "
                  "classification map, error detection and error-correction rounds (thesis "
                  "§3.3.3-3.4).";
    patterns = "1 + 3*ceil(log2 W) + 10 (41 for W = 1024, 44 for W = 1280); + 3 per correction "
               "probe and 3*ceil(log2 W) + 9 per correction round taken (42 at 1280)";
  }
  d.name = method;
  d.summary = description;
  d.patterns_formula = patterns;  // patterns: null (depends on the projector width) except minsw
  d.outputs = {"proj_col_px", "proj_col_subpx", "valid", "confidence", "depth_mm", "points",
               "valid_fraction", "error_fraction", "decode_ms", "pattern_count", "rounds", "report"};
  if (method == "ensemble" || method == "auto") {
    d.outputs.push_back("transport_class");
    d.outputs.push_back("transport_class_legend");
  } else {
    d.outputs.push_back("proj_col_uncertainty_px");  // absent with max_uncertainty_px = 0
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
  if (args.method != "ensemble" && args.method != "auto") {
    cfg.noise_k = params.get_number("noise_k");
    cfg.max_uncertainty_px = params.get_number("max_uncertainty_px");
  }
  if (args.method == "ensemble" || args.method == "auto") {
    if (args.method == "auto") cfg.auto_tolerance = params.get_number("auto_tolerance");
    cfg.agree_px = params.get_number("agree_px");
    cfg.correction_rounds = static_cast<uint32_t>(params.get_int("correction_rounds"));
    cfg.min_progress = params.get_number("min_progress");
    cfg.min_round_gain = params.get_number("min_round_gain");
    cfg.min_acceptance = params.get_number("min_acceptance");
    cfg.recheck_claims = params.get_bool("recheck_claims");
    cfg.probe_margin = params.get_number("probe_margin");
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
