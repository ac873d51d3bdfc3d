// SPDX-License-Identifier: MIT
// Phase shifting and modulated phase shifting (thesis §3.3.3 baselines; see
// phase_session.hpp).
//
// Patterns (projector column x, frequency f with period P_f, shift k of N = 6):
//   I_fk(x) = 0.5 + 0.5 cos(2 pi x / P_f - 2 pi k / N),  P = {W, W/8, W/64}.
// Phase (N-step least squares): with samples L_k = A + B cos(theta - 2 pi k/N),
//   C = sum L_k cos(2 pi k/N) = (N/2) B cos theta, S = sum L_k sin(2 pi k/N) =
//   (N/2) B sin theta, so theta = atan2(S, C) and B = 2 sqrt(C^2 + S^2) / N.
//   Six steps reject the 2nd-4th harmonics of a non-linear (gamma) projector.
// Temporal unwrapping: x_0 = P_0 theta_0 / 2 pi (P_0 = W: unambiguous); then
//   m = round(x_{f-1} / P_f - theta_f / 2 pi), x_f = P_f (m + theta_f / 2 pi).
//   The residual |x_{f-1}/P_f - theta_f/2pi - m| must stay below
//   unwrap_tolerance (0.25 of a period: a phase error of pi/2), else invalid.
// Validity: B >= min_modulation * full scale at every frequency; no sample
//   saturated (>= full scale) or non-finite; unwrap residuals in tolerance.
// confidence = 1 - 2 * max unwrap residual (in [0, 1]).
// Modulated (Chen et al. 2008): mask m = (a, b) in 3 x 3 lights projector
//   pixel (x, y) iff x = a (mod 3) and y = b (mod 3). Over the 9 masks each
//   pixel is lit once, and global light sees 1/9 of the pattern in each, so
//   max - min over the 9 images = the direct part of I_fk (Nayar et al. 2006).
#include "phase_session.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include "procam/sdk/triangulate.hpp"

namespace procam::sl {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr uint32_t kShifts = 6, kFreqs = 3, kMasks = 9;

struct PhaseConfig {
  bool modulated = false;
  double min_modulation = 0.02;
  double unwrap_tolerance = 0.25;
};

class PhaseSession final : public sdk::Session {
 public:
  PhaseSession(PhaseConfig cfg, sdk::Rig rig) : cfg_(cfg), rig_(std::move(rig)) {
    rig_.threads = std::clamp(rig_.threads, 1u, 64u);
    const double w = rig_.projector_width;
    periods_ = {w, w / 8.0, w / 64.0};
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    n_ = size_t{cam.width} * cam.height;
  }

  sdk::Error next_plan(sdk::Plan& plan, bool& has_round) override {
    has_round = false;
    if (started_) return sdk::ok();
    const uint32_t pw = rig_.projector_width, ph = rig_.projector_height;
    std::vector<uint8_t> line(pw);
    for (uint32_t f = 0; f < kFreqs; ++f)
      for (uint32_t k = 0; k < kShifts; ++k) {
        for (uint32_t x = 0; x < pw; ++x) {
          const double v = 0.5 + 0.5 * std::cos(2.0 * std::numbers::pi * (x / periods_[f] - double(k) / kShifts));
          line[x] = static_cast<uint8_t>(std::lround(255.0 * v));
        }
        const uint32_t masks = cfg_.modulated ? kMasks : 1;
        for (uint32_t m = 0; m < masks; ++m) {
          std::string label = "f" + std::to_string(f) + " shift " + std::to_string(k);
          if (cfg_.modulated) label += " mod " + std::to_string(m);
          const uint32_t i = plan.add_frame(label, pw, ph, PROCAM_PIXEL_U8);
          std::span<uint8_t> px = plan.pattern_u8(i);
          for (uint32_t y = 0; y < ph; ++y)
            for (uint32_t x = 0; x < pw; ++x)
              px[size_t{y} * pw + x] = !cfg_.modulated || (x % 3 == m % 3 && y % 3 == m / 3) ? line[x] : 0;
        }
      }
    plan.set_note(std::string(cfg_.modulated ? "modulated-phase-shift" : "phase-shift") + ": " +
                  std::to_string(plan.size()) + " frames — 3 frequencies x 6 shifts" +
                  (cfg_.modulated ? " x 9 modulation masks" : ""));
    patterns_ = plan.size();
    C_.assign(kFreqs, std::vector<float>(n_, 0.0f));
    S_.assign(kFreqs, std::vector<float>(n_, 0.0f));
    bad_.assign(n_, 0);
    added_.assign(patterns_, 0);
    if (cfg_.modulated) {
      group_max_.assign(kFreqs * kShifts, {});
      group_min_.assign(kFreqs * kShifts, {});
      group_count_.assign(kFreqs * kShifts, 0);
    }
    started_ = true;
    has_round = true;
    return sdk::ok();
  }

  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    const auto t0 = std::chrono::steady_clock::now();
    if (index >= patterns_) return sdk::invalid_argument("frame index " + std::to_string(index) + " out of range");
    const std::string what = "frame " + std::to_string(index);
    if (added_[index]) return sdk::state_error(what + " was already added");
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    if (sdk::Error e = sdk::check_frame(&frame, cam.width, cam.height, 1, what); !e.ok()) return e;
    if (full_scale_ == 0) full_scale_ = static_cast<float>(sdk::full_scale(frame));
    added_[index] = 1;
    const uint32_t masks = cfg_.modulated ? kMasks : 1;
    const uint32_t group = index / masks, f = group / kShifts, k = group % kShifts;
    const float c = static_cast<float>(std::cos(2.0 * std::numbers::pi * k / kShifts));
    const float s = static_cast<float>(std::sin(2.0 * std::numbers::pi * k / kShifts));
    const uint32_t w = cam.width;
    if (!cfg_.modulated) {
      sdk::parallel_rows(cam.height, rig_.threads, [&](uint32_t y0, uint32_t y1) {
        std::vector<float> row(w);
        for (uint32_t y = y0; y < y1; ++y) {
          sdk::read_row(frame, y, row.data());
          const size_t off = size_t{y} * w;
          accumulate(row.data(), off, w, f, c, s);
        }
      });
    } else {  // Nayar separation: running max / min over the group's 9 masks
      auto& mx = group_max_[group];
      auto& mn = group_min_[group];
      if (mx.empty()) {
        mx.assign(n_, -std::numeric_limits<float>::infinity());
        mn.assign(n_, std::numeric_limits<float>::infinity());
      }
      sdk::parallel_rows(cam.height, rig_.threads, [&](uint32_t y0, uint32_t y1) {
        std::vector<float> row(w);
        for (uint32_t y = y0; y < y1; ++y) {
          sdk::read_row(frame, y, row.data());
          const size_t off = size_t{y} * w;
          for (uint32_t x = 0; x < w; ++x) {
            const float v = row[x];
            if (!std::isfinite(v) || v >= full_scale_) bad_[off + x] = 1;
            mx[off + x] = std::max(mx[off + x], v);
            mn[off + x] = std::min(mn[off + x], v);
          }
        }
      });
      if (++group_count_[group] == kMasks) {
        sdk::parallel_rows(cam.height, rig_.threads, [&](uint32_t y0, uint32_t y1) {
          std::vector<float> d(w);
          for (uint32_t y = y0; y < y1; ++y) {
            const size_t off = size_t{y} * w;
            for (uint32_t x = 0; x < w; ++x) d[x] = mx[off + x] - mn[off + x];
            accumulate(d.data(), off, w, f, c, s, /*check=*/false);
          }
        });
        std::vector<float>().swap(mx);
        std::vector<float>().swap(mn);
      }
    }
    decode_ms_ += ms_since(t0);
    return sdk::ok();
  }

  sdk::Error end_round() override {
    const auto t0 = std::chrono::steady_clock::now();
    for (uint8_t a : added_)
      if (!a) return sdk::state_error("end_round before all frames were added");
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    coord_.assign(n_, std::numeric_limits<float>::quiet_NaN());
    valid_.assign(n_, 0);
    conf_.assign(n_, 0.0f);
    const double min_b = cfg_.min_modulation * static_cast<double>(full_scale_);
    const double two_pi = 2.0 * std::numbers::pi;
    sdk::parallel_rows(cam.height, rig_.threads, [&](uint32_t y0, uint32_t y1) {
      for (size_t i = size_t{y0} * cam.width; i < size_t{y1} * cam.width; ++i) {
        if (bad_[i]) continue;
        double x = 0, worst = 0;
        bool ok = true;
        for (uint32_t f = 0; f < kFreqs && ok; ++f) {
          const double C = C_[f][i], S = S_[f][i];
          const double B = 2.0 * std::sqrt(C * C + S * S) / kShifts;
          if (!(B >= min_b) || !std::isfinite(B)) {
            ok = false;
            break;
          }
          double t = std::atan2(S, C) / two_pi;  // in (-0.5, 0.5]
          if (t < 0) t += 1.0;                   // fraction of a period, [0, 1)
          if (f == 0) {
            x = t * periods_[0];
          } else {
            const double q = x / periods_[f] - t;
            const double m = std::round(q);
            worst = std::max(worst, std::fabs(q - m));
            if (std::fabs(q - m) > cfg_.unwrap_tolerance) ok = false;
            x = periods_[f] * (m + t);
          }
        }
        if (!ok) continue;
        const double W = rig_.projector_width;
        if (x > W - 0.5) x -= W;  // phase wraps at the single period
        if (x < -0.5 || x > W - 0.5) continue;
        coord_[i] = static_cast<float>(x);
        valid_[i] = 255;
        conf_[i] = static_cast<float>(std::clamp(1.0 - 2.0 * worst, 0.0, 1.0));
      }
    });
    C_.clear();
    S_.clear();
    decode_ms_ += ms_since(t0);
    return sdk::ok();
  }

  sdk::Error outputs(sdk::Outputs& out) override {
    const auto t0 = std::chrono::steady_clock::now();
    const sdk::RigCamera& cam = rig_.cameras.at(0);
    const uint32_t w = cam.width, h = cam.height;
    std::optional<sdk::DepthResult> depth;
    if (rig_.can_triangulate(0))
      depth = sdk::triangulate_columns(cam.calibration, rig_.projector, w, h, coord_.data(), nullptr, rig_.threads);
    decode_ms_ += ms_since(t0);
    size_t valid = 0;
    for (uint8_t v : valid_) valid += v != 0 ? 1u : 0u;
    const std::string method = cfg_.modulated ? "modulated-phase-shift" : "phase-shift";
    out.add_image("proj_col_px", "px", "unwrapped projector column (continuous, NaN: invalid)", w, h, std::move(coord_));
    out.add_image("valid", "", "255 where the column decoded validly, 0 where invalid", w, h, std::move(valid_));
    out.add_image("confidence", "", "1 - 2 * largest unwrapping residual (periods), in [0, 1]", w, h, std::move(conf_));
    if (depth) {
      out.add_image("depth_mm", "mm", "z of the triangulated point, camera frame (NaN: none)", w, h, std::move(depth->depth_mm));
      out.add_points("points", "triangulated points, camera frame", "x,y,z,intensity", 4, std::move(depth->points));
    }
    sdk::StandardOutputs standard;
    standard.decode_ms = decode_ms_;
    standard.pattern_count = patterns_;
    standard.valid_pixels = valid;
    standard.total_pixels = n_;
    standard.report = {
        {"method", method},
        {"code", cfg_.modulated ? "sinusoidal phase shifting, each pattern modulated by 9 high-frequency dot masks (Chen et al. 2008)"
                                : "sinusoidal phase shifting with temporal unwrapping"},
        {"periods_px", periods_},
        {"shifts", kShifts},
        {"patterns", patterns_},
        {"model", cfg_.modulated ? "global light removed per pattern by direct/global separation (fails where the direct part is weak: translucent, defocused)"
                                 : "direct illumination only: global light biases the phase"},
        {"why", cfg_.modulated ? "Baseline of thesis §3.3.3: separation-based modulated phase shifting needs 9x the images (162) and a measurable direct component."
                               : "Baseline of thesis §3.3.3: 18 images, sub-pixel columns, but long-range global light shifts the low-frequency phases."},
        {"min_modulation", cfg_.min_modulation},
        {"unwrap_tolerance", cfg_.unwrap_tolerance},
        {"triangulated", depth.has_value()},
        {"camera_index", 0},
    };
    sdk::add_standard_outputs(out, standard);
    return sdk::ok();
  }

 private:
  static double ms_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  }
  void accumulate(const float* v, size_t off, uint32_t w, uint32_t f, float c, float s, bool check = true) {
    float* C = C_[f].data() + off;
    float* S = S_[f].data() + off;
    for (uint32_t x = 0; x < w; ++x) {
      if (check && (!std::isfinite(v[x]) || v[x] >= full_scale_)) bad_[off + x] = 1;
      C[x] += v[x] * c;
      S[x] += v[x] * s;
    }
  }

  PhaseConfig cfg_;
  sdk::Rig rig_;
  std::vector<double> periods_;
  size_t n_ = 0;
  bool started_ = false;
  uint32_t patterns_ = 0;
  float full_scale_ = 0;
  std::vector<std::vector<float>> C_, S_, group_max_, group_min_;
  std::vector<uint32_t> group_count_;
  std::vector<uint8_t> bad_, added_, valid_;
  std::vector<float> coord_, conf_;
  double decode_ms_ = 0;
};

std::vector<sdk::ParamSpec> phase_specs() {
  return {
      {"min_modulation", sdk::ParamType::number, 0.02, 0.0, 1.0, {},
       "pixels whose sinusoid amplitude B is below this fraction of full scale at any frequency are invalid "
       "(5 DN at 8 bit: the phase of a weaker sinusoid is dominated by noise)"},
      {"unwrap_tolerance", sdk::ParamType::number, 0.25, 0.0, 0.5, {},
       "largest accepted unwrapping residual, in periods of the finer frequency (0.25 = a phase error of pi/2)"},
  };
}

}  // namespace

sdk::MethodDescription describe_phase_method(const std::string& method) {
  const bool mod = method == "modulated-phase-shift";
  sdk::MethodDescription d;
  d.name = method;
  d.summary = mod ? "Modulated phase shifting (Chen et al. 2008; thesis §3.3.3 baseline): 18 phase-shift "
                    "patterns each modulated by 9 high-frequency masks, direct component by max - min."
                  : "Phase shifting (thesis §3.3.3 baseline): 3 frequencies (periods W, W/8, W/64) x 6 "
                    "shifts, temporal unwrapping; continuous columns.";
  d.patterns = mod ? 162u : 18u;  // 3 frequencies x 6 shifts (x 9 masks), any projector size
  d.rounds = 1;
  d.outputs = {"proj_col_px", "valid", "confidence", "depth_mm", "points", "valid_fraction", "decode_ms",
               "pattern_count", "report"};
  d.params = phase_specs();
  return d;
}

sdk::Error create_phase_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out) {
  static const std::vector<sdk::ParamSpec> specs = phase_specs();
  sdk::Params params;
  if (sdk::Error e = sdk::parse_params(args.params, specs, params, args.method); !e.ok()) return e;
  if (args.rig.is_null()) return sdk::invalid_argument(args.method + " needs a rig description (rig_json)");
  sdk::Rig rig;
  if (sdk::Error e = sdk::parse_rig(args.rig, rig); !e.ok()) return e;
  if (rig.projector_width < 64) return sdk::invalid_argument(args.method + " needs a projector at least 64 columns wide");
  PhaseConfig cfg;
  cfg.modulated = args.method == "modulated-phase-shift";
  cfg.min_modulation = params.get_number("min_modulation");
  cfg.unwrap_tolerance = params.get_number("unwrap_tolerance");
  out = std::make_unique<PhaseSession>(cfg, std::move(rig));
  return sdk::ok();
}

}  // namespace procam::sl
