// SPDX-License-Identifier: MIT
// The outputs every decoder plugin reports, with one set of names, units and
// descriptions: decode_ms, pattern_count, valid_fraction (scalars) and the
// JSON `report`. Plugins fill a StandardOutputs and call add_standard_outputs()
// once in Session::outputs(); depth/point outputs are added separately.
// Errors: as Outputs::add_* (std::invalid_argument when a name is already
// used or the report is not a JSON object — a plugin bug — and std::bad_alloc;
// the SDK's ABI wrapper turns both into error codes).
// Thread-safety: reentrant; the Outputs object is thread-bound (docs/threading.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <utility>

#include <nlohmann/json.hpp>

#include "procam/sdk/outputs.hpp"

namespace procam::sdk {

struct StandardOutputs {
  double decode_ms = 0;        // plugin wall time spent decoding (sdk::ScopedMs), ms
  uint64_t pattern_count = 0;  // frames projected in this scan, all rounds
  size_t valid_pixels = 0;     // camera pixels with a valid result
  size_t total_pixels = 0;     // camera pixels decoded (valid_fraction = valid / total; 0 if none)
  nlohmann::json report = nlohmann::json::object();  // method-specific; a JSON object
};

// Names, units and descriptions of the standard outputs (also for README tables).
inline constexpr const char* kDecodeMsDescription =
    "plugin wall time spent decoding (add_frame work, end_round, outputs incl. triangulation)";
inline constexpr const char* kPatternCountDescription = "frames projected in this scan, all rounds";
inline constexpr const char* kValidFractionDescription =
    "fraction of camera pixels with a valid decode (valid map != 0)";
inline constexpr const char* kReportDescription = "model choice and decoding settings";

// Adds decode_ms [ms], pattern_count, valid_fraction and report. The report
// gets "patterns": pattern_count when it has no "patterns" key of its own.
inline void add_standard_outputs(Outputs& out, const StandardOutputs& s) {
  if (!s.report.is_object()) throw std::invalid_argument("standard outputs: report must be a JSON object");
  out.add_scalar("decode_ms", "ms", kDecodeMsDescription, s.decode_ms);
  out.add_scalar("pattern_count", "", kPatternCountDescription, static_cast<double>(s.pattern_count));
  out.add_scalar("valid_fraction", "", kValidFractionDescription,
                 s.total_pixels > 0
                     ? static_cast<double>(s.valid_pixels) / static_cast<double>(s.total_pixels)
                     : 0.0);
  nlohmann::json report = s.report;
  if (!report.contains("patterns")) report["patterns"] = s.pattern_count;
  out.add_json("report", kReportDescription, report.dump());
}

}  // namespace procam::sdk
