// SPDX-License-Identifier: MIT
// CLI commands that talk to procamd: plugins, rig, status, scan, result.
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "cli.hpp"
#include "procam/engine/calibration_tables.hpp"

namespace procam::cli {

int cmd_plugins(const Args& a) {
  client::Client c = a.connect();
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
      // Scan inputs (PROTOCOL.md 5.4): what --input NAME=SCAN_ID[:OUTPUT] gives it.
      for (const auto& in : m.value("inputs", nlohmann::json::array()))
        std::printf("      --input %s=<scan id>  %s%s%s  %s%s\n", in.value("name", "").c_str(),
                    in.value("kind", "").c_str(), in.value("unit", "").empty() ? "" : ", ",
                    in.value("unit", "").c_str(), in.value("required", true) ? "" : "(optional) ",
                    in.value("description", "").c_str());
    }
  }
  for (const auto& rj : (*r)["rejected"])
    std::printf("rejected %s: %s\n", rj.value("file", "").c_str(), rj["error"].value("message", "").c_str());
  return 0;
}

int cmd_rig(const Args& a) {
  client::Client c = a.connect();
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
  // Calibration tables (docs/calibration.md): one line each.
  const auto& tables = rig.value("calibration_tables", nlohmann::json::object());
  if (tables.empty()) std::printf("  calibration tables: none\n");
  for (const auto& [name, table] : tables.items())
    std::printf("  table      %s\n", engine::describe_calibration_table(name, table).c_str());
  return 0;
}

int cmd_scans(const Args& a) {
  client::Client c = a.connect();
  proto::ListScans q;
  q.limit = 20;
  if (a.has("state")) q.state = a.get("state");
  if (a.has("limit")) {
    const std::string v = a.get("limit");
    char* end = nullptr;
    const unsigned long n = std::strtoul(v.c_str(), &end, 10);
    if (v.empty() || *end != '\0' || n < 1 || n > proto::kMaxListScans)
      return report(Error(Code::invalid_argument, "--limit must be an integer 1.." + std::to_string(proto::kMaxListScans)));
    q.limit = static_cast<uint32_t>(n);
  }
  auto r = c.call(q);
  if (!r) return report(r.status());
  if (a.json) { std::cout << r->dump(2) << "\n"; return 0; }
  const auto& scans = (*r)["scans"];
  if (scans.empty()) std::printf("no scans%s\n", q.state ? (" in state " + *q.state).c_str() : "");
  for (const auto& s : scans) {
    std::printf("%-24s %-9s %s/%s", s.value("scan_id", "").c_str(), s.value("state", "").c_str(),
                s.value("plugin", "").c_str(), s.value("method", "").c_str());
    if (!s.value("label", "").empty()) std::printf("  \"%s\"", s.value("label", "").c_str());
    std::printf("  %s\n", s.value("created_utc", "").c_str());
  }
  if ((*r).value("truncated", false))
    std::printf("(%zu of %llu shown: --limit N for more)\n", scans.size(),
                static_cast<unsigned long long>((*r).value("total", uint64_t{0})));
  return 0;
}

int cmd_rig_options(const Args& a) {
  client::Client c = a.connect();
  auto r = c.call(proto::ListRigOptions{});
  if (!r) return report(r.status());
  if (a.json) { std::cout << r->dump(2) << "\n"; return 0; }
  const auto& opts = (*r)["options"];
  if (opts.empty()) std::printf("rig %s takes no rig_options\n", (*r).value("rig", "").c_str());
  for (const auto& [key, o] : opts.items()) {
    std::printf("%s (%s): %s", key.c_str(), o.value("type", "").c_str(), o.value("description", "").c_str());
    if (o.contains("default")) std::printf("; default %s", o["default"].dump().c_str());
    std::printf("\n");
    for (const auto& v : o.value("values", nlohmann::json::array()))
      std::printf("  %-28s %s\n", v.value("name", "").c_str(), v.value("description", "").c_str());
  }
  return 0;
}

int cmd_status(const Args& a) {
  client::Client c = a.connect();
  proto::StatusQuery q;
  if (a.has("scan")) q.scan_id = a.get("scan");
  auto r = c.call(q);
  if (!r) return report(r.status());
  if (a.json || q.scan_id) { std::cout << r->dump(2) << "\n"; return 0; }
  const auto& d = (*r)["daemon"];
  std::printf("%s  up %.0f s  %s  rig %s  plugins %d\n", d.value("version", "").c_str(), d.value("uptime_s", 0.0),
              d.value("state", "").c_str(), d.value("rig", "").c_str(), d.value("plugins", 0));
  const auto& s = d["scans"];
  std::printf("scans: %d done, %d failed, %d queued\n", s.value("done", 0), s.value("failed", 0), s.value("queued", 0));
  if (d.contains("current")) {
    const auto& cur = d["current"];
    const auto& pr = cur.value("progress", nlohmann::json());
    std::printf("current: %s  %s  %s/%s", cur.value("scan_id", "").c_str(), cur.value("state", "").c_str(),
                cur.value("plugin", "").c_str(), cur.value("method", "").c_str());
    if (pr.is_object())
      std::printf("  %s %d/%d", pr.value("stage", "").c_str(), pr.value("done", 0), pr.value("total", 0));
    std::printf("\n");
  }
  if (d.contains("metrics") && d["metrics"].is_object()) {  // daemons since issue 6
    const auto& m = d["metrics"];
    const auto& dm = m.value("decode_ms", nlohmann::json::object());
    std::printf("queue: %d of %d  rejected busy: %d  cancelled: %d\n", m.value("queue_depth", 0),
                m.value("queue_limit", 0), m.value("scans_rejected_busy", 0), m.value("scans_cancelled", 0));
    std::printf("frames: %llu captured, %llu dropped (re-captured)\n",
                static_cast<unsigned long long>(m.value("frames_captured", uint64_t{0})),
                static_cast<unsigned long long>(m.value("frames_dropped", uint64_t{0})));
    std::printf("decode ms: last %.1f  mean %.1f  max %.1f\n", dm.value("last", 0.0), dm.value("mean", 0.0),
                dm.value("max", 0.0));
    std::printf("requests: %llu (%llu bad)  stored scans: %d (%.1f MiB)  curve: %s\n",
                static_cast<unsigned long long>(m.value("requests", uint64_t{0})),
                static_cast<unsigned long long>(m.value("bad_requests", uint64_t{0})), m.value("scans_stored", 0),
                static_cast<double>(m.value("results_bytes", uint64_t{0})) / 1048576.0,
                m.value("curve", false) ? "on" : "off");
  }
  return 0;
}

int cmd_scan(const Args& a) {
  client::Client c = a.connect();
  if (!a.has("plugin") || !a.has("method")) return usage_error("scan needs --plugin and --method");
  if (!a.has("out")) return usage_error("scan needs --out DIR for the results");
  auto params = kv_object(a.list("param"), "--param");
  if (!params) return report(params.status());
  auto ropts = kv_object(a.list("rig-option"), "--rig-option");
  if (!ropts) return report(ropts.status());
  proto::Scan s;
  s.plugin = a.get("plugin");
  s.method = a.get("method");
  s.params = *params;
  s.rig_options = *ropts;
  s.label = a.has("label") ? a.get("label") : "";
  s.save_frames = a.has("save-frames") && a.get("save-frames") != "0";
  auto inputs = input_refs(a.list("input"));
  if (!inputs) return report(inputs.status());
  s.inputs = std::move(*inputs);
  std::fprintf(stderr, "scanning with %s/%s on %s\n", s.plugin.c_str(), s.method.c_str(), c.endpoint().c_str());
  auto fin = c.scan(s, progress_line);
  if (!fin) return report(fin.status());
  const std::string id = fin->value("scan_id", "");
  auto m = c.fetch_all(id, a.get("out"));
  if (!m) return report(m.status().with_context("downloading results"));
  if (a.json) std::cout << m->dump(2) << "\n";
  else print_summary(*m, a.get("out"));
  return m->value("state", "") == "done" ? 0 : 1;
}

int cmd_result(const Args& a) {
  client::Client c = a.connect();
  if (!a.has("scan") || !a.has("out")) return usage_error("result needs --scan ID and --out DIR");
  auto m = c.fetch_all(a.get("scan"), a.get("out"));
  if (!m) return report(m.status());
  if (a.json) std::cout << m->dump(2) << "\n";
  else print_summary(*m, a.get("out"));
  return 0;
}

}  // namespace procam::cli
