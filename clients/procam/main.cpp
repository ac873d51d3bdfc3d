// SPDX-License-Identifier: MIT
// `procam`: command-line client for procamd, and offline tools (see cli.hpp
// for how to add a command).
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cli.hpp"
#include "procam/core/log.hpp"

namespace {
using namespace procam::cli;

struct Command {
  const char* name;
  int (*run)(const Args&);
  std::vector<std::string> options;  // accepted --options (besides --json/--help)
  const char* usage;
};

// The command table. Remote commands also take --endpoint E (default
// $PROCAM_ENDPOINT or tcp://127.0.0.1:5560) and --timeout SECONDS.
const std::vector<Command> kCommands = {
    {"plugins", cmd_plugins, {"endpoint", "timeout"},
     "plugins                         list decoder plugins, their methods and parameters"},
    {"rig", cmd_rig, {"endpoint", "timeout"},
     "rig                             describe the active rig (hardware, calibration, state)"},
    {"status", cmd_status, {"endpoint", "timeout", "scan"},
     "status [--scan ID]              daemon status, or one scan's state and progress"},
    {"scan", cmd_scan, {"endpoint", "timeout", "plugin", "method", "param", "rig-option", "label", "save-frames", "out", "input"},
     "scan --plugin P --method M [--param k=v]... [--rig-option k=v]... [--label L] [--save-frames 1]\n"
     "     [--input NAME=SCAN_ID[:OUTPUT]]... --out DIR\n"
     "                                run a scan, show progress, download results, print a summary;\n"
     "                                --save-frames 1 also keeps the raw frames (frame-r<round>-<i>.png)\n"
     "                                for `procam decode --frames DIR`; --input feeds output OUTPUT (default\n"
     "                                NAME) of a finished scan to the method's input NAME (procam plugins lists them)"},
    {"scans", cmd_scans, {"endpoint", "timeout", "state", "limit"},
     "scans [--state queued|capturing|decoding|writing|done|failed|active] [--limit N]\n"
     "                                list the daemon's scans, newest first (default 20)"},
    {"rig-options", cmd_rig_options, {"endpoint", "timeout"},
     "rig-options                     the rig_options a scan may carry (the sim rig: its scenes)"},
    {"result", cmd_result, {"endpoint", "timeout", "scan", "out"},
     "result --scan ID --out DIR      download a finished scan's results"},
    {"decode", cmd_decode, {"plugin", "method", "param", "frames", "out", "rig", "plugins", "layout", "input",
                            "isolation"},
     "decode --plugin P --method M --frames DIR --out DIR [--param k=v]... [--rig RIG.json] [--plugins DIR]...\n"
     "       [--layout procam|opencv-graycode|gupta-pairs|FILE.json] [--input NAME=FILE]...\n"
     "                                offline: decode a scan's saved frames (frame-r<round>-<i>.png), or\n"
     "                                image files sorted by name in plan order (later rounds in roundN/),\n"
     "                                or in another layout (--layout; missing white/black synthesized);\n"
     "                                --input gives the method's input NAME a float map FILE the way scans\n"
     "                                store them: 1-channel float OpenEXR (e.g. a scan's depth_mm.exr; float\n"
     "                                TIFF/PFM also read), camera-sized, NaN = invalid;\n"
     "                                --isolation process (default: the plugin runs in a worker process, as\n"
     "                                in procamd) or in_process (no worker: a little faster, a crash ends procam)"},
    {"bench", cmd_bench, {"rig", "scenes", "scene", "method", "param", "out", "keep", "plugins", "threads", "only-listed"},
     "bench --out DIR [--scene NAME|FILE]... [--method M]... [--rig RIG.json] [--threads N] [--only-listed 1]\n"
     "      [--param METHOD.key=value]... [--keep DIR]   (keep: write every run's outputs + outputs.json)\n"
     "                                offline: every method on every sim scene; speed-vs-error table + plot"},
    {"sim", cmd_sim, {"scene", "pattern", "out", "rig", "list", "frames", "components"},
     "sim --scene S --pattern white|black|gray:BIT[:inv]|checker:SIZE:DX:DY|FILE --out DIR [--rig RIG.json] [--frames N] [--components 1]\n"
     "                                offline: render a sim scene with ground truth and direct/global split\n"
     "                                (--components 1: one image per transport path);\n"
     "                                sim --list scenes; sim --scene S --pattern gray-errors (per-bit errors)"},
    {"calibrate", cmd_calibrate, {"endpoint", "timeout", "scene", "reference", "out", "force", "param", "label"},
     "calibrate PLUGIN/METHOD --out FILE [--scene S] [--reference structured-light/gray] [--param k=v]...\n"
     "          [--force 1]\n"
     "                                scan a plane with the reference method, run PLUGIN/METHOD with its depth_mm\n"
     "                                as input, write the method's calibration_table to FILE (not over an existing\n"
     "                                file without --force 1) and print the rig-config line (docs/calibration.md)"},
    {"cancel", cmd_cancel, {"endpoint", "timeout", "scan"},
     "cancel --scan ID                cancel a queued or running scan"},
    {"ping", cmd_ping, {"endpoint", "timeout"},
     "ping                            is procamd alive? (answers at once even while scanning)"},
    {"calibrate-latency", cmd_calibrate_latency, {"rig", "cycles", "write"},
     "calibrate-latency --rig RIG.json [--cycles N] [--write 1]\n"
     "                                offline (stop procamd): measure display/camera latency; --write stores it in the rig config"},
    {"calibrate-geometry", cmd_calibrate_geometry,
     {"captures", "projector", "board", "square-mm", "layout", "out", "force", "plugins", "scans", "label",
      "endpoint", "timeout"},
     "calibrate-geometry --captures DIR... --projector WxH --board COLSxROWS --square-mm S --out RIG.json\n"
     "       (ChArUco: --board charuco:SXxSY:SQUARE_MM:MARKER_MM:DICT, e.g. charuco:5x7:40:30:DICT_5X5_100)\n"
     "       [--layout procam|opencv-graycode|gupta-pairs|FILE.json] [--force 1]\n"
     "                                offline: camera + projector intrinsics with distortion and cam_from_proj\n"
     "                                from board poses under Gray codes with rows (one folder per pose)\n"
     "calibrate-geometry --scans ID[,ID...] --board COLSxROWS --square-mm S --out RIG.json [--label TEXT]\n"
     "                                through procamd: from finished pose scans (scan --plugin structured-light\n"
     "                                --method gray --param rows=true --save-frames 1, one per board pose)"},
    {"keygen", cmd_keygen, {"out"},
     "keygen --out NAME               new CURVE key pair: NAME.pub, NAME.secret (README \"Remote access\")"},
};

void print_usage(FILE* f) {
  std::fprintf(f, "usage: procam <command> [options]   (--json: raw JSON output)\n\n");
  for (const auto& c : kCommands) std::fprintf(f, "  %s\n", c.usage);
  std::fprintf(f, "\nremote commands take --endpoint E (default $PROCAM_ENDPOINT or tcp://127.0.0.1:5560)\n"
                  "and --timeout SECONDS; see README.md and proto/PROTOCOL.md.\n");
}

}  // namespace

int main(int argc, char** argv) {
  procam::log::configure("warn");
  if (argc < 2) {
    print_usage(stderr);
    return 2;
  }
  Args a;
  a.cmd = argv[1];
  if (a.cmd == "-h" || a.cmd == "--help" || a.cmd == "help") {
    print_usage(stdout);
    return 0;
  }
  auto cmd = std::find_if(kCommands.begin(), kCommands.end(), [&](const Command& c) { return a.cmd == c.name; });
  if (cmd == kCommands.end()) return usage_error("unknown command '" + a.cmd + "'");
  for (int i = 2; i < argc; ++i) {
    std::string s = argv[i];
    if (s == "--json") { a.json = true; continue; }
    if (s == "-h" || s == "--help") { std::printf("usage: procam %s\n", cmd->usage); return 0; }
    if (s.rfind("--", 0) != 0) {
      // Only `calibrate` takes one bare argument (its PLUGIN/METHOD).
      if (a.cmd != "calibrate" || !a.positional.empty()) return usage_error("unexpected argument '" + s + "'");
      a.positional = s;
      continue;
    }
    std::string k = s.substr(2), v;
    if (auto eq = k.find('='); eq != std::string::npos) {
      v = k.substr(eq + 1);
      k = k.substr(0, eq);
    } else {
      if (i + 1 >= argc) return usage_error("--" + k + " needs a value");
      v = argv[++i];
    }
    if (std::find(cmd->options.begin(), cmd->options.end(), k) == cmd->options.end())
      return usage_error("'" + a.cmd + "' has no option --" + k);
    a.opt[k] = v;
    a.all[k].push_back(v);
  }
  return cmd->run(a);
}
