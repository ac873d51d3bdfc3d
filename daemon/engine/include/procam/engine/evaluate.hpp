// SPDX-License-Identifier: MIT
// Accuracy of a plugin's outputs against a rig's ground truth, by evaluators
// chosen from what the plugin outputs. The service (manifest "evaluation") and
// `procam bench` call evaluate_outputs(); nothing else looks outputs up by name
// to evaluate them.
//
// Threads: reentrant (pure functions of their arguments; the registry is
// immutable). Errors: never throws for bad data — an evaluator that cannot
// compare (size mismatch, no truth) reports {"error": "..."} in its section.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/image.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

namespace procam::engine {

// Compares a decoded projector-column map (F32, NaN = not decoded) and an
// optional depth map with the truth. Reported (all over the truth's lit pixels
// unless stated):
//   lit_pixels, decoded_fraction (decoded / lit),
//   within_1col_fraction (decoded and |col - truth| <= 1, over lit): the
//     headline accuracy; a decoded integer column is the projector pixel
//     whose centre is nearest, so |err| <= 0.5 when exact, 1 allows one
//     neighbouring column,
//   gross_error_fraction (|err| > 1, over decoded lit pixels),
//   col_rms_px (over decoded, non-gross), spurious_fraction (decoded pixels
//   the truth says are not lit, over all decoded),
//   depth_rms_mm / depth_median_abs_mm / depth_p99_abs_mm (over decoded
//   non-gross pixels with finite depth).
nlohmann::json evaluate_correspondence(const Image& proj_col, const Image* depth_mm,
                                       const hw::GroundTruth& truth);

// Depth map (F32 mm, NaN = none) against truth.depth_mm over the truth's lit
// pixels, whatever the columns: pixels (finite estimate and truth),
// decoded_fraction (over lit), rms_mm, median_abs_mm, p99_abs_mm, bias_mm
// (mean signed error).
nlohmann::json evaluate_depth(const Image& depth_mm, const hw::GroundTruth& truth);

// A radiance component map (F32 DN, NaN = none) against its truth map (same
// units, see hw::GroundTruth::direct): over lit pixels with a finite estimate,
// median_abs_error_dn; over those whose truth is >= kMinTruthDn,
// median_rel_error (|est - truth| / truth) and rel_pixels. A component the
// scene does not have (truth < kMinTruthDn everywhere, e.g. global light on
// a plane) has rel_pixels 0 and median_rel_error null.
inline constexpr double kMinTruthDn = 1.0;
nlohmann::json evaluate_component(const Image& estimate_dn, const Image& truth_dn, const hw::GroundTruth& truth);

// One evaluator of the registry: selected when the plugin's outputs contain
// what it needs (applies), it returns its section of the result.
struct Evaluator {
  const char* name;  // section name; "correspondence" is merged into the top level (see below)
  const char* what;  // the outputs it reads, for humans
  bool (*applies)(const std::vector<host::Output>& outputs);
  nlohmann::json (*evaluate)(const std::vector<host::Output>& outputs, const hw::GroundTruth& truth);
};

// The registry, in evaluation order:
//   correspondence  proj_col_px (+ depth_mm, proj_col_px_<code>, proj_col_subpx)
//   depth           depth_mm
//   components      direct_dn and/or global_dn vs truth.direct / truth.global
//   medium          scalars medium_<param> vs truth.medium["<param>"]
// An evaluator whose truth does not exist returns {"error": "no truth for ..."}
// rather than a number.
const std::vector<Evaluator>& evaluators();

// Runs every evaluator that applies. Result: the correspondence metrics at the
// top level (lit_pixels, within_1col_fraction, ... as evaluate_correspondence,
// plus "codes": {<code>: metrics} for proj_col_px_<code> maps and "subpx" for
// proj_col_subpx — the manifest format clients read), one object per other
// evaluator under its name, and "evaluators": the names that ran (empty when
// none applies, e.g. the null plugin's mean_dn).
nlohmann::json evaluate_outputs(const std::vector<host::Output>& outputs, const hw::GroundTruth& truth);

}  // namespace procam::engine
