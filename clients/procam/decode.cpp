// SPDX-License-Identifier: MIT
// `procam decode`: offline decoding of saved frames, no daemon.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <thread>

#include "cli.hpp"
#include "procam/engine/calibration_tables.hpp"
#include "procam/engine/inputs.hpp"
#include "procam/engine/previews.hpp"
#include "procam/engine/results.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/engine/service.hpp"
#include "procam/host/plugin_host.hpp"

#ifndef PROCAM_DEFAULT_PLUGIN_DIRS
#define PROCAM_DEFAULT_PLUGIN_DIRS ""
#endif
#ifndef PROCAM_DEFAULT_RIG
#define PROCAM_DEFAULT_RIG ""
#endif

namespace procam::cli {
namespace fs = std::filesystem;

int cmd_decode(const Args& a) {
  for (const char* k : {"plugin", "method", "frames", "out"})
    if (!a.has(k)) return usage_error(std::string("decode needs --") + k);
  auto params = kv_object(a.list("param"), "--param");
  if (!params) return report(params.status());
  const std::string rig_path = a.has("rig") ? a.get("rig") : PROCAM_DEFAULT_RIG;
  auto rig_cfg = engine::read_json_file(rig_path);
  if (!rig_cfg) return report(rig_cfg.status().with_context("--rig"));
  auto rig_json = engine::plugin_rig_json_from_config(*rig_cfg, std::max(1u, std::thread::hardware_concurrency()));
  if (!rig_json) return report(rig_json.status());
  // The rig config's calibration tables (paths relative to it), as procamd does.
  auto tables = engine::load_calibration_tables(*rig_cfg, fs::path(rig_path).parent_path().string(), rig_path);
  if (!tables) return report(tables.status());
  if (!tables->empty()) (*rig_json)["calibration_tables"] = std::move(*tables);
  const std::vector<std::string> dirs = plugin_search_dirs(a);
  host::PluginHost host;
  host.load_directories(dirs);
  const std::string isolation = a.get("isolation", "process");
  if (isolation != "process" && isolation != "in_process")
    return usage_error("--isolation must be process or in_process, not '" + isolation + "'");
  if (isolation == "in_process") {
    host::IsolationOptions iso;
    iso.mode = host::Isolation::in_process;
    host.set_isolation(iso);
  }
  const auto [cam_w, cam_h] = engine::camera0_size(*rig_json);
  auto inputs = engine::load_input_files(a.list("input"), cam_w, cam_h);  // --input NAME=FILE
  if (!inputs) return report(inputs.status());
  auto session =
      host.create_session(a.get("plugin"), a.get("method"), params->dump(), rig_json->dump(), inputs->views());
  if (!session) return report(session.status());
  auto t0 = std::chrono::steady_clock::now();
  engine::OfflineOptions offline;
  if (a.has("layout")) offline.layout = a.get("layout");
  if (const auto* pl = host.find(a.get("plugin")))
    for (const auto& m : pl->methods)
      if (m.name == a.get("method")) offline.multi_round = m.describe.value("rounds", nlohmann::json(1)) != nlohmann::json(1);
  auto outcome = engine::run_offline(*session, a.get("frames"), [](const engine::Progress& p) {
    std::fprintf(stderr, "\r  decode round %d %zu/%zu %-24.24s", p.round, p.done, p.total, p.message.c_str());
  }, offline);
  std::fprintf(stderr, "\n");
  if (!outcome) return report(outcome.status());
  if (!outcome->rounds_skipped.empty()) std::fprintf(stderr, "note: %s\n", outcome->rounds_skipped.c_str());
  auto outs = session->outputs();
  if (!outs) return report(outs.status());
  const std::string out = a.get("out");
  auto written = engine::write_outputs(out, *outs);
  if (!written) return report(written.status());
  nlohmann::json rounds = nlohmann::json::array();
  for (const auto& r : outcome->rounds) rounds.push_back({{"note", r.note}, {"frames", r.frames}});
  nlohmann::json m = {{"procam", 1}, {"scan_id", "offline"}, {"state", "done"}, {"plugin", a.get("plugin")},
                      {"method", a.get("method")}, {"params", *params}, {"frames_dir", a.get("frames")},
                      {"layout", offline.layout}, {"inputs", a.list("input")},
                      {"created_utc", engine::utc_now()}, {"finished_utc", engine::utc_now()},
                      {"plan", {{"rounds", rounds}, {"patterns", outcome->patterns},
                                {"rounds_skipped", outcome->rounds_skipped.empty() ? nlohmann::json(nullptr)
                                                                                   : nlohmann::json(outcome->rounds_skipped)}}},
                      {"timing_ms", {{"decode", outcome->decode_ms},
                                     {"total", std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count()}}},
                      {"outputs", written->outputs}, {"previews", written->previews}, {"error", nullptr}};
  if (auto s = engine::write_scan_report(out, m); !s) return report(s);
  m["files"] = engine::list_files(out);
  if (auto s = engine::write_file_atomic((fs::path(out) / "manifest.json").string(), m.dump(2)); !s) return report(s);
  if (a.json) std::cout << m.dump(2) << "\n";
  else print_summary(m, out);
  return 0;
}

}  // namespace procam::cli
