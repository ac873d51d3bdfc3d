// SPDX-License-Identifier: MIT
// `procam`: command-line client for procamd, and offline decoding of saved frames.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "procam/client/client.hpp"
#include "procam/core/log.hpp"
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

namespace {
namespace fs = std::filesystem;
using namespace procam;

const char* kUsage = R"(usage: procam <command> [options]

commands (talk to a running procamd; --endpoint E, default $PROCAM_ENDPOINT or tcp://127.0.0.1:5560):
  plugins                         list decoder plugins, their methods and parameters
  rig                             describe the active rig (hardware, calibration, state)
  status [--scan ID]              daemon status, or one scan's state and progress
  scan --plugin P --method M      run a scan and download its results into --out DIR
       [--param k=v]... [--rig-option k=v]... [--label L] --out DIR
  result --scan ID --out DIR      download a finished scan's results

offline (no daemon):
  decode --plugin P --method M --frames DIR --out DIR
       [--param k=v]... [--rig RIG.json] [--plugins DIR]...
       decode a folder of captured images, sorted by file name in plan order
       (see plugins/<plugin>/README.md for the order)

common: --json prints raw JSON replies; -h/--help.
)";

struct Args {
  std::string cmd;
  std::map<std::string, std::string> opt;
  std::vector<std::string> params, rig_options, plugin_dirs;
  bool json = false;
};

int usage_error(const std::string& msg) {
  std::fprintf(stderr, "procam: %s\n\n%s", msg.c_str(), kUsage);
  return 2;
}

int report(const Status& s) {
  std::fprintf(stderr, "procam: error: %s\n", s.message().c_str());
  if (!s.hint().empty()) std::fprintf(stderr, "        hint: %s\n", s.hint().c_str());
  std::fprintf(stderr, "        (code %s)\n", code_name(s.code()));
  return 1;
}

// "k=v": v parsed as JSON when it is JSON (numbers, true/false, arrays,
// quoted strings), otherwise taken as a plain string.
Result<nlohmann::json> kv_object(const std::vector<std::string>& items, const char* what) {
  nlohmann::json o = nlohmann::json::object();
  for (const auto& it : items) {
    auto eq = it.find('=');
    if (eq == std::string::npos || eq == 0)
      return Error(Code::invalid_argument, std::string(what) + " '" + it + "' is not key=value");
    const std::string k = it.substr(0, eq), v = it.substr(eq + 1);
    try {
      o[k] = nlohmann::json::parse(v);
    } catch (const std::exception&) {
      o[k] = v;
    }
  }
  return o;
}

std::string fmt_pct(const nlohmann::json& j, const char* k) {
  if (!j.contains(k) || !j[k].is_number()) return "n/a";
  char b[32];
  std::snprintf(b, sizeof b, "%.2f%%", j[k].get<double>() * 100.0);
  return b;
}
std::string fmt_num(const nlohmann::json& j, const char* k, const char* unit, int prec = 2) {
  if (!j.contains(k) || !j[k].is_number()) return "n/a";
  char b[48];
  std::snprintf(b, sizeof b, "%.*f %s", prec, j[k].get<double>(), unit);
  return b;
}

// The short summary `make demo` prints: method, patterns, decode time, accuracy.
void print_summary(const nlohmann::json& m, const std::string& out_dir) {
  std::printf("\n== scan %s: %s ==\n", m.value("scan_id", "").c_str(), m.value("state", "").c_str());
  std::printf("  method        %s / %s\n", m.value("plugin", "").c_str(), m.value("method", "").c_str());
  if (m.contains("rig")) {
    const auto& st = m["rig"].value("state", nlohmann::json::object());
    std::printf("  rig           %s%s\n", m["rig"].value("name", "").c_str(),
                st.contains("scene") ? (", scene " + st["scene"].get<std::string>()).c_str() : "");
  }
  const auto& plan = m.value("plan", nlohmann::json::object());
  std::printf("  patterns      %d in %zu round(s)\n", plan.value("patterns", 0),
              plan.value("rounds", nlohmann::json::array()).size());
  for (const auto& o : m.value("outputs", nlohmann::json::array()))
    if (o.value("name", "") == "report" && o["value"].is_object()) {
      const auto& r = o["value"];
      if (r.contains("model")) std::printf("  model         %s\n", r["model"].get<std::string>().c_str());
      if (r.contains("why")) {  // first sentence; the manifest has the rest
        std::string why = r["why"].get<std::string>();
        if (auto dot = why.find(". "); dot != std::string::npos) why = why.substr(0, dot + 1);
        std::printf("  why           %s\n", why.c_str());
      }
    }
  const auto& t = m.value("timing_ms", nlohmann::json::object());
  std::printf("  decode time   %s (capture %s, write %s)\n", fmt_num(t, "decode", "ms", 1).c_str(),
              fmt_num(t, "capture", "ms", 1).c_str(), fmt_num(t, "write", "ms", 1).c_str());
  if (m.contains("evaluation")) {
    const auto& e = m["evaluation"];
    std::printf("  accuracy vs ground truth (%d lit pixels):\n", e.value("lit_pixels", 0));
    std::printf("    within 1 projector column  %s of lit pixels\n", fmt_pct(e, "within_1col_fraction").c_str());
    std::printf("    decoded                    %s of lit pixels\n", fmt_pct(e, "decoded_fraction").c_str());
    std::printf("    gross errors (>1 column)   %s of decoded\n", fmt_pct(e, "gross_error_fraction").c_str());
    std::printf("    column RMS                 %s\n", fmt_num(e, "col_rms_px", "px", 3).c_str());
    std::printf("    depth RMS / median |err|   %s / %s\n", fmt_num(e, "depth_rms_mm", "mm", 3).c_str(),
                fmt_num(e, "depth_median_abs_mm", "mm", 3).c_str());
  }
  if (m.contains("error") && !m["error"].is_null())
    std::printf("  error         %s: %s\n", m["error"].value("code", "").c_str(),
                m["error"].value("message", "").c_str());
  if (!out_dir.empty()) {
    std::printf("  results in    %s/\n", out_dir.c_str());
    for (const auto& p : m.value("previews", nlohmann::json::array()))
      std::printf("    preview     %s\n", p.value("file", "").c_str());
  }
}

// Progress on stderr: a redrawn bar on a terminal; on a pipe or log file, one
// line per stage change and per quarter of a stage, so logs stay readable.
void progress_line(const proto::Event& ev) {
  static const bool tty = ::isatty(2) != 0;
  static std::string last_key;
  if (ev.event == "progress" && !tty) {
    const auto total = ev.body.value("total", 0), done = ev.body.value("done", 0);
    const int quarter = total > 0 ? done * 4 / total : 0;
    const std::string key = ev.body.value("stage", "") + std::to_string(ev.body.value("round", 1)) + "/" +
                            std::to_string(quarter);
    if (key == last_key) return;
    last_key = key;
    std::fprintf(stderr, "  %-8s round %d  %d/%d %s\n", ev.body.value("stage", "").c_str(),
                 ev.body.value("round", 1), done, total, ev.body.value("message", "").c_str());
    return;
  }
  if (ev.event == "state" && !tty) {
    std::fprintf(stderr, "  state: %s\n", ev.body.value("state", "").c_str());
    return;
  }
  if (ev.event == "progress") {
    const auto total = ev.body.value("total", 0), done = ev.body.value("done", 0);
    const std::string stage = ev.body.value("stage", "");
    const int width = 30;
    const int fill = total > 0 ? done * width / total : 0;
    std::fprintf(stderr, "\r  %-8s round %d [%s%s] %3d/%-3d %-28.28s", stage.c_str(), ev.body.value("round", 1),
                 std::string(static_cast<size_t>(fill), '#').c_str(),
                 std::string(static_cast<size_t>(width - fill), '.').c_str(), done, total,
                 ev.body.value("message", "").c_str());
  } else if (ev.event == "state") {
    std::fprintf(stderr, "\r  state: %-60s\n", ev.body.value("state", "").c_str());
  }
  std::fflush(stderr);
}

int cmd_plugins(client::Client& c, const Args& a) {
  auto r = c.call(proto::ListPlugins{});
  if (!r) return report(r.status());
  if (a.json) { std::cout << r->dump(2) << "\n"; return 0; }
  for (const auto& p : (*r)["plugins"]) {
    std::printf("%s %s  (%s)\n", p.value("name", "").c_str(), p.value("version", "").c_str(), p.value("file", "").c_str());
    for (const auto& m : p["methods"]) {
      std::printf("  %-12s %s\n", m.value("name", "").c_str(), m.value("description", "").c_str());
      for (const auto& prm : m.value("params", nlohmann::json::array()))
        std::printf("      --param %s=<%s>  default %s  %s\n", prm.value("name", "").c_str(),
                    prm.value("type", "").c_str(), prm.contains("default") ? prm["default"].dump().c_str() : "-",
                    prm.value("description", "").c_str());
    }
  }
  for (const auto& rj : (*r)["rejected"])
    std::printf("rejected %s: %s\n", rj.value("file", "").c_str(), rj["error"].value("message", "").c_str());
  return 0;
}

int cmd_rig(client::Client& c, const Args& a) {
  auto r = c.call(proto::DescribeRig{});
  if (!r) return report(r.status());
  const auto& rig = (*r)["rig"];
  if (a.json) { std::cout << rig.dump(2) << "\n"; return 0; }
  std::printf("rig %s\n", rig.value("name", "").c_str());
  const auto& p = rig.value("projector", nlohmann::json::object());
  std::printf("  projector  %s %s %dx%d\n", p.value("backend", "").c_str(), p.value("name", "").c_str(),
              p.value("width", 0), p.value("height", 0));
  int i = 0;
  for (const auto& cam : rig.value("cameras", nlohmann::json::array())) {
    std::printf("  camera %d   %s %s %dx%d %d-bit\n", i++, cam.value("backend", "").c_str(),
                cam.value("id", "").c_str(), cam.value("width", 0), cam.value("height", 0), cam.value("bit_depth", 0));
    if (cam.contains("calibration")) std::printf("             calibration %s\n", cam["calibration"].dump().c_str());
  }
  if (rig.contains("state")) std::printf("  state      %s\n", rig["state"].dump().c_str());
  return 0;
}

int cmd_status(client::Client& c, const Args& a) {
  proto::StatusQuery q;
  if (a.opt.count("scan")) q.scan_id = a.opt.at("scan");
  auto r = c.call(q);
  if (!r) return report(r.status());
  if (a.json || q.scan_id) { std::cout << r->dump(2) << "\n"; return 0; }
  const auto& d = (*r)["daemon"];
  std::printf("%s  up %.0f s  %s  rig %s  plugins %d\n", d.value("version", "").c_str(), d.value("uptime_s", 0.0),
              d.value("state", "").c_str(), d.value("rig", "").c_str(), d.value("plugins", 0));
  const auto& s = d["scans"];
  std::printf("scans: %d done, %d failed, %d queued\n", s.value("done", 0), s.value("failed", 0), s.value("queued", 0));
  if (d.contains("current")) std::printf("current: %s\n", d["current"].dump().c_str());
  return 0;
}

int cmd_scan(client::Client& c, const Args& a) {
  if (!a.opt.count("plugin") || !a.opt.count("method")) return usage_error("scan needs --plugin and --method");
  if (!a.opt.count("out")) return usage_error("scan needs --out DIR for the results");
  auto params = kv_object(a.params, "--param");
  if (!params) return report(params.status());
  auto ropts = kv_object(a.rig_options, "--rig-option");
  if (!ropts) return report(ropts.status());
  proto::Scan s;
  s.plugin = a.opt.at("plugin");
  s.method = a.opt.at("method");
  s.params = *params;
  s.rig_options = *ropts;
  s.label = a.opt.count("label") ? a.opt.at("label") : "";
  std::fprintf(stderr, "scanning with %s/%s on %s\n", s.plugin.c_str(), s.method.c_str(), c.endpoint().c_str());
  auto fin = c.scan(s, progress_line);
  if (!fin) return report(fin.status());
  const std::string id = fin->value("scan_id", "");
  auto m = c.fetch_all(id, a.opt.at("out"));
  if (!m) return report(m.status().with_context("downloading results"));
  if (a.json) std::cout << m->dump(2) << "\n";
  else print_summary(*m, a.opt.at("out"));
  return m->value("state", "") == "done" ? 0 : 1;
}

int cmd_result(client::Client& c, const Args& a) {
  if (!a.opt.count("scan") || !a.opt.count("out")) return usage_error("result needs --scan ID and --out DIR");
  auto m = c.fetch_all(a.opt.at("scan"), a.opt.at("out"));
  if (!m) return report(m.status());
  if (a.json) std::cout << m->dump(2) << "\n";
  else print_summary(*m, a.opt.at("out"));
  return 0;
}

std::vector<std::string> split_colon(const std::string& s) {
  std::vector<std::string> out;
  size_t pos = 0;
  while (pos <= s.size()) {
    size_t e = s.find(':', pos);
    if (e == std::string::npos) e = s.size();
    if (e > pos) out.push_back(s.substr(pos, e - pos));
    pos = e + 1;
  }
  return out;
}

int cmd_decode(const Args& a) {
  for (const char* k : {"plugin", "method", "frames", "out"})
    if (!a.opt.count(k)) return usage_error(std::string("decode needs --") + k);
  auto params = kv_object(a.params, "--param");
  if (!params) return report(params.status());
  const std::string rig_path = a.opt.count("rig") ? a.opt.at("rig") : PROCAM_DEFAULT_RIG;
  auto rig_cfg = engine::read_json_file(rig_path);
  if (!rig_cfg) return report(rig_cfg.status().with_context("--rig"));
  auto rig_json = engine::plugin_rig_json_from_config(*rig_cfg, std::max(1u, std::thread::hardware_concurrency()));
  if (!rig_json) return report(rig_json.status());
  std::vector<std::string> dirs = a.plugin_dirs;
  if (const char* env = std::getenv("PROCAM_PLUGIN_PATH"))
    for (auto& p : split_colon(env)) dirs.push_back(p);
  if (dirs.empty()) dirs = split_colon(PROCAM_DEFAULT_PLUGIN_DIRS);
  host::PluginHost host;
  host.load_directories(dirs);
  auto session = host.create_session(a.opt.at("plugin"), a.opt.at("method"), params->dump(), rig_json->dump());
  if (!session) return report(session.status());
  auto t0 = std::chrono::steady_clock::now();
  auto outcome = engine::run_offline(*session, a.opt.at("frames"), [](const engine::Progress& p) {
    std::fprintf(stderr, "\r  decode round %d %zu/%zu %-24.24s", p.round, p.done, p.total, p.message.c_str());
  });
  std::fprintf(stderr, "\n");
  if (!outcome) return report(outcome.status());
  auto outs = session->outputs();
  if (!outs) return report(outs.status());
  const std::string out = a.opt.at("out");
  auto written = engine::write_outputs(out, *outs);
  if (!written) return report(written.status());
  nlohmann::json rounds = nlohmann::json::array();
  for (const auto& r : outcome->rounds) rounds.push_back({{"note", r.note}, {"frames", r.frames}});
  nlohmann::json m = {{"procam", 1}, {"scan_id", "offline"}, {"state", "done"}, {"plugin", a.opt.at("plugin")},
                      {"method", a.opt.at("method")}, {"params", *params}, {"frames_dir", a.opt.at("frames")},
                      {"created_utc", engine::utc_now()}, {"finished_utc", engine::utc_now()},
                      {"plan", {{"rounds", rounds}, {"patterns", outcome->patterns}}},
                      {"timing_ms", {{"decode", outcome->decode_ms},
                                     {"total", std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count()}}},
                      {"outputs", written->outputs}, {"previews", written->previews}, {"error", nullptr}};
  m["files"] = engine::list_files(out);
  if (auto s = engine::write_file_atomic((fs::path(out) / "manifest.json").string(), m.dump(2)); !s) return report(s);
  if (a.json) std::cout << m.dump(2) << "\n";
  else print_summary(m, out);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  procam::log::configure("warn");
  if (argc < 2) { std::fputs(kUsage, stderr); return 2; }
  Args a;
  a.cmd = argv[1];
  if (a.cmd == "-h" || a.cmd == "--help" || a.cmd == "help") { std::fputs(kUsage, stdout); return 0; }
  static const std::vector<std::string> valued = {"endpoint", "plugin", "method", "out", "scan", "label",
                                                  "frames", "rig", "timeout"};
  for (int i = 2; i < argc; ++i) {
    std::string s = argv[i];
    if (s == "--json") { a.json = true; continue; }
    if (s == "-h" || s == "--help") { std::fputs(kUsage, stdout); return 0; }
    if (s.rfind("--", 0) != 0) return usage_error("unexpected argument '" + s + "'");
    std::string k = s.substr(2), v;
    auto eq = k.find('=');
    if (eq != std::string::npos) { v = k.substr(eq + 1); k = k.substr(0, eq); }
    else {
      if (i + 1 >= argc) return usage_error("--" + k + " needs a value");
      v = argv[++i];
    }
    if (k == "param") a.params.push_back(v);
    else if (k == "rig-option") a.rig_options.push_back(v);
    else if (k == "plugins") a.plugin_dirs.push_back(v);
    else if (std::find(valued.begin(), valued.end(), k) != valued.end()) a.opt[k] = v;
    else return usage_error("unknown option --" + k);
  }
  if (a.cmd == "decode") return cmd_decode(a);
  const std::string ep = a.opt.count("endpoint") ? a.opt.at("endpoint") : procam::client::default_endpoint();
  long timeout_ms = 10000;
  if (a.opt.count("timeout")) timeout_ms = std::stol(a.opt.at("timeout")) * 1000;
  procam::client::Client c(ep, std::chrono::milliseconds(timeout_ms));
  if (a.cmd == "plugins") return cmd_plugins(c, a);
  if (a.cmd == "rig") return cmd_rig(c, a);
  if (a.cmd == "status") return cmd_status(c, a);
  if (a.cmd == "scan") return cmd_scan(c, a);
  if (a.cmd == "result") return cmd_result(c, a);
  return usage_error("unknown command '" + a.cmd + "'");
}
