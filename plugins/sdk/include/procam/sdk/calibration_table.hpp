// SPDX-License-Identifier: MIT
// procam::sdk::CalibrationTable — a measured, monotonic 1-D map from a
// per-pixel quantity a plugin computes (a focus index f̄, a ratio Ω, a
// separation residue β⁺ − β⁻) to a physical one (depth in mm), and its file
// format. docs/calibration.md is the user's workflow; this is the contract.
//
// File / JSON format, version 1 (one table per file):
//   {"format": "procam-calibration-table", "version": 1,
//    "name": "defocus.multi-focal",              // what a plugin asks the rig for
//    "x": {"name": "fbar", "unit": "index"},     // the measured quantity
//    "y": {"name": "depth", "unit": "mm"},       // what it maps to
//    "samples": [[x0, y0], [x1, y1], ...],       // >= 2; x strictly increasing,
//                                                // y strictly monotonic (either way)
//    "extra": {...},                             // optional, plugin-specific
//    "made": {...}}                              // optional provenance (plugin,
//                                                // method, rig, scene, from_scan, date)
// Unknown top-level keys are refused (a typo must not pass silently).
//
// lookup(x) interpolates linearly between samples and returns NaN outside
// [x_first, x_last] or for non-finite x: a table never extrapolates.
// inverse(y) is the same map the other way (y monotonic makes it unique).
//
// fit_monotonic() builds a table from scattered (x, y) pairs of a calibration
// scan (a plane: every pixel one pair): it bins x into equal-count bins, takes
// the median x and median y of each bin (robust to the stray pixel of a real
// capture), and keeps the longest run in which y is strictly monotonic in the
// direction of the majority of steps, so the result is always invertible.
//
// Errors: sdk::Error INVALID_ARGUMENT naming the field ("calibration table
// 'defocus.multi-focal': samples[3] x 2.1 is not above samples[2] x 2.4").
// Thread-safety: the struct is a value; lookups on a const table are reentrant.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/sdk/error.hpp"
#include "procam/sdk/params.hpp"

namespace procam::sdk {

inline constexpr const char* kCalibrationTableFormat = "procam-calibration-table";
inline constexpr int kCalibrationTableVersion = 1;

struct CalibrationTable {
  std::string name;                        // e.g. "defocus.multi-focal"
  std::string x_name, x_unit;              // e.g. "fbar", "index"
  std::string y_name = "depth", y_unit = "mm";
  std::vector<std::pair<double, double>> samples;  // (x, y), x strictly increasing
  nlohmann::json extra = nlohmann::json::object();
  nlohmann::json made = nlohmann::json::object();

  bool empty() const noexcept { return samples.size() < 2; }
  double x_min() const noexcept { return samples.empty() ? std::numeric_limits<double>::quiet_NaN() : samples.front().first; }
  double x_max() const noexcept { return samples.empty() ? std::numeric_limits<double>::quiet_NaN() : samples.back().first; }
  bool y_increasing() const noexcept {
    return samples.size() >= 2 && samples.back().second > samples.front().second;
  }

  // y at x, linear between samples; NaN outside [x_min, x_max] or for NaN x.
  float lookup(double x) const noexcept {
    if (samples.size() < 2 || !(x >= samples.front().first) || !(x <= samples.back().first))
      return std::numeric_limits<float>::quiet_NaN();
    auto it = std::upper_bound(samples.begin(), samples.end(), x,
                               [](double v, const std::pair<double, double>& s) { return v < s.first; });
    if (it == samples.end()) return static_cast<float>(samples.back().second);
    const auto& hi = *it;
    const auto& lo = *(it - 1);
    const double t = (x - lo.first) / (hi.first - lo.first);  // hi.first > lo.first: no 0/0
    return static_cast<float>(lo.second + t * (hi.second - lo.second));
  }

  // x at y (y strictly monotonic makes it unique); NaN outside the y range.
  float inverse(double y) const noexcept {
    if (samples.size() < 2 || !std::isfinite(y)) return std::numeric_limits<float>::quiet_NaN();
    const bool inc = y_increasing();
    for (size_t k = 1; k < samples.size(); ++k) {
      const auto& a = samples[k - 1];
      const auto& b = samples[k];
      const double lo = inc ? a.second : b.second, hi = inc ? b.second : a.second;
      if (y >= lo && y <= hi) {
        const double t = (y - a.second) / (b.second - a.second);  // strictly monotonic: != 0
        return static_cast<float>(a.first + t * (b.first - a.first));
      }
    }
    return std::numeric_limits<float>::quiet_NaN();
  }
};

namespace detail {
inline Error table_string(const nlohmann::json& j, const char* key, const std::string& where,
                          std::string& out) {
  if (!j.is_object() || !j.contains(key) || !j.at(key).is_string() ||
      j.at(key).get<std::string>().empty())
    return invalid_argument(where + key + " must be a non-empty string");
  out = j.at(key).get<std::string>();
  return ok();
}
}  // namespace detail

// Checks and reads a table (format above). `table` is reset first.
inline Error parse_table(const nlohmann::json& j, CalibrationTable& table) {
  table = CalibrationTable{};
  if (!j.is_object()) return invalid_argument("calibration table must be a JSON object");
  std::string where = "calibration table: ";
  if (j.contains("name") && j.at("name").is_string())
    where = "calibration table '" + j.at("name").get<std::string>() + "': ";
  for (const auto& item : j.items()) {
    const std::string key = item.key();  // (a structured binding cannot be captured before C++20 in clang)
    static const char* kKeys[] = {"format", "version", "name", "x", "y", "samples", "extra", "made"};
    if (std::find_if(std::begin(kKeys), std::end(kKeys), [&](const char* k) { return key == k; }) ==
        std::end(kKeys))
      return invalid_argument(where + "unknown key \"" + key +
                              "\" (known: format, version, name, x, y, samples, extra, made)");
  }
  if (!j.contains("format") || j.at("format") != kCalibrationTableFormat)
    return invalid_argument(where + "format must be \"" + std::string(kCalibrationTableFormat) +
                            "\"; is this a calibration table file?");
  if (!j.contains("version") || !j.at("version").is_number_integer() ||
      j.at("version").get<int64_t>() != kCalibrationTableVersion)
    return invalid_argument(where + "version must be " + std::to_string(kCalibrationTableVersion) +
                            " (this procam reads version 1 tables; re-make the table with "
                            "`procam calibrate`)");
  if (Error e = detail::table_string(j, "name", where, table.name); !e.ok()) return e;
  if (!j.contains("x") || !j.contains("y"))
    return invalid_argument(where + "x and y ({\"name\", \"unit\"}) are required");
  if (Error e = detail::table_string(j.at("x"), "name", where + "x.", table.x_name); !e.ok()) return e;
  if (Error e = detail::table_string(j.at("x"), "unit", where + "x.", table.x_unit); !e.ok()) return e;
  if (Error e = detail::table_string(j.at("y"), "name", where + "y.", table.y_name); !e.ok()) return e;
  if (Error e = detail::table_string(j.at("y"), "unit", where + "y.", table.y_unit); !e.ok()) return e;
  if (!j.contains("samples") || !j.at("samples").is_array() || j.at("samples").size() < 2)
    return invalid_argument(where + "samples must be an array of at least 2 [x, y] pairs");
  const nlohmann::json& s = j.at("samples");
  for (size_t k = 0; k < s.size(); ++k) {
    const std::string at = where + "samples[" + std::to_string(k) + "]";
    if (!s[k].is_array() || s[k].size() != 2 || !s[k][0].is_number() || !s[k][1].is_number())
      return invalid_argument(at + " must be a pair of numbers [x, y], got " + detail::shown(s[k]));
    const double x = s[k][0].get<double>(), y = s[k][1].get<double>();
    if (!std::isfinite(x) || !std::isfinite(y)) return invalid_argument(at + " is not finite");
    if (k > 0 && !(x > table.samples.back().first))
      return invalid_argument(at + " x " + std::to_string(x) + " is not above samples[" +
                              std::to_string(k - 1) + "] x " +
                              std::to_string(table.samples.back().first) +
                              " (x must increase strictly)");
    table.samples.emplace_back(x, y);
  }
  const bool inc = table.samples[1].second > table.samples[0].second;
  for (size_t k = 1; k < table.samples.size(); ++k) {
    const double dy = table.samples[k].second - table.samples[k - 1].second;
    if (!(inc ? dy > 0 : dy < 0))
      return invalid_argument(where + "y is not strictly monotonic at samples[" + std::to_string(k) +
                              "]: the map could not be inverted");
  }
  if (j.contains("extra")) table.extra = j.at("extra");
  if (j.contains("made")) {
    if (!j.at("made").is_object()) return invalid_argument(where + "made must be an object");
    table.made = j.at("made");
  }
  return ok();
}

inline nlohmann::json to_json(const CalibrationTable& t) {
  nlohmann::json samples = nlohmann::json::array();
  for (const auto& [x, y] : t.samples) samples.push_back({x, y});
  return {{"format", kCalibrationTableFormat},
          {"version", kCalibrationTableVersion},
          {"name", t.name},
          {"x", {{"name", t.x_name}, {"unit", t.x_unit}}},
          {"y", {{"name", t.y_name}, {"unit", t.y_unit}}},
          {"samples", std::move(samples)},
          {"extra", t.extra},
          {"made", t.made}};
}

// Fits a monotonic table to scattered pairs (xs[i], ys[i]); non-finite pairs
// are skipped. `bins` equal-count bins (>= 2); each yields (median x, median y).
// Keeps the longest run of bins in which y moves strictly in the majority
// direction and x strictly increases. Needs at least 2·bins finite pairs.
// `table`'s name, axes, extra and made are kept; its samples are replaced.
inline Error fit_monotonic(const std::vector<float>& xs, const std::vector<float>& ys, size_t bins,
                           CalibrationTable& table) {
  if (xs.size() != ys.size())
    return invalid_argument("fit_monotonic: " + std::to_string(xs.size()) + " x values but " +
                            std::to_string(ys.size()) + " y values");
  if (bins < 2) return invalid_argument("fit_monotonic: bins must be >= 2");
  std::vector<std::pair<float, float>> pairs;
  pairs.reserve(xs.size());
  for (size_t i = 0; i < xs.size(); ++i)
    if (std::isfinite(xs[i]) && std::isfinite(ys[i])) pairs.emplace_back(xs[i], ys[i]);
  if (pairs.size() < 2 * bins)
    return invalid_argument("fit_monotonic: " + std::to_string(pairs.size()) +
                            " valid pixels, need at least " + std::to_string(2 * bins) +
                            "; is the calibration plane lit, in view and decoded?");
  std::sort(pairs.begin(), pairs.end());
  auto median = [](std::vector<float>& v) {
    const size_t m = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
    return static_cast<double>(v[m]);
  };
  std::vector<std::pair<double, double>> pts;
  std::vector<float> bx, by;
  for (size_t b = 0; b < bins; ++b) {
    const size_t lo = pairs.size() * b / bins, hi = pairs.size() * (b + 1) / bins;
    bx.clear();
    by.clear();
    for (size_t i = lo; i < hi; ++i) {
      bx.push_back(pairs[i].first);
      by.push_back(pairs[i].second);
    }
    pts.emplace_back(median(bx), median(by));
  }
  int up = 0, down = 0;
  for (size_t k = 1; k < pts.size(); ++k) {
    if (pts[k].second > pts[k - 1].second) ++up;
    if (pts[k].second < pts[k - 1].second) ++down;
  }
  const bool inc = up >= down;
  size_t best_begin = 0, best_len = 1, begin = 0;
  for (size_t k = 1; k <= pts.size(); ++k) {
    const bool ok_step = k < pts.size() && pts[k].first > pts[k - 1].first &&
                         (inc ? pts[k].second > pts[k - 1].second : pts[k].second < pts[k - 1].second);
    if (!ok_step) {
      if (k - begin > best_len) {
        best_len = k - begin;
        best_begin = begin;
      }
      begin = k;
    }
  }
  if (best_len < 2)
    return invalid_argument("fit_monotonic: y does not change monotonically with x over the "
                            "plane; does the plane span enough depth (tilt it more)?");
  table.samples.assign(pts.begin() + static_cast<std::ptrdiff_t>(best_begin),
                       pts.begin() + static_cast<std::ptrdiff_t>(best_begin + best_len));
  return ok();
}

}  // namespace procam::sdk
