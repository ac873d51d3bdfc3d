// SPDX-License-Identifier: MIT
// `procam calibrate-latency`: measure display and camera latency on a rig
// (offline: opens the rig's devices itself, so stop procamd first) with
// alternating black/white patterns, print them, and with --write store them in
// the rig config's "sync" section, where procamd's sync engine reads them and
// `procam rig` shows them (state.sync).
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "cli.hpp"
#include "procam/engine/calibration_tables.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/sync.hpp"
#include "procam/hw/rig.hpp"

namespace procam::cli {
namespace fs = std::filesystem;

int cmd_calibrate_latency(const Args& a) {
  if (!a.has("rig")) return usage_error("calibrate-latency needs --rig RIG.json");
  const std::string path = a.get("rig");
  auto cfg = engine::read_json_file(path);
  if (!cfg) return report(cfg.status());
  hw::RigContext ctx;
  ctx.config_dir = fs::absolute(path).parent_path().string();
  ctx.scene_dirs = {(fs::path(ctx.config_dir) / ".." / "scenes").lexically_normal().string()};
  auto rig = hw::create_rig(engine::without_calibration_tables(*cfg), ctx);  // tables: not a device key
  if (!rig) return report(rig.status().with_context("opening the rig (is procamd running on it? stop it first)"));
  int cycles = 5;
  try {
    if (a.has("cycles")) cycles = std::stoi(a.get("cycles"));
  } catch (const std::exception&) {
    return usage_error("--cycles must be an integer");
  }
  auto res = engine::calibrate_latency(**rig, cycles);
  if (!res) return report(res.status());
  if (a.json) {
    std::cout << res->dump(2) << "\n";
  } else {
    std::printf("latency calibration on rig %s (%d black/white cycles)\n", cfg->value("name", "?").c_str(), cycles);
    std::printf("  display latency  %.3f ms   (presentation report -> light seen by the camera)\n",
                (*res)["display_latency_ms"].get<double>());
    std::printf("  camera latency   %.3f ms   (capture call -> frame stamp)\n", (*res)["camera_latency_ms"].get<double>());
  }
  if (a.has("write")) {
    if (!(*rig)->describe()["state"].contains("sync"))
      return report(Error(Code::failed_precondition, "rig '" + cfg->value("name", "?") + "' keeps no sync state",
                          "the pure sim rig needs no latency; use a hardware rig config (configs/rigs/glfw-*.json)"));
    nlohmann::json updated = *cfg;
    char stamp[32];
    const std::time_t now = std::time(nullptr);
    std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
    nlohmann::json& sync = updated["sync"];
    if (!sync.is_object()) sync = nlohmann::json::object();
    sync["display_latency_ms"] = (*res)["display_latency_ms"];
    sync["camera_latency_ms"] = (*res)["camera_latency_ms"];
    sync["latency_source"] = "calibrated";
    sync["calibrated_utc"] = stamp;
    const std::string tmp = path + ".tmp";
    {
      std::ofstream out(tmp);
      out << updated.dump(2) << "\n";
      if (!out) return report(Error(Code::io_error, "cannot write " + tmp));
    }
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) return report(Error(Code::io_error, "cannot replace " + path + ": " + ec.message()));
    std::printf("  stored in %s (sync.display_latency_ms / camera_latency_ms); restart procamd to use them\n", path.c_str());
  }
  return 0;
}

}  // namespace procam::cli
