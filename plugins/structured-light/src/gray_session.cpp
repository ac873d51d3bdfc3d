// SPDX-License-Identifier: MIT
// Method "gray" session: plan, streaming decode, triangulation, outputs.
#include "gray_session.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <limits>
#include <optional>
#include <utility>

#include "gray_code.hpp"
#include "procam/sdk/map_cache.hpp"
#include "plan_layout.hpp"
#include "round_decoder.hpp"
#include "streaming_session.hpp"
#include "subpixel.hpp"
#include "procam/sdk/triangulate.hpp"

namespace procam::sl {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr const char* kModel = "direct illumination only (no global-light handling)";
constexpr const char* kWhy =
    "Conventional Gray code (thesis §3.2): each camera pixel is assumed to see one projector "
    "pixel with no global light and no defocus (Eq. 3.3-3.4 with L_g = 0, alpha = 1), so "
    "L > L-bar (Eq. 3.5) decides every bit and ceil(log2 W) planes suffice — the fewest "
    "patterns of the binary codes. It errs under long-range inter-reflections (low-frequency "
    "planes) and sub-surface scattering or defocus (high-frequency planes); bits whose margin "
    "|L - L-bar| is below min_bit_margin of the pixel's contrast are reported invalid instead "
    "of guessed. Use an ensemble method for scenes with strong global light.";

struct GrayConfig {
  bool rows = false;
  bool inverse = true;         // binarize "inverse" (true) or "white"
  double min_contrast = 0.03;  // fraction of full scale
  double min_bit_margin = 0.1; // fraction of the pixel's contrast
  uint32_t max_weak_error_px = 1;  // tolerated weak planes (decode.hpp)
  double noise_k = 3.0;            // noise rule (decode.hpp): margins within k sigma_d rejected
  double max_uncertainty_px = 1.5;  // widest half-interval of uncertain planes (decode_uncertain)
  bool tie_intervals = false;       // exact ties enumerated too (decode_uncertain)
  uint32_t fill_passes = 0;         // neighbour-consistent candidate selection (neighbour_fill.hpp)
  uint32_t fill_min_neighbours = 1;
  bool fill_extrapolate = true;
  bool fill_ties = true;
  StripeAverageParams stripe;       // stripe-averaged margins behind a gate (stripe_average.hpp)
};

// One line for the report: what the gate saw and whether rule A ran.
std::string stripe_summary(const StripeAverageReport& r, const StripeAverageParams& p) {
  if (p.mode == StripeAverageMode::off) return "stripe averaging off";
  if (!r.available) return "stripe averaging not available: " + r.why_not;
  char buf[192];
  std::snprintf(buf, sizeof buf, "finest planes noise-bound on %.1f %% of lit pixels (gate %.1f %%): %s",
                100.0 * r.f_noise, 100.0 * p.gate,
                r.fired ? "stripe averaging used" : "stripe averaging not used");
  return buf;
}

class GraySession final : public StreamingSession<BinaryRoundDecoder> {
 public:
  GraySession(GrayConfig cfg, sdk::Rig rig)
      : cfg_(cfg), rig_(std::move(rig)), cols_(make_gray_code(rig_.projector_width)) {
    if (cfg_.rows) rows_ = make_gray_code(rig_.projector_height);
    // Per-pixel loops spawn this many threads per frame; beyond a few dozen
    // row bands only add start-up cost.
    rig_.threads = std::clamp(rig_.threads, 1u, 64u);
  }
  // Maps the host did not take (intensity) go back to the map cache.
  ~GraySession() override { recycle_maps(std::move(result_)); }
  GraySession(const GraySession&) = delete;
  GraySession& operator=(const GraySession&) = delete;

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (round_started_) {  // single-round method
      has_round = false;
      return sdk::ok();
    }
    const StripeCode* rows = rows_ ? &*rows_ : nullptr;
    Layout layout = make_layout(cols_, rows, cfg_.inverse);
    render_plan(layout, cols_, rows, rig_.projector_width, rig_.projector_height, plan);
    plan.set_note("gray: " + std::to_string(layout.frames.size()) + " frames — white, black, " +
                  std::to_string(layout.col_bits) + " column planes" +
                  (rows ? " and " + std::to_string(layout.row_bits) + " row planes" : "") +
                  (cfg_.inverse ? ", each with its inverse" : ""));
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    decoder_.emplace(std::move(layout), cols_, rows, cam.width, cam.height, rig_.threads,
                     cfg_.max_weak_error_px);
    decoder_->set_uncertain_output(true, static_cast<float>(cfg_.max_uncertainty_px),
                                     cfg_.tie_intervals);
    NeighbourFillRule fill;
    fill.passes = cfg_.fill_passes;
    fill.min_neighbours = cfg_.fill_min_neighbours;
    fill.extrapolate = cfg_.fill_extrapolate;
    decoder_->set_neighbour_fill(fill, cfg_.fill_ties);
    decoder_->set_stripe_average(cfg_.stripe);
    pattern_count_ = plan.size();
    round_started_ = true;
    has_round = true;
    return sdk::ok();
  }

  sdk::Error end_round() override {
    const ScopedMs timed(decode_ms_);
    result_ = decoder_->finish(cfg_.min_contrast, cfg_.min_bit_margin, cfg_.noise_k);
    decoder_.reset();  // releases the accumulators
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    if (rig_.can_triangulate(0))
      depth_ = sdk::triangulate_columns(cam.calibration, rig_.projector, cam.width, cam.height,
                                        result_.cols.coord.data(), result_.intensity.data(),
                                        rig_.threads,
                                        // rows decoded: a distorted projector's columns are corrected
                                        result_.rows.coord.empty() ? nullptr : result_.rows.coord.data());
    return sdk::ok();
  }

  // Called once per decoded round (SDK contract): moves the maps out.
  sdk::Error outputs(sdk::Outputs& out) override {
    out.set_release(sdk::give_map, sdk::give_map);  // the next scan's decoder reuses the maps' pages
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    const uint32_t w = cam.width, h = cam.height;
    sdk::StandardOutputs standard;
    standard.decode_ms = decode_ms_;
    standard.pattern_count = pattern_count_;
    for (uint8_t v : result_.cols.valid) standard.valid_pixels += v != 0 ? 1u : 0u;
    standard.total_pixels = result_.cols.valid.size();
    std::vector<float> subpx(result_.cols.coord.size());
    sdk::parallel_rows(h, rig_.threads, [&](uint32_t y0, uint32_t y1) {
      refine_columns(result_.cols.coord.data(), w, y0, y1, SubpixelOptions{}, subpx.data());
    });
    out.add_image("proj_col_subpx", "px",
                  "sub-pixel refined column (line fit through stripe steps along the row, "
                  "subpixel.hpp); NaN: invalid",
                  w, h, std::move(subpx));
    out.add_image("proj_col_px", "px", "decoded projector column per camera pixel (NaN: invalid)",
                  w, h, std::move(result_.cols.coord));
    out.add_image("proj_col_uncertainty_px", "px",
                  "half-width of the column interval the uncertain finest planes allow "
                  "(proj_col_px is its centre); 0: every plane certain; NaN: invalid",
                  w, h, std::move(result_.cols.uncertainty));
    if (cfg_.rows)
      out.add_image("proj_row_px", "px", "decoded projector row per camera pixel (NaN: invalid)",
                    w, h, std::move(result_.rows.coord));
    out.add_image("valid", "", "255 where the column decoded validly, 0 where invalid", w, h,
                  std::move(result_.cols.valid));
    out.add_image("confidence", "",
                  "min over column bits of |L - L_inv| / (white - black), clipped to [0, 1]", w,
                  h, std::move(result_.cols.confidence));
    sdk::add_depth_outputs(out, depth_, w, h);
    standard.report = {
        {"method", "gray"},
        {"code", "binary-reflected Gray"},
        {"bits", cols_.bits},
        {"row_bits", rows_ ? rows_->bits : 0u},
        {"patterns", pattern_count_},
        {"binarize", cfg_.inverse ? "inverse" : "white"},
        {"model", kModel},
        {"why", kWhy},
        {"min_contrast", cfg_.min_contrast},
        {"min_bit_margin", cfg_.min_bit_margin},
        {"max_weak_error_px", cfg_.max_weak_error_px},
        {"error_bound_px", plane_error_bounds(cols_)},
        {"noise_k", cfg_.noise_k},
        {"max_uncertainty_px", cfg_.max_uncertainty_px},
        {"tie_intervals", cfg_.tie_intervals},
        {"fill_passes", cfg_.fill_passes},
        {"filled_pixels", result_.cols_filled},
        {"row_filled_pixels", result_.rows_filled},
        {"noise", {{"measured", result_.noise.measured},
                   {"model", "sigma_d^2 = a + b * (white + black), input units"},
                   {"a", result_.noise.a},
                   {"b", result_.noise.b},
                   {"pairs", result_.noise.pairs},
                   {"sample_pixels", result_.noise.pixels}}},
        {"stripe_average",
         {{"mode", cfg_.stripe.mode == StripeAverageMode::off         ? "off"
                   : cfg_.stripe.mode == StripeAverageMode::on        ? "on"
                                                                      : "auto"},
          {"gate", cfg_.stripe.gate},
          {"available", result_.stripe.available},
          {"f_noise", result_.stripe.f_noise},
          {"fired", result_.stripe.fired},
          {"pixels_added", result_.stripe.added},
          {"planes_decided", result_.stripe.planes_decided},
          {"averaged_noise", {{"measured", result_.stripe.averaged.measured},
                              {"a", result_.stripe.averaged.a},
                              {"b", result_.stripe.averaged.b}}},
          {"summary", stripe_summary(result_.stripe, cfg_.stripe)}}},
        {"uncertain_pixels", result_.cols_weak},
        {"weak_plane_pixels", result_.cols_weak},
        {"row_weak_plane_pixels", result_.rows_weak},
        {"input_full_scale", result_.full_scale},
        {"triangulated", depth_.has_value()},
        {"camera_index", 0},
    };
    if (!depth_) standard.report["note"] = "rig has no calibration for projector and camera 0: no depth";
    sdk::add_standard_outputs(out, standard);
    return sdk::ok();
  }

 private:

  GrayConfig cfg_;
  sdk::Rig rig_;
  StripeCode cols_;
  std::optional<StripeCode> rows_;
  RoundResult result_;
  std::optional<sdk::DepthResult> depth_;
  bool round_started_ = false;
  uint32_t pattern_count_ = 0;
};

}  // namespace

const std::vector<sdk::ParamSpec>& gray_param_specs() {
  static const std::vector<sdk::ParamSpec> specs = {
      {"rows", sdk::ParamType::boolean, false, -kInf, kInf, {},
       "also project row Gray codes (ceil(log2 H) planes more) and output proj_row_px"},
      {"binarize", sdk::ParamType::string, "inverse", -kInf, kInf, {"inverse", "white"},
       "\"inverse\": project every plane and its inverse, bit = L > L_inv (robust, 2 frames per "
       "bit); \"white\": no inverse frames, L_inv = white + black - L (thesis §3.2 footnote 2 "
       "generalised to a projector black level; half the frames, assumes linear response)"},
      {"min_contrast", sdk::ParamType::number, 0.03, 0.0, 1.0, {},
       "pixels with white - black below this fraction of full scale are shadow/invalid; 0.03 "
       "(7.7 DN at 8 bit) is about 3 sigma of the white-black difference noise of a typical "
       "sensor (sigma ~ 2 DN), so noise alone never passes as a lit pixel"},
      {"min_bit_margin", sdk::ParamType::number, 0.1, 0.0, 1.0, {},
       "a pixel is invalid when any bit's |L - L_inv| is below this fraction of its "
       "white - black: under direct light the margin equals the contrast (Eq. 3.3-3.5, "
       "alpha = 1), so 0.1 rejects only pixels within ~5% of a stripe edge or dominated by "
       "global light/defocus, while keeping a 3.5-sigma margin over sensor noise at 100 DN "
       "contrast"},
      {"max_weak_error_px", sdk::ParamType::integer, 1, 0.0, 1024.0, {}, kMaxWeakErrorHelp},
      {"noise_k", sdk::ParamType::number, 3.0, 0.0, 100.0, {},
       "a bit is also rejected when |L - L_inv| <= noise_k * sigma_d, sigma_d^2 = a + b * "
       "(white + black) fitted to this capture's pattern/inverse pairs (their sum is the same "
       "for every pattern, so its spread is noise); 3 lets a pure-noise bit through 0.27% of "
       "the time (Gaussian). 0 = off; binarize=white has no pairs to measure and skips it"},
      {"max_uncertainty_px", sdk::ParamType::number, 1.5, 0.0, 512.0, {},
       "a pixel with uncertain planes (margin within the thresholds above; at most 3 strict "
       "ones, plus the tolerated finest) gets the interval of every column its uncertain bits "
       "allow when that interval's half-width is at most this (proj_col_px = its centre, "
       "proj_col_uncertainty_px = the half-width, lower confidence), and is invalid otherwise. "
       "1.5 covers a stripe edge blurred together with the finest plane (4 columns); 0 keeps "
       "exact pixels only"},
      {"tie_intervals", sdk::ParamType::boolean, false, -kInf, kInf, {},
       "also give an interval where an uncertain plane ties exactly (|L - L_inv| = 0, common "
       "for a blurred fine plane at 8 bit) and the white is not clipped; otherwise such a "
       "pixel is invalid. On the real chessboard sample it keeps 1.5-2.7 points more of the "
       "plain decode's pixels; on the sim it raises the metal lamp's gross errors from 3.37 "
       "to 3.55 % (docs/report/real.md), hence off by default"},
      {"fill_passes", sdk::ParamType::integer, 0, 0.0, 64.0, {},
       "neighbour-consistent candidate selection for pixels still rejected: where the "
       "decoded 4-neighbours agree (within +-2 columns of their median), the pixel's own "
       "candidate columns (every word its uncertain planes allow) within +-1.5 of that median "
       "are kept when they are adjacent columns, as an interval of half-width <= 1 (reported "
       ">= 0.5) with half the confidence; repeated this many passes, so a run of rejected "
       "pixels fills inward up to this many pixels from each edge. The neighbours only choose "
       "among the pixel's own candidates, so a depth edge is not bridged. On the real "
       "chessboard sample 4 keeps 90.0-97.2 % of the plain decode's pixels (85.4-95.1 % "
       "without); on the sim it raises gross errors (metal lamp 3.37 -> 7.65 %, "
       "docs/report/real.md), hence 0 (off) by default: set 4 for real 8-bit captures"},
      {"fill_min_neighbours", sdk::ParamType::integer, 1, 1.0, 4.0, {},
       "decoded 4-neighbours a pixel needs before the neighbour fill may choose its column"},
      {"fill_extrapolate", sdk::ParamType::boolean, true, -kInf, kInf, {},
       "continue each neighbour's column through the pixel by the pixel behind it (no lag on "
       "slopes) instead of taking it as is"},
      {"fill_ties", sdk::ParamType::boolean, true, -kInf, kInf, {},
       "the neighbour fill also enumerates exactly tied planes (white unclipped)"},
      {"stripe_average", sdk::ParamType::string, "auto", -kInf, kInf, {"auto", "off", "on"},
       "uncertain planes of a rejected pixel decided by their margin averaged over 7 pixels "
       "along the stripe (direction from the structure tensor of the 8..128-column planes; "
       "decided where the average exceeds noise_k times its own fitted noise), then the "
       "normal interval rule. \"auto\": only when the finest planes are noise-bound on at "
       "least stripe_average_gate of the lit pixels (finest plane uncertain and noise_k * "
       "sigma_d >= min_bit_margin * contrast): real 8-bit captures 22-32 %, every sim scene "
       "<= 1.7 %, where the uncertain planes are mixed light paths that averaging would make "
       "wrongly certain (docs/structured-light.md). binarize=inverse only (it needs the "
       "pairs' noise); keeps the column pairs until the scan ends (26 MB at 1280x1024, 8 bit)"},
      {"stripe_average_gate", sdk::ParamType::number, 0.10, 0.0, 1.0, {},
       "share of lit pixels whose finest plane is uncertain with a noise-set threshold at "
       "which stripe_average=auto runs (reported as stripe_average.f_noise)"},
  };
  return specs;
}

sdk::MethodDescription describe_gray() {
  sdk::MethodDescription d;
  d.name = "gray";
  d.summary =
      "Conventional binary-reflected Gray code (thesis §3.2): white, black, then ceil(log2 W) "
      "column bit planes from the most significant, each with its inverse; optional row "
      "codes. Direct-illumination model: no global-light handling.";
  d.patterns = std::nullopt;  // depends on the projector width
  d.patterns_formula = "2 + 2*bits (binarize=inverse) or 2 + bits (binarize=white), bits = "
                       "ceil(log2 projector width); rows add 2*row_bits or row_bits";
  d.rounds = 1;
  d.outputs = {"proj_col_px", "proj_col_subpx", "proj_col_uncertainty_px", "proj_row_px", "valid", "confidence", "depth_mm", "points",
               "valid_fraction", "decode_ms", "pattern_count", "report"};
  d.params = gray_param_specs();
  return d;
}

sdk::Error create_gray_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Params params;
  if (sdk::Error e = sdk::parse_params(args.params, gray_param_specs(), params, args.method);
      !e.ok())
    return e;
  if (args.rig.is_null()) return sdk::invalid_argument("gray needs a rig description (rig_json)");
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  GrayConfig cfg;
  cfg.rows = params.get_bool("rows");
  cfg.inverse = params.get_string("binarize") == "inverse";
  cfg.min_contrast = params.get_number("min_contrast");
  cfg.min_bit_margin = params.get_number("min_bit_margin");
  cfg.max_weak_error_px = static_cast<uint32_t>(params.get_int("max_weak_error_px"));
  cfg.noise_k = params.get_number("noise_k");
  cfg.max_uncertainty_px = params.get_number("max_uncertainty_px");
  cfg.tie_intervals = params.get_bool("tie_intervals");
  cfg.fill_passes = static_cast<uint32_t>(params.get_int("fill_passes"));
  cfg.fill_min_neighbours = static_cast<uint32_t>(params.get_int("fill_min_neighbours"));
  cfg.fill_extrapolate = params.get_bool("fill_extrapolate");
  cfg.fill_ties = params.get_bool("fill_ties");
  const std::string stripe = params.get_string("stripe_average");
  cfg.stripe.mode = stripe == "off" ? StripeAverageMode::off
                    : stripe == "on" ? StripeAverageMode::on
                                     : StripeAverageMode::automatic;
  cfg.stripe.gate = params.get_number("stripe_average_gate");
  out = std::make_unique<GraySession>(cfg, std::move(rig));
  return sdk::ok();
}

}  // namespace procam::sl
