// SPDX-License-Identifier: MIT
// The polarized-striping plugin's sessions (see polarized_striping_session.hpp).
#include "polarized_striping_session.hpp"

#include <cmath>
#include <optional>

#include "estimate.hpp"
#include "procam/sdk/triangulate.hpp"
#include "params.hpp"
#include "stripe_stack.hpp"

namespace procam::polarized_striping {
namespace {

// What a planned frame is: a flood frame, or stripe k; seen through the best
// (crossed) or worst (parallel) analyser, or none.
enum class Analyser : uint8_t { none, best, worst };
struct Role {
  Analyser analyser = Analyser::none;
  uint16_t stripe = 0;
};

double wrap_deg(double a) { return std::fmod(std::fmod(a, 180.0) + 180.0, 180.0); }

class PolarizedStripingSession final : public sdk::Session {
 public:
  PolarizedStripingSession(Config cfg, const sdk::Rig& rig) : cfg_(std::move(cfg)), rig_(rig) {}

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    if (planned_) return sdk::ok();
    const uint32_t pw = rig_.projector_width, ph = rig_.projector_height;
    const auto add = [&](const std::string& label, Role role, std::optional<StripeColumns> cols) {
      const uint32_t i = plan.add_frame(label, pw, ph);
      if (cols)
        sdk::fill_pattern(plan, i, [c = *cols](uint32_t x, uint32_t) {
          return x >= c.first && x < c.first + c.width ? 1.0 : 0.0;
        });
      else
        sdk::fill_pattern(plan, i, [](uint32_t, uint32_t) { return 1.0; });
      procam_frame_settings& s = plan.settings(i);
      if (cfg_.exposure_us > 0) s.exposure_us = cfg_.exposure_us;
      if (role.analyser != Analyser::none) {
        // Backscatter keeps the source's polarisation, the surface depolarises:
        // crossed analyser = best image E_b (Eq. 5.4), parallel = worst E_w (Eq. 5.5).
        s.projector_polarizer_deg = wrap_deg(cfg_.polarizer_deg);
        s.polarizer_deg = wrap_deg(cfg_.polarizer_deg + (role.analyser == Analyser::best ? 90.0 : 0.0));
      }
      roles_.push_back(role);
    };
    switch (cfg_.method) {
      case Method::flood: add("white", {}, std::nullopt); break;
      case Method::polarized_flood:
        add("white best (analyser crossed)", {Analyser::best, 0}, std::nullopt);
        add("white worst (analyser parallel)", {Analyser::worst, 0}, std::nullopt);
        break;
      case Method::striping:
      case Method::polarized_striping:
        for (uint32_t k = 0; k < cfg_.stripes; ++k) {
          const StripeColumns c = stripe_columns(pw, cfg_.stripes, cfg_.stripe_px, k);
          const auto kk = static_cast<uint16_t>(k);
          if (cfg_.method == Method::striping) {
            add("stripe " + std::to_string(k), {Analyser::none, kk}, c);
          } else {
            add("stripe " + std::to_string(k) + " best", {Analyser::best, kk}, c);
            add("stripe " + std::to_string(k) + " worst", {Analyser::worst, kk}, c);
          }
        }
        break;
    }
    plan.set_note(cfg_.method_name + ": " + std::to_string(plan.size()) + " frames (see report)");
    pattern_count_ = plan.size();
    planned_ = has_round = true;
    return sdk::ok();
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    const sdk::ScopedMs timer(decode_ms_);
    const auto& cam = rig_.cameras[0];
    if (sdk::Error e = sdk::check_frame(&frame, cam.width, cam.height, 1, "frame " + std::to_string(index)); !e.ok())
      return e;
    if (seen_type_ == 0) {
      seen_type_ = frame.pixel_type;
      full_scale_ = sdk::full_scale(frame);
    } else if (frame.pixel_type != seen_type_ || sdk::full_scale(frame) != full_scale_) {
      return sdk::bad_frame("frame " + std::to_string(index) + " is " + sdk::describe_image(frame) +
                            " but earlier frames of this scan differ: keep one camera mode for the whole scan");
    }
    const Role role = roles_.at(index);
    if (is_striping(cfg_.method)) {
      StripeStack& st = role.analyser == Analyser::worst ? worst_ : best_;
      if (st.width() == 0)  // U8 frames of <= 256 stripes: the 6-byte packed state; cfg_.stripes frames each
        st = StripeStack(cam.width, cam.height, frame.pixel_type == PROCAM_PIXEL_U8 && cfg_.stripes <= 256,
                         cfg_.stripes);
      st.add(frame, role.stripe, rig_.threads);
    } else {
      std::vector<float>& m = role.analyser == Analyser::worst ? worst_map_ : best_map_;
      sdk::take_map(m, size_t{cam.width} * cam.height);  // every element written below
      for (uint32_t y = 0; y < cam.height; ++y) sdk::read_row(frame, y, m.data() + size_t{y} * cam.width);
    }
    return sdk::ok();
  }

  sdk::Error end_round() override {
    const sdk::ScopedMs timer(decode_ms_);
    const auto& cam = rig_.cameras[0];
    levels_ = levels_for(cfg_, full_scale_);
    switch (cfg_.method) {
      case Method::flood: maps_ = estimate_flood(std::move(best_map_), cfg_, levels_, cam.width, cam.height); break;
      case Method::polarized_flood:
        maps_ = estimate_polarized_flood(std::move(best_map_), worst_map_, cfg_, levels_, cam.width, cam.height);
        break;
      case Method::striping:
        maps_ = estimate_striping(best_, nullptr, cfg_, levels_, rig_.projector_width, StripingPass::fastest,
                                  rig_.can_triangulate(0));
        break;
      case Method::polarized_striping:
        maps_ = estimate_striping(best_, &worst_, cfg_, levels_, rig_.projector_width, StripingPass::fastest,
                                  rig_.can_triangulate(0));
        break;
    }
    // The stacks (~28 MB at 1920x1200) are freed with the session, not here:
    // unmapping them would add to the latency after the last frame.
    if (!worst_map_.empty()) sdk::give_map(std::move(worst_map_));
    if (is_striping(cfg_.method) && rig_.can_triangulate(0)) {
      std::vector<float> intensity(maps_.col.size());
      for (size_t i = 0; i < intensity.size(); ++i) {
        const double v = maps_.image_u8.empty() ? double(maps_.image[i]) : double(maps_.image_u8[i]);
        intensity[i] = static_cast<float>(v / full_scale_);
      }
      depth_ = sdk::triangulate_columns(cam.calibration, rig_.projector, cam.width, cam.height, maps_.col.data(),
                                        intensity.data(), rig_.threads);
      if (!cfg_.all_maps) sdk::give_map(std::move(maps_.col));  // made for depth only
    }
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    const sdk::ScopedMs timer(decode_ms_);
    const uint32_t w = maps_.width, h = maps_.height;
    sdk::StandardOutputs std_out;
    std_out.pattern_count = pattern_count_;
    std_out.total_pixels = size_t{w} * h;
    std_out.valid_pixels = maps_.valid;
    std_out.report = report();
    // The maps move into the outputs and go back to the map cache at
    // session_destroy (the next scan of this size reuses their pages).
    out.set_release(sdk::give_map, sdk::give_map);
    // image_dn: U8 for an 8-bit striping scan (the composite is a frame value), else F32.
    if (!maps_.image_u8.empty())
      out.add_image("image_dn", "DN", image_description(), w, h, std::move(maps_.image_u8));
    else
      out.add_image("image_dn", "DN", image_description(), w, h, std::move(maps_.image));
    out.add_image("enhanced_dn", "DN", enhanced_description(), w, h, std::move(maps_.enhanced));
    out.add_image("backscatter_dn", "DN",
                  "backscatter estimate B^ in the unpolarised image's units (NaN: clipped or not separable)", w, h,
                  std::move(maps_.backscatter));
    // The quality maps only with param maps = "all" (their means are in the report).
    if (!maps_.cqm.empty())
      out.add_image("cqm", "", "contrast quality measure S / (S + B(1 - p)) per pixel (Eq. 5.8; NaN: invalid)", w, h,
                    std::move(maps_.cqm));
    if (!maps_.weight.empty())
      out.add_image("snr_weight", "", "SNR weight W = sigmoid((S - mu) / z) per pixel (Eq. 5.10; NaN: invalid)", w,
                    h, std::move(maps_.weight));
    if (is_polarized(cfg_.method))
      out.add_scalar("dop", "", "degree of polarization p of the backscatter used in Eq. 5.6 (0: not separated)",
                     maps_.p);
    if (is_striping(cfg_.method)) {
      out.add_image("stripe_index", "", "index k of the light sheet that lit the pixel (argmax_k SI_k; fractional "
                                        "between two adjacent sheets; NaN: no stripe)", w, h, std::move(maps_.stripe));
      if (cfg_.all_maps)
        out.add_image("stripe_col_px", "px", "projector column of the centre of that sheet (NaN: no stripe); "
                                             "sparse: only pixels a sheet lit", w, h, std::move(maps_.col));
      if (!maps_.gqm.empty())
        out.add_image("gqm", "", "gradient quality measure (D + B(1 - p)) / (D + A + B(1 - p)) per pixel (Eq. 5.9)",
                      w, h, std::move(maps_.gqm));
      sdk::add_depth_outputs(out, depth_, w, h);
    }
    std_out.decode_ms = decode_ms_;
    sdk::add_standard_outputs(out, std_out);
    return sdk::ok();
  }

 private:
  std::string image_description() const {
    switch (cfg_.method) {
      case Method::flood: return "the flood-lit image (DN)";
      case Method::polarized_flood: return "the best-polarised image E_b: analyser crossed (Eq. 5.4; DN)";
      case Method::striping: return "composite CI = max_k SI_k over the stripe images (Eq. 5.7; DN)";
      default: return "composite CI = max_k E_b,k over the best-analyser stripe images (Eq. 5.7, §5.2.1; DN)";
    }
  }
  std::string enhanced_description() const {
    switch (cfg_.method) {
      case Method::flood: return "signal S^ = E - B^, B^ uniform (DN; NaN: clipped)";
      case Method::polarized_flood: return "signal S^ by Eq. 5.6 from E_b and E_w (DN; NaN: clipped)";
      case Method::striping: return "stripe signal D^ = CI - background, backscatter removed (DN; NaN: no stripe)";
      default: return "signal S^ = D^ + A^ under polarised sheets, backscatter removed (DN; NaN: no stripe)";
    }
  }

  nlohmann::json report() const {
    nlohmann::json r = {{"method", cfg_.method_name},
                        {"params", cfg_.params.json()},
                        {"patterns", pattern_count_},
                        {"full_scale_dn", full_scale_},
                        {"noise_sigma_dn", levels_.sigma},
                        {"margin_dn", levels_.margin},
                        {"saturation_dn", levels_.saturation},
                        {"snr_weight", {{"mu_dn", levels_.mu}, {"z_dn", levels_.z}}},
                        {"valid_pixels", maps_.valid},
                        {"quality", maps_.quality}};
    if (is_polarized(cfg_.method)) r["dop"] = maps_.dop;
    if (!maps_.notes.empty()) r["notes"] = maps_.notes;
    if (is_striping(cfg_.method)) {
      r["stripes"] = cfg_.stripes;
      r["stripe_px"] = cfg_.stripe_px;
      r["depth"] = rig_.can_triangulate(0) ? "triangulated stripe_col_px (column planes)"
                                           : "rig not calibrated: no depth_mm";
    }
    switch (cfg_.method) {
      case Method::flood:
        r["model"] = "E = S + B; B uniform = backscatter_percentile quantile of E (darkest pixels see medium only)";
        break;
      case Method::polarized_flood:
        r["model"] = "E_b = S/2 + B(1-p)/2, E_w = S/2 + B(1+p)/2 (Eq. 5.4-5.5); S^ by Eq. 5.6, B^ = (E_w - E_b)/p";
        break;
      case Method::striping:
        r["model"] = "CI = max_k SI_k (Eq. 5.7); background = mean of the K-2 frames below the top two; D^ = CI - "
                     "background; A cannot be told from B without polarisation: counted in B^, GQM not estimable";
        break;
      case Method::polarized_striping:
        r["model"] = "best/worst analyser per sheet; D^ = 2 (CI_b - bg_b); B^ = (bg_w - bg_b)/p; A^ = bg_w + bg_b - "
                     "B^; S^ = D^ + A^; CQM (Eq. 5.8), GQM (Eq. 5.9) from these";
        break;
    }
    return r;
  }

  Config cfg_;
  sdk::Rig rig_;
  std::vector<Role> roles_;
  StripeStack best_, worst_;
  std::vector<float> best_map_, worst_map_;
  uint32_t seen_type_ = 0;
  double full_scale_ = 255;
  bool planned_ = false;
  uint64_t pattern_count_ = 0;
  double decode_ms_ = 0;
  Levels levels_;
  Maps maps_;
  std::optional<sdk::DepthResult> depth_;
};

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
      {"flood", Method::flood, "one white frame without polariser: the flood-lit baseline (thesis §5.2)", 1, "1"},
      {"polarized-flood", Method::polarized_flood,
       "polarised white light seen through a crossed (best) and a parallel (worst) analyser; signal by Eq. 5.6",
       2, "2"},
      {"striping", Method::striping,
       "K vertical light sheets; composite CI = max_k SI_k (Eq. 5.7), stripe map and depth from the sheets", 64,
       "stripes"},
      {"polarized-striping", Method::polarized_striping,
       "polarised light sheets, each seen through the crossed and the parallel analyser (thesis §5.2.1)", 128,
       "2 * stripes"},
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
    a.push_back(d.to_json());
  }
  return a;
}

sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  Config cfg;
  if (sdk::Error e = parse_config(args.method, args.params, rig.projector_width, cfg); !e.ok()) return e;
  cfg.threads = rig.threads;
  out = std::make_unique<PolarizedStripingSession>(std::move(cfg), rig);
  return sdk::ok();
}

}  // namespace procam::polarized_striping
