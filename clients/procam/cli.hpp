// SPDX-License-Identifier: MIT
// Shared pieces of the `procam` CLI: parsed arguments, error reporting, the
// scan summary, and the command table.
//
// How to add a command:
//   1. Write `int cmd_<name>(const Args&)` in a new clients/procam/<area>.cpp.
//   2. Declare it below and add one row to kCommands in main.cpp (name, the
//      options it accepts, whether it talks to procamd, one usage line).
//   3. Add the file to clients/CMakeLists.txt and a test in tests/integration/.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/client/client.hpp"
#include "procam/core/status.hpp"

namespace procam::cli {

struct Args {
  std::string cmd;
  std::map<std::string, std::string> opt;              // last value of each --key
  std::map<std::string, std::vector<std::string>> all; // every value of each --key
  bool json = false;
  std::string positional;  // the one bare argument of commands that take one (calibrate PLUGIN/METHOD)
  bool has(const std::string& k) const { return opt.count(k) != 0; }
  std::string get(const std::string& k, const std::string& def = "") const {
    auto it = opt.find(k);
    return it == opt.end() ? def : it->second;
  }
  std::vector<std::string> list(const std::string& k) const {
    auto it = all.find(k);
    return it == all.end() ? std::vector<std::string>{} : it->second;
  }
  // A client for --endpoint (default $PROCAM_ENDPOINT) with --timeout seconds.
  client::Client connect() const;
};

int usage_error(const std::string& msg);
int report(const Status& s);
// "k=v" items to an object; v parsed as JSON when it is JSON, else a string.
Result<nlohmann::json> kv_object(const std::vector<std::string>& items, const char* what);
std::vector<std::string> split_colon(const std::string& s);
// `--input NAME=SCAN_ID[:OUTPUT]` items to scan inputs (OUTPUT defaults to
// NAME): input NAME of the method gets output OUTPUT of finished scan SCAN_ID.
Result<std::map<std::string, proto::InputRef>> input_refs(const std::vector<std::string>& items);
// Plugin folders for offline commands: --plugins DIR..., then
// $PROCAM_PLUGIN_PATH, else the build's and the install's plugin folders.
std::vector<std::string> plugin_search_dirs(const Args& a);
// The short scan summary (`make demo`): method, patterns, decode time, accuracy.
void print_summary(const nlohmann::json& manifest, const std::string& out_dir);
// Progress on stderr: a redrawn bar on a terminal, sparse lines in logs.
void progress_line(const proto::Event& ev);

// Commands (remote.cpp, decode.cpp, ...).
int cmd_plugins(const Args&);
int cmd_rig(const Args&);
int cmd_status(const Args&);
int cmd_scans(const Args&);
int cmd_rig_options(const Args&);
int cmd_scan(const Args&);
int cmd_result(const Args&);
int cmd_decode(const Args&);
int cmd_bench(const Args&);  // bench.cpp (issue 4): speed-vs-error report
int cmd_sim(const Args&);  // sim.cpp (issue 3)
int cmd_keygen(const Args&);  // service.cpp (issue 6): CURVE keys, cancel, ping
int cmd_cancel(const Args&);
int cmd_ping(const Args&);
int cmd_calibrate_latency(const Args&);  // hw.cpp (issue 5): display/camera latency of a rig
int cmd_calibrate(const Args&);  // calibrate_table.cpp (issue 12): a calibration table from a reference scan
int cmd_calibrate_geometry(const Args&);  // calibrate.cpp (issue 16): intrinsics, distortion, cam_from_proj

}  // namespace procam::cli
