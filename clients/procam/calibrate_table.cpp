// SPDX-License-Identifier: MIT
// `procam calibrate PLUGIN/METHOD --out FILE`: make a calibration table
// through the product (docs/calibration.md). Two scans on procamd:
//   1. the reference (default structured-light/gray) measures the plane's
//      depth_mm by triangulation;
//   2. PLUGIN/METHOD runs with that depth_mm as its input and outputs the
//      JSON output calibration_table;
// then the table (with "made" completed: rig, scene, scans, date) is checked
// and written to FILE, and the line to add to the rig config is printed.
// FILE is never overwritten without --force 1 (checked before scanning).
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "cli.hpp"
#include "procam/engine/calibration_tables.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/service.hpp"

namespace procam::cli {
namespace fs = std::filesystem;

namespace {

// "plugin/method" -> {plugin, method}; empty on a malformed target.
std::pair<std::string, std::string> split_target(const std::string& t) {
  const size_t slash = t.find('/');
  if (slash == std::string::npos || slash == 0 || slash + 1 == t.size() || t.find('/', slash + 1) != std::string::npos)
    return {};
  return {t.substr(0, slash), t.substr(slash + 1)};
}

// Runs one scan to its end; its manifest when done, else the scan's error.
Result<nlohmann::json> run_to_end(client::Client& c, const proto::Scan& s, const char* what) {
  std::fprintf(stderr, "%s: %s/%s\n", what, s.plugin.c_str(), s.method.c_str());
  auto fin = c.scan(s, progress_line);
  if (!fin) return fin.status().with_context(what);
  const std::string id = fin->value("scan_id", "");
  if (fin->value("state", "") != "done") {
    auto err = proto::error_from_json(fin->value("error", nlohmann::json()));
    return (err ? *err : Status(Error(Code::internal, "scan " + id + " ended " + fin->value("state", ""))))
        .with_context(std::string(what) + " (scan " + id + ")");
  }
  auto r = c.call(proto::ResultQuery{id});
  if (!r) return r.status().with_context(what);
  return r->value("manifest", nlohmann::json::object());
}

}  // namespace

int cmd_calibrate(const Args& a) {
  const auto [plugin, method] = split_target(a.positional);
  if (plugin.empty()) return usage_error("calibrate needs PLUGIN/METHOD, e.g. procam calibrate defocus/two-focal --out t.json");
  if (!a.has("out")) return usage_error("calibrate needs --out FILE for the table");
  const std::string out = a.get("out");
  const bool force = a.has("force") && a.get("force") != "0";
  std::error_code ec;
  if (fs::exists(out, ec) && !force)
    return report(Error(Code::failed_precondition, "'" + out + "' exists; not overwriting it",
                        "choose another --out, or add --force 1 to replace it"));
  const auto [ref_plugin, ref_method] = split_target(a.get("reference", "structured-light/gray"));
  if (ref_plugin.empty()) return usage_error("--reference must be PLUGIN/METHOD, e.g. structured-light/gray");
  auto params = kv_object(a.list("param"), "--param");
  if (!params) return report(params.status());

  client::Client c = a.connect();
  nlohmann::json rig_options = nlohmann::json::object();
  if (a.has("scene")) rig_options["scene"] = a.get("scene");
  const std::string label = a.get("label", "calibration " + a.positional);

  proto::Scan ref;
  ref.plugin = ref_plugin;
  ref.method = ref_method;
  ref.rig_options = rig_options;
  ref.label = label + " (reference)";
  auto ref_manifest = run_to_end(c, ref, "reference scan");
  if (!ref_manifest) return report(ref_manifest.status());
  const std::string ref_id = ref_manifest->value("scan_id", "");

  proto::Scan cal;
  cal.plugin = plugin;
  cal.method = method;
  cal.params = *params;
  cal.rig_options = rig_options;
  cal.label = label;
  cal.inputs["depth_mm"] = {ref_id, "depth_mm"};
  auto cal_manifest = run_to_end(c, cal, "calibration scan");
  if (!cal_manifest) return report(cal_manifest.status());
  const std::string cal_id = cal_manifest->value("scan_id", "");

  nlohmann::json table;
  for (const auto& o : cal_manifest->value("outputs", nlohmann::json::array()))
    if (o.value("name", "") == "calibration_table" && o.value("kind", "") == "json") table = o.value("value", nlohmann::json());
  std::string why;  // a calibration method that could not fit says so in its report
  for (const auto& o : cal_manifest->value("outputs", nlohmann::json::array()))
    if (o.value("name", "") == "report" && o.contains("value") && o["value"].is_object())
      why = o["value"].value("table_error", "");
  if (table.is_null() && !why.empty())
    return report(Error(Code::failed_precondition, "scan " + cal_id + " (" + a.positional + ") made no table: " + why,
                        "docs/calibration.md: the plane, its placement and the focus settings"));
  if (table.is_null())
    return report(Error(Code::not_found, "scan " + cal_id + " (" + a.positional + ") has no JSON output 'calibration_table'",
                        "is " + a.positional + " a calibration method? `procam plugins` lists each method's outputs"));
  // Complete "made" with what only this side knows; keep what the plugin wrote.
  nlohmann::json& made = table["made"];
  if (!made.is_object()) made = nlohmann::json::object();
  const nlohmann::json rig_state = cal_manifest->value("rig", nlohmann::json::object());
  const nlohmann::json defaults = {
      {"plugin", plugin},
      {"method", method},
      {"rig", rig_state.value("name", "")},
      {"scene", rig_state.value("state", nlohmann::json::object()).value("scene", "")},
      {"from_scan", cal_id},
      {"reference_scan", ref_id},
      {"reference", ref_plugin + "/" + ref_method},
      {"date", engine::utc_now()}};
  for (const auto& [k, v] : defaults.items())
    if (!made.contains(k)) made[k] = v;
  if (Status st = engine::check_calibration_table(table, "the calibration_table of scan " + cal_id); !st)
    return report(st);
  if (fs::path(out).has_parent_path()) fs::create_directories(fs::path(out).parent_path(), ec);
  if (Status st = engine::write_file_atomic(out, table.dump(2) + "\n"); !st) return report(st);
  const std::string name = table["name"].get<std::string>();
  if (a.json) {
    std::cout << nlohmann::json{{"file", out}, {"table", table}, {"reference_scan", ref_id}, {"scan", cal_id}}.dump(2)
              << "\n";
    return 0;
  }
  std::printf("wrote %s\n  %s\n", out.c_str(), engine::describe_calibration_table(name, table).c_str());
  // An absolute path is always right; a path relative to the rig config's
  // folder (e.g. "tables/x.json") keeps the rig folder movable.
  const std::string abs = fs::absolute(out, ec).lexically_normal().string();
  std::printf("add to the rig config (an absolute path, or one relative to the config file), then restart procamd:\n"
              "  \"calibration_tables\": {\"%s\": \"%s\"}\n",
              name.c_str(), abs.c_str());
  return 0;
}

}  // namespace procam::cli
