// SPDX-License-Identifier: MIT
// The procamd ZeroMQ server: a ROUTER socket answering proto/ requests, and
// forwarding scan events to clients that asked for them.
//
// Threads: run() owns the socket and runs on the calling (main) thread until
// a stop signal arrives on `stop_fd` (e.g. a signalfd for SIGTERM/SIGINT).
// Events come from the scan worker through notify_event(), which is
// thread-safe and never blocks. Any malformed request gets an error reply;
// nothing a client sends can stop the loop.
#pragma once

#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "procam/core/status.hpp"
#include "procam/engine/service.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::daemon {

class Server {
public:
  Server(engine::ScanService& service, const host::PluginHost& plugins);
  ~Server();

  // Binds `endpoint` (error names the endpoint, e.g. address in use).
  Status bind(const std::string& endpoint);
  // Serves until `stop_fd` is readable.
  void run(int stop_fd);
  // Thread-safe: queue an event for the scan's subscribers.
  void notify_event(const std::string& scan_id, const std::string& event, nlohmann::json fields);

private:
  using Envelope = std::vector<std::string>;
  void handle(std::vector<zmq::message_t>& msg);
  void reply(const Envelope& env, const std::string& body, const std::string* extra = nullptr);
  void drain_events();

  engine::ScanService& service_;
  const host::PluginHost& plugins_;
  zmq::context_t ctx_{1};
  zmq::socket_t router_;
  int event_fd_ = -1;
  std::mutex events_mu_;
  struct PendingEvent { std::string scan_id, event; nlohmann::json fields; };
  std::deque<PendingEvent> events_;
  std::map<std::string, std::vector<Envelope>> subscribers_;
  std::map<std::string, uint64_t> seq_;
};

}  // namespace procam::daemon
