// SPDX-License-Identifier: MIT
// Calibration tables in rig configs (see calibration_tables.hpp).
#include "procam/engine/calibration_tables.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "procam/engine/rig_json.hpp"

namespace procam::engine {
namespace fs = std::filesystem;

Status check_calibration_table(const nlohmann::json& t, const std::string& what) {
  // Format v1 as fixed in docs/calibration.md. (The SDK's parse_table reads
  // the same format on the plugin side.)
  auto bad = [&](const std::string& m) {
    return Error(Code::invalid_argument, what + ": " + m,
                 "make tables with `procam calibrate` (docs/calibration.md); do not edit samples by hand");
  };
  if (!t.is_object()) return bad("a table must be a JSON object");
  if (t.value("format", "") != "procam-calibration-table")
    return bad("\"format\" must be \"procam-calibration-table\"");
  if (!t.contains("version") || !t["version"].is_number_integer() || t["version"].get<int64_t>() != 1)
    return bad("\"version\" must be 1 (the only table format this procam reads)");
  if (!t.contains("name") || !t["name"].is_string() || t["name"].get<std::string>().empty())
    return bad("\"name\" must be a non-empty string");
  for (const char* axis : {"x", "y"}) {
    const auto it = t.find(axis);
    if (it == t.end() || !it->is_object() || !(*it)["name"].is_string() || !(*it)["unit"].is_string())
      return bad(std::string("\"") + axis + "\" must be {\"name\": <string>, \"unit\": <string>}");
  }
  for (const char* obj : {"extra", "made"})
    if (t.contains(obj) && !t[obj].is_object()) return bad(std::string("\"") + obj + "\" must be an object");
  const auto samples = t.find("samples");
  if (samples == t.end() || !samples->is_array() || samples->size() < 2)
    return bad("\"samples\" must be an array of at least 2 [x, y] pairs");
  double px = 0, py = 0;
  int dir = 0;  // +1 / -1 once y's direction is known
  for (size_t i = 0; i < samples->size(); ++i) {
    const auto& s = (*samples)[i];
    const std::string at = "samples[" + std::to_string(i) + "]";
    if (!s.is_array() || s.size() != 2 || !s[0].is_number() || !s[1].is_number())
      return bad(at + " must be [x, y], two numbers");
    const double x = s[0].get<double>(), y = s[1].get<double>();
    if (!std::isfinite(x) || !std::isfinite(y)) return bad(at + " is not finite");
    if (i > 0) {
      if (!(x > px)) return bad(at + ": x must increase strictly (" + std::to_string(px) + " then " + std::to_string(x) + ")");
      const int d = y > py ? 1 : y < py ? -1 : 0;
      if (d == 0 || (dir != 0 && d != dir))
        return bad(at + ": y must be strictly monotonic (" + std::to_string(py) + " then " + std::to_string(y) + ")");
      dir = d;
    }
    px = x;
    py = y;
  }
  return {};
}

Result<nlohmann::json> load_calibration_tables(const nlohmann::json& rig, const std::string& config_dir,
                                               const std::string& config_file) {
  nlohmann::json out = nlohmann::json::object();
  if (!rig.is_object() || !rig.contains("calibration_tables")) return out;
  const std::string where = "rig config '" + config_file + "'";
  const auto& refs = rig["calibration_tables"];
  if (!refs.is_object())
    return Error(Code::invalid_argument, where + ": 'calibration_tables' must be an object",
                 "{\"<table name>\": \"<file, relative to the config>\"}, e.g. "
                 "{\"defocus.multi-focal\": \"tables/defocus-multi-focal.json\"}");
  for (const auto& [name, ref] : refs.items()) {
    const std::string field = "calibration_tables." + name;
    if (!ref.is_string() || ref.get<std::string>().empty())
      return Error(Code::invalid_argument, where + ": '" + field + "' must be a file path (a string)",
                   "paths are relative to the rig config file");
    const fs::path p = fs::path(ref.get<std::string>()).is_absolute()
                           ? fs::path(ref.get<std::string>())
                           : (fs::path(config_dir) / ref.get<std::string>()).lexically_normal();
    auto table = read_json_file(p.string());
    if (!table)
      return Error(table.status().code(), where + ": '" + field + "': " + table.status().message(),
                   "make the table with `procam calibrate` (docs/calibration.md) or fix the path");
    PROCAM_TRY(check_calibration_table(*table, where + ": '" + field + "' (" + p.string() + ")"));
    if ((*table)["name"].get<std::string>() != name)
      return Error(Code::invalid_argument,
                   where + ": '" + field + "' holds a table named '" + (*table)["name"].get<std::string>() + "'",
                   "the key must be the table's name: plugins look tables up by it");
    out[name] = std::move(*table);
  }
  return out;
}

nlohmann::json without_calibration_tables(nlohmann::json rig) {
  if (rig.is_object()) rig.erase("calibration_tables");
  return rig;
}

std::string describe_calibration_table(const std::string& name, const nlohmann::json& t) {
  auto axis = [&](const char* a) {
    const auto& o = t.value(a, nlohmann::json::object());
    return o.value("name", std::string("?")) + " [" + o.value("unit", std::string()) + "]";
  };
  const auto& s = t.value("samples", nlohmann::json::array());
  double x0 = NAN, x1 = NAN, ylo = NAN, yhi = NAN;
  for (const auto& p : s) {
    if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number()) continue;
    const double x = p[0].get<double>(), y = p[1].get<double>();
    if (std::isnan(x0)) x0 = x;
    x1 = x;
    ylo = std::isnan(ylo) ? y : std::min(ylo, y);
    yhi = std::isnan(yhi) ? y : std::max(yhi, y);
  }
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s: %s -> %s, x %g..%g, y %g..%g, %zu samples", name.c_str(), axis("x").c_str(),
                axis("y").c_str(), x0, x1, ylo, yhi, s.size());
  std::string line = buf;
  const auto& made = t.value("made", nlohmann::json::object());
  std::string m;
  for (const auto& [k, v] : made.items())
    m += (m.empty() ? "" : ", ") + k + " " + (v.is_string() ? v.get<std::string>() : v.dump());
  if (!m.empty()) line += "; made: " + m;
  return line;
}

}  // namespace procam::engine
