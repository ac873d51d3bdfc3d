// SPDX-License-Identifier: MIT
// Calibration tables in rig configs (see calibration_tables.hpp).
#include "procam/engine/calibration_tables.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "procam/engine/rig_json.hpp"
#include "procam/sdk/calibration_table.hpp"

namespace procam::engine {
namespace fs = std::filesystem;

Status check_calibration_table(const nlohmann::json& t, const std::string& what) {
  // The SDK's reader is the one definition of format v1: what the daemon
  // accepts here is exactly what plugins can parse.
  sdk::CalibrationTable parsed;
  if (sdk::Error e = sdk::parse_table(t, parsed); !e.ok())
    return Error(Code::invalid_argument, what + ": " + e.message,
                 "make tables with `procam calibrate` (docs/calibration.md); do not edit samples by hand");
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
