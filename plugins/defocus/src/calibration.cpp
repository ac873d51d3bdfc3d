// SPDX-License-Identifier: MIT
// Calibration tables of the defocus methods (see calibration.hpp).
#include "calibration.hpp"

#include <cmath>
#include <sstream>

namespace procam::defocus {
namespace {

std::string list_mm(const std::vector<double>& f) {
  std::ostringstream s;
  s << "[";
  for (size_t k = 0; k < f.size(); ++k) s << (k ? ", " : "") << f[k];
  s << "] mm";
  return s.str();
}

}  // namespace

sdk::Error make_table(const CueKind& kind, const std::vector<float>& cue, const std::vector<float>& depth_mm,
                      const std::vector<double>& focus_mm, size_t bins, sdk::CalibrationTable& out) {
  out = sdk::CalibrationTable{};
  out.name = kind.table_name;
  out.x_name = kind.x_name;
  out.x_unit = kind.x_unit;
  out.y_name = "depth";
  out.y_unit = "mm";
  out.extra = {{"focus_mm", focus_mm}, {"method", kind.method}};
  if (sdk::Error e = sdk::fit_monotonic(cue, depth_mm, bins, out); !e.ok())
    return sdk::invalid_argument("calibration table '" + std::string(kind.table_name) + "': " + e.message);
  return sdk::ok();
}

sdk::Error table_from_rig(const sdk::Rig& rig, const CueKind& kind, const std::vector<double>& focus_mm,
                          sdk::CalibrationTable& out) {
  const nlohmann::json* j = rig.table(kind.table_name);
  if (j == nullptr)
    return sdk::failed_precondition("rig has no calibration table '" + std::string(kind.table_name) +
                                    "': make one with method calibrate-" + std::string(kind.method) +
                                    " on an inclined plane (`procam calibrate defocus/calibrate-" +
                                    std::string(kind.method) + "`, docs/calibration.md) and add it to the rig "
                                    "config's calibration_tables");
  if (sdk::Error e = sdk::parse_table(*j, out); !e.ok()) return e;
  std::vector<double> made_with;
  if (out.extra.is_object() && out.extra.contains("focus_mm") && out.extra.at("focus_mm").is_array())
    for (const auto& v : out.extra.at("focus_mm"))
      if (v.is_number()) made_with.push_back(v.get<double>());
  bool same = made_with.size() == focus_mm.size();
  for (size_t k = 0; same && k < focus_mm.size(); ++k)
    same = std::abs(made_with[k] - focus_mm[k]) <= 1e-6 * focus_mm[k];
  if (!same)
    return sdk::invalid_argument("calibration table '" + std::string(kind.table_name) + "' was made with focus settings " +
                                 (made_with.empty() ? std::string("(none recorded)") : list_mm(made_with)) +
                                 " but this scan asks for " + list_mm(focus_mm) +
                                 ": scan with the table's settings (params) or calibrate again with these");
  return sdk::ok();
}

size_t depth_from_cue(const sdk::CalibrationTable& table, const std::vector<float>& cue, uint32_t threads,
                      std::vector<float>& depth_mm) {
  depth_mm.resize(cue.size());
  const size_t n = cue.size();
  std::vector<size_t> counts(threads < 1 ? 1 : threads, 0);
  const auto bands = static_cast<uint32_t>(counts.size());
  sdk::parallel_rows(bands, bands, [&](uint32_t b0, uint32_t b1) {
    for (uint32_t b = b0; b < b1; ++b) {
      size_t c = 0;
      for (size_t i = n * b / bands; i < n * (b + 1) / bands; ++i) {
        depth_mm[i] = table.lookup(static_cast<double>(cue[i]));  // NaN outside: never extrapolated
        c += std::isfinite(depth_mm[i]) ? 1u : 0u;
      }
      counts[b] = c;
    }
  });
  size_t total = 0;
  for (size_t c : counts) total += c;
  return total;
}

}  // namespace procam::defocus
