// SPDX-License-Identifier: MIT
// procamd service benchmark (issue 6), against a real daemon process:
//  1. status round trip on loopback TCP while full-size scans run (p50/p99;
//     goal p99 <= 2 ms), also ping;
//  2. RSS of the daemon over many small simulated scans (the curve, every
//     --every scans), with retention off (every record kept) by default.
// usage: procam_service_bench [--scans 1000] [--every 100] [--status-samples 20000]
//                             [--max-scans-kept N] [--port 5590] [--json FILE]
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/client/client.hpp"
#include "core/testing/child_process.hpp"  // hw/core/testing: fork/exec/stop/reap

namespace {
namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Proc {
  pid_t pid = -1;
  ~Proc() { stop(); }
  void start(const std::vector<std::string>& argv, const std::string& log) {
    pid = procam::testing::spawn_logged(argv, log);
  }
  void stop() {
    if (pid > 0) {
      procam::testing::stop_child(pid);
      pid = -1;
    }
  }
  long rss_kb() const {
    std::ifstream in("/proc/" + std::to_string(pid) + "/status");
    std::string line;
    while (std::getline(in, line))
      if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    return -1;
  }
};

json rig(bool tiny) {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/sim.json");
  json r = json::parse(in);
  if (!tiny) return r;
  auto shrink = [](json& i) {
    i["width"] = 128;
    i["height"] = 80;
    i["fx"] = i["fx"].get<double>() / 10.0;
    i["fy"] = i["fy"].get<double>() / 10.0;
    i["cx"] = 63.5;
    i["cy"] = 39.5;
  };
  shrink(r["projector"]["intrinsics"]);
  for (auto& c : r["cameras"]) shrink(c["intrinsics"]);
  return r;
}

std::string start_daemon(Proc& p, const fs::path& dir, bool tiny, const std::string& endpoint, size_t keep) {
  json cfg = {{"rig", rig(tiny)}, {"scene_dirs", {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"}},
              {"plugin_paths", {std::string(PROCAM_PLUGIN_DIR)}}, {"endpoint", endpoint},
              {"results_dir", (dir / "results").string()}, {"log", "warn"}, {"max_queue", 64}};
  if (keep) cfg["retention"] = {{"max_scans", keep}};
  std::ofstream(dir / "cfg.json") << cfg.dump();
  p.start({std::string(PROCAM_BINARY_DIR) + "/bin/procamd", "--config", (dir / "cfg.json").string()},
          (dir / "procamd.log").string());
  for (int i = 0; i < 100; ++i) {
    procam::client::Client c(endpoint, std::chrono::milliseconds(300));
    if (c.call(procam::proto::Ping{}).ok()) return "";
  }
  return "daemon did not start; see " + (dir / "procamd.log").string();
}

double pct(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p / 100.0 * static_cast<double>(v.size())))];
}

procam::proto::Scan scan_req(const std::string& scene) {
  procam::proto::Scan s;
  s.plugin = "structured-light";
  s.method = "gray";
  s.rig_options = {{"scene", scene}};
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  size_t scans = 1000, every = 100, samples = 20000, keep = 0;
  int port = 5590;
  std::string json_out;
  for (int i = 1; i + 1 < argc; i += 2) {
    std::string k = argv[i], v = argv[i + 1];
    if (k == "--scans") scans = std::stoul(v);
    else if (k == "--every") every = std::max<size_t>(1, std::stoul(v));
    else if (k == "--status-samples") samples = std::stoul(v);
    else if (k == "--max-scans-kept") keep = std::stoul(v);
    else if (k == "--port") port = std::stoi(v);
    else if (k == "--json") json_out = v;
    else { std::fprintf(stderr, "unknown option %s\n", k.c_str()); return 2; }
  }
  const fs::path dir = fs::temp_directory_path() / ("procam-service-bench-" + std::to_string(getpid()));
  fs::create_directories(dir / "a");
  fs::create_directories(dir / "b");
  json report;

  // 1. Status round trip on loopback TCP while full-size scans run.
  {
    Proc p;
    const std::string ep = "tcp://127.0.0.1:" + std::to_string(port);
    if (auto e = start_daemon(p, dir / "a", false, ep, 0); !e.empty()) { std::fprintf(stderr, "%s\n", e.c_str()); return 1; }
    procam::client::Client c(ep, std::chrono::seconds(10));
    std::vector<double> status_ms, ping_ms;
    size_t queued = 0, scanning_samples = 0;
    const auto t0 = Clock::now();
    while (status_ms.size() < samples && Clock::now() - t0 < std::chrono::minutes(5)) {
      auto st = c.call(procam::proto::StatusQuery{});
      if (st && (*st)["daemon"]["scans"]["queued"].get<int>() < 2 && queued < 200) {
        if (c.call(scan_req(queued % 2 ? "tilted-box" : "plane")).ok()) ++queued;
      }
      auto ts = Clock::now();
      auto r = c.call(procam::proto::StatusQuery{});
      const double ms = std::chrono::duration<double, std::milli>(Clock::now() - ts).count();
      if (r && (*r)["daemon"]["state"] == "scanning") {
        status_ms.push_back(ms);
        ++scanning_samples;
      }
      ts = Clock::now();
      if (c.call(procam::proto::Ping{}).ok())
        ping_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - ts).count());
    }
    auto st = c.call(procam::proto::StatusQuery{});
    report["status_while_scanning"] = {
        {"samples", status_ms.size()}, {"p50_ms", pct(status_ms, 50)}, {"p90_ms", pct(status_ms, 90)},
        {"p99_ms", pct(status_ms, 99)}, {"max_ms", pct(status_ms, 100)}, {"ping_p50_ms", pct(ping_ms, 50)},
        {"ping_p99_ms", pct(ping_ms, 99)}, {"scans_queued", queued},
        {"scans_done", st ? (*st)["daemon"]["scans"]["done"] : json()}};
    std::printf("status while scanning (full-size sim rig, tcp loopback): n=%zu p50=%.3f ms p90=%.3f ms p99=%.3f ms "
                "max=%.3f ms; ping p50=%.3f p99=%.3f ms\n",
                status_ms.size(), pct(status_ms, 50), pct(status_ms, 90), pct(status_ms, 99), pct(status_ms, 100),
                pct(ping_ms, 50), pct(ping_ms, 99));
    std::fflush(stdout);
    p.stop();
  }

  // 2. RSS over many small scans.
  {
    Proc p;
    const std::string ep = "ipc://" + (dir / "b" / "sock").string();
    if (auto e = start_daemon(p, dir / "b", true, ep, keep); !e.empty()) { std::fprintf(stderr, "%s\n", e.c_str()); return 1; }
    procam::client::Client c(ep, std::chrono::seconds(30));
    json curve = json::array();
    curve.push_back({{"scans", 0}, {"rss_kb", p.rss_kb()}});
    std::printf("RSS after 0 scans: %ld kB\n", p.rss_kb());
    const auto t0 = Clock::now();
    size_t failed = 0;
    for (size_t i = 1; i <= scans; ++i) {
      auto fin = c.scan(scan_req(i % 2 ? "tilted-box" : "plane"), nullptr);
      if (!fin || (*fin)["state"] != "done") ++failed;
      if (i % every == 0) {
        const long rss = p.rss_kb();
        curve.push_back({{"scans", i}, {"rss_kb", rss}});
        std::printf("RSS after %zu scans: %ld kB (%.1f s)\n", i, rss,
                    std::chrono::duration<double>(Clock::now() - t0).count());
        std::fflush(stdout);
      }
    }
    report["rss_curve"] = curve;
    report["rss_scans_failed"] = failed;
    report["rss_retention_max_scans"] = keep;
    p.stop();
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
  if (!json_out.empty()) std::ofstream(json_out) << report.dump(2) << "\n";
  return 0;
}
