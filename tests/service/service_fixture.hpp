// SPDX-License-Identifier: MIT
// Test helpers for the service suite: daemon configs written into a private
// temp folder (tiny or default simulated rig, CURVE, retention, queue size),
// raw ZeroMQ sockets, latency percentiles.
#pragma once

#include <algorithm>
#include <chrono>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "../integration/daemon_process.hpp"

namespace procam::testing {

struct ConfigOptions {
  bool tiny_rig = true;            // 128x80 camera and projector: a scan takes milliseconds
  size_t max_queue = 16;
  nlohmann::json curve;            // null: off
  nlohmann::json retention;        // null: off
  nlohmann::json queued_scans;     // null: the daemon's default (run queued scans after a restart)
  nlohmann::json plugins;          // procamd.json "plugins" (isolation, timeouts); null: the defaults
  std::vector<std::string> plugin_paths;
};

// The default simulated rig (configs/rigs/sim.json), shrunk when tiny.
inline nlohmann::json rig_json(bool tiny) {
  std::ifstream in(source("configs/rigs/sim.json"));
  nlohmann::json rig = nlohmann::json::parse(in);
  if (!tiny) return rig;
  auto shrink = [](nlohmann::json& intr) {
    intr["width"] = 128;
    intr["height"] = 80;
    intr["fx"] = intr["fx"].get<double>() / 10.0;
    intr["fy"] = intr["fy"].get<double>() / 10.0;
    intr["cx"] = 63.5;
    intr["cy"] = 39.5;
  };
  shrink(rig["projector"]["intrinsics"]);
  for (auto& c : rig["cameras"]) shrink(c["intrinsics"]);
  rig["name"] = "sim-tiny";
  return rig;
}

inline std::string write_config(const fs::path& dir, const ConfigOptions& o) {
  nlohmann::json cfg = {{"rig", rig_json(o.tiny_rig)},
                        {"scene_dirs", {source("configs/scenes")}},
                        {"plugin_paths", o.plugin_paths},
                        {"results_dir", (dir / "results").string()},
                        {"log", "info"},
                        {"threads", 1},
                        {"max_queue", o.max_queue}};
  if (!o.curve.is_null()) cfg["curve"] = o.curve;
  if (!o.retention.is_null()) cfg["retention"] = o.retention;
  if (!o.queued_scans.is_null()) cfg["queued_scans"] = o.queued_scans;
  if (!o.plugins.is_null()) cfg["plugins"] = o.plugins;
  const std::string path = (dir / "procamd-test.json").string();
  std::ofstream(path) << cfg.dump(2);
  return path;
}

// A procamd on its own temp folder with a written config. Results live in
// `results_dir` (may be shared between restarts).
struct ServiceDaemon {
  TempDir cfgdir;
  std::unique_ptr<Daemon> d;
  std::string results;

  explicit ServiceDaemon(const ConfigOptions& o = {}, const std::string& results_dir = "") {
    const std::string cfg = write_config(cfgdir.path, o);
    std::vector<std::string> extra{"--config", cfg};
    if (!results_dir.empty()) {  // the last --results wins
      extra.push_back("--results");
      extra.push_back(results_dir);
    }
    d = std::make_unique<Daemon>(extra);
    results = results_dir.empty() ? d->results : results_dir;
  }
  const std::string& endpoint() const { return d->endpoint; }
};

inline proto::Scan tiny_scan(const std::string& scene = "plane", const std::string& label = "") {
  proto::Scan s;
  s.plugin = "structured-light";
  s.method = "gray";
  s.rig_options = {{"scene", scene}};
  s.label = label;
  return s;
}

// Polls status until the scan is final; returns its summary (null on timeout).
inline nlohmann::json wait_final(client::Client& c, const std::string& scan_id,
                                 std::chrono::seconds limit = std::chrono::seconds(120)) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < until) {
    auto st = c.call(proto::StatusQuery{scan_id});
    if (st) {
      const std::string s = (*st)["scan"].value("state", "");
      if (s == "done" || s == "failed") return (*st)["scan"];
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return nullptr;
}

inline double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(p / 100.0 * static_cast<double>(v.size())));
  return v[k];
}

// One raw DEALER exchange: sends [empty, frames...]; returns the reply body or "" on timeout.
inline std::string raw_exchange(zmq::socket_t& sock, const std::vector<std::string>& frames) {
  sock.send(zmq::message_t(), zmq::send_flags::sndmore);
  for (size_t i = 0; i < frames.size(); ++i)
    sock.send(zmq::buffer(frames[i]), i + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
  std::vector<zmq::message_t> msg;
  auto got = zmq::recv_multipart(sock, std::back_inserter(msg));
  if (!got || msg.size() < 2) return "";
  return msg[1].to_string();
}

}  // namespace procam::testing
