// SPDX-License-Identifier: MIT
// The defocus plugin's parameters, method descriptions and capture plan.
//
// Plan (every method): for focus setting k = 0..F-1 (in order), 24 frames of
// period-24 vertical stripes shifted by t = 0..23 projector pixels, frame
// index 24 k + t, label "focus <k> shift <t>", projector_focus_mm = focus_mm[k].
// The stripes are pre-filtered (thesis §2.4 footnote 5) with a Gaussian of
// prefilter_sigma_px (sdk::smoothed_stripes). Units: mm, projector pixels.
// Threads: reentrant. Errors: sdk::Error INVALID_ARGUMENT naming the parameter.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "focus_measures.hpp"
#include "procam/plugin_sdk.hpp"

namespace procam::defocus {

struct SweepConfig {
  std::vector<double> focus_mm;     // the focus settings, in plan order
  double prefilter_sigma_px = 1.0;  // anti-aliasing pre-filter of the stripes
  double black_fraction = 0.02;     // mean below this fraction of full scale: black
  Validity validity;                // min_modulation (black_dn set from black_fraction)
  size_t table_bins = 0;            // calibrate-* methods: samples of the table they make
};

// Pixel pair for Eq. 2.8: B receives global light, A (same depth) does not.
struct PixelPair {
  uint32_t xb = 0, yb = 0, xa = 0, ya = 0;
};

std::vector<sdk::MethodDescription> method_descriptions();

// Validates params of `method` against its specs and the camera size (pairs
// must lie inside it) and fills the sweep.
sdk::Error parse_sweep_config(const std::string& method, const nlohmann::json& params, const sdk::Rig& rig,
                              SweepConfig& config, std::vector<PixelPair>& pairs);

void add_sweep_frames(sdk::Plan& plan, uint32_t proj_width, uint32_t proj_height, const SweepConfig& config);

// Per pair: G(f) = E_B(f)/E_A(f) (Eq. 2.8, up to the scale alpha_A), E_B(f),
// E_A(f), and relative variations (max - min) / max of G and of E_B over f.
nlohmann::json invariance_summary(const E3Accumulator& acc, const std::vector<PixelPair>& pairs);

// (max - min) / max of positive values; NaN when empty or max <= 0.
double relative_variation(const std::vector<double>& v);

}  // namespace procam::defocus
