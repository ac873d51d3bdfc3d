// SPDX-License-Identifier: MIT
// The procamd ZeroMQ server: a ROUTER socket answering proto/ requests, and
// forwarding scan events to clients that asked for them.
//
// Threads: run() owns the socket and runs on the calling (main) thread until
// a stop signal arrives on `stop_fd` (e.g. a signalfd for SIGTERM/SIGINT).
// Events come from the scan worker through notify_event(), which is
// thread-safe and never blocks. Any malformed request gets an error reply;
// nothing a client sends can stop the loop.
//
// Security: with CURVE enabled (enable_curve, before bind) a ZAP handler
// thread answers libzmq's authentication requests on inproc://zeromq.zap.01:
// a client is let in only if its CURVE public key is in the authorized_keys
// file (re-read when the file changes). Everyone else never gets a session.
#pragma once

#include <atomic>
#include <chrono>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <zmq.hpp>
#include <zmq_addon.hpp>

#include "procam/core/status.hpp"
#include "procam/engine/service.hpp"
#include "procam/host/plugin_host.hpp"
#include "config.hpp"

namespace procam::daemon {

// Replies that may wait in one client's outgoing queue (ZMQ_SNDHWM). Fetch
// replies are at most 8 MiB, so one connection can hold at most ~128 MiB of
// daemon memory however many fetches it sends without reading them.
inline constexpr int kReplyQueueMessages = 16;
// Events that may wait for one client whose queue is full (see
// Server::send_event). Progress events of a scan coalesce to the newest, so
// this bounds a client that never reads, not a busy one.
inline constexpr size_t kEventBacklog = 256;
// The largest ZeroMQ message procamd receives at all (ZMQ_MAXMSGSIZE), to
// bound the memory one connection can make it buffer. A request body over
// the protocol limit (proto::kMaxRequestBytes, 1 MiB) and up to this size is
// read and answered `too_large` with its id; ZeroMQ drops a larger one
// before buffering it and closes that connection, which the socket monitor
// logs (Server::on_monitor_event).
inline constexpr int64_t kHardMessageBytes = int64_t{64} << 20;

class Server {
public:
  Server(engine::ScanService& service, const host::PluginHost& plugins);
  ~Server();

  // Makes the socket a CURVE server with an allowlist; call before bind().
  // Errors name the key file that is missing, unreadable or malformed.
  Status enable_curve(const CurveConfig& curve);
  // Binds `endpoint` (error names the endpoint, e.g. address in use).
  Status bind(const std::string& endpoint);
  // Serves until `stop_fd` is readable.
  void run(int stop_fd);
  // Thread-safe: queue an event for the scan's subscribers.
  void notify_event(const std::string& scan_id, const std::string& event, nlohmann::json fields);

private:
  using Envelope = std::vector<std::string>;
  void handle(std::vector<zmq::message_t>& msg);
  enum class Sent { yes, queue_full, client_gone };
  Sent try_send(const Envelope& env, const std::string& body, const std::string* extra);
  // A reply to a request: dropped (counted, logged) when the client's queue
  // is full; the client's own timeout then tells it.
  void reply(const Envelope& env, const std::string& body, const std::string* extra = nullptr);
  // An event: never dropped while the client is connected and reads at
  // all. When its queue is full the event waits in a per-client backlog that
  // the loop retries every few ms; a waiting progress event of the same scan
  // is replaced by the newer one, state and log events keep their order.
  void send_event(const Envelope& env, const std::string& scan_id, bool progress, const std::string& body);
  void flush_backlog();
  void note_dropped(const char* what);
  void drain_events();
  // Socket monitor (main thread): connections ZeroMQ ended (a client
  // leaving, or a message over kHardMessageBytes / a ZMTP error, which
  // ZeroMQ 4.3 reports the same way), counted and logged at most 10 lines a
  // minute; failed handshakes logged likewise.
  void drain_monitor();
  void on_monitor_event(uint16_t event, uint32_t value, const std::string& endpoint);
  void zap_loop();
  bool key_allowed(const std::string& key32);

  engine::ScanService& service_;
  const host::PluginHost& plugins_;
  zmq::context_t ctx_{1};
  zmq::socket_t router_;
  zmq::socket_t monitor_;  // PAIR on the router's monitor; closed before router_
  uint64_t connections_closed_ = 0;  // main thread only
  std::chrono::steady_clock::time_point monitor_window_{};
  unsigned monitor_logged_ = 0, monitor_quiet_ = 0;
  int event_fd_ = -1;
  std::mutex events_mu_;
  struct PendingEvent { std::string scan_id, event; nlohmann::json fields; };
  std::deque<PendingEvent> events_;
  std::map<std::string, std::vector<Envelope>> subscribers_;
  std::map<std::string, uint64_t> seq_;
  struct Backlogged { std::string scan_id; bool progress; std::string body; };
  std::map<Envelope, std::deque<Backlogged>> backlog_;  // main thread only
  uint64_t requests_ = 0, bad_requests_ = 0;  // main thread only
  // Replies (or events) not sent because the client's queue was full: it is
  // not reading what it asked for (see kReplyQueueMessages). Main thread only.
  uint64_t replies_dropped_ = 0;
  std::chrono::steady_clock::time_point dropped_window_{};
  uint64_t dropped_logged_ = 0;
  bool curve_ = false;
  // ZAP handler (CURVE only): its own thread and REP socket.
  std::string authorized_keys_path_;
  std::vector<std::string> authorized_;         // 32-byte binary public keys
  int64_t authorized_mtime_ = -1;
  std::atomic<bool> zap_stop_{false};
  std::chrono::steady_clock::time_point refused_window_{};  // ZAP thread only: log rate limit
  unsigned refused_logged_ = 0, refused_quiet_ = 0;
  std::thread zap_thread_;
};

// Reads a Z85 CURVE key (40 characters) from a file holding it as its first
// non-comment line. Errors name the file.
Result<std::string> read_z85_key_file(const std::string& path);

}  // namespace procam::daemon
