// SPDX-License-Identifier: MIT
// ROUTER request loop: decode → dispatch to ScanService → encode reply.
#include "server.hpp"

#include <sys/eventfd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <variant>

#include "procam/core/log.hpp"
#include "procam/proto/protocol.hpp"
#include <zmq_addon.hpp>

namespace procam::daemon {

namespace {
template <class... Ts> struct overloaded : Ts... { using Ts::operator()...; };
template <class... Ts> overloaded(Ts...) -> overloaded<Ts...>;
}  // namespace

Server::Server(engine::ScanService& service, const host::PluginHost& plugins)
    : service_(service), plugins_(plugins), router_(ctx_, zmq::socket_type::router) {
  event_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  router_.set(zmq::sockopt::linger, 200);
  // Drop anything absurdly large before it is buffered (the monitor below
  // logs the dropped connection); requests between 1 MiB and this are read
  // and get a too_large reply.
  router_.set(zmq::sockopt::maxmsgsize, kHardMessageBytes);
  // Outgoing memory per client is bounded: at most kReplyQueueMessages
  // replies wait in a client's queue (a fetch reply is <= 8 MiB, so <= 128 MiB
  // per connection). router_mandatory makes a full queue an EAGAIN we can
  // count and log instead of a silent drop inside libzmq.
  router_.set(zmq::sockopt::sndhwm, kReplyQueueMessages);
  router_.set(zmq::sockopt::router_mandatory, true);
  // Heartbeats let clients tell a dead daemon from a slow one.
  router_.set(zmq::sockopt::heartbeat_ivl, 2000);
  router_.set(zmq::sockopt::heartbeat_timeout, 6000);
  // Connections ZeroMQ closes, including those it drops for an oversized
  // message, are otherwise invisible: watch them through a socket monitor.
  static constexpr const char* kMonitor = "inproc://procamd-router-monitor";
  if (zmq_socket_monitor(router_.handle(), kMonitor,
                         ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL) == 0) {
    monitor_ = zmq::socket_t(ctx_, zmq::socket_type::pair);
    monitor_.set(zmq::sockopt::linger, 0);
    monitor_.connect(kMonitor);
  } else {
    PROCAM_LOG(daemon, warn) << "cannot monitor the request socket (" << zmq_strerror(zmq_errno())
                             << "): connections dropped for oversized messages will not be logged";
  }
}

Server::~Server() {
  zap_stop_ = true;
  if (zap_thread_.joinable()) zap_thread_.join();
  if (event_fd_ >= 0) ::close(event_fd_);
}

Result<std::string> read_z85_key_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error(Code::io_error, "cannot read key file '" + path + "'", "create one with `procam keygen`");
  std::string line;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
    size_t b = line.find_first_not_of(" \t");
    if (b == std::string::npos || line[b] == '#') continue;
    line = line.substr(b);
    if (line.size() != 40)
      return Error(Code::invalid_argument, "key file '" + path + "' does not hold a 40-character Z85 CURVE key",
                   "create one with `procam keygen`");
    return line;
  }
  return Error(Code::invalid_argument, "key file '" + path + "' is empty", "create one with `procam keygen`");
}

namespace {
int64_t mtime_ns(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return -1;
  return static_cast<int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
}
}  // namespace

Status Server::enable_curve(const CurveConfig& curve) {
  if (!zmq_has("curve"))
    return Error(Code::unavailable, "this libzmq was built without CURVE", "install Debian's libzmq5");
  auto secret = read_z85_key_file(curve.secret_key_file);
  if (!secret) return secret.status().with_context("curve.secret_key_file");
  struct stat st {};
  if (::stat(curve.secret_key_file.c_str(), &st) == 0 && (st.st_mode & (S_IRWXG | S_IRWXO)))
    PROCAM_LOG(daemon, warn) << "secret key file '" << curve.secret_key_file
                             << "' is readable by others; chmod 600 it";
  char pub[41] = {};
  if (zmq_curve_public(pub, secret->c_str()) != 0)
    return Error(Code::invalid_argument, "'" + curve.secret_key_file + "' is not a valid Z85 CURVE secret key",
                 "create one with `procam keygen`");
  authorized_keys_path_ = curve.authorized_keys;
  if (mtime_ns(authorized_keys_path_) < 0)
    return Error(Code::io_error, "cannot read curve.authorized_keys '" + authorized_keys_path_ + "'",
                 "create it: one client public key (procam keygen's .pub file content) per line");
  (void)key_allowed("");  // load now so errors show at start
  try {
    router_.set(zmq::sockopt::curve_server, 1);
    router_.set(zmq::sockopt::curve_secretkey, *secret);
    router_.set(zmq::sockopt::zap_domain, "procam");
  } catch (const zmq::error_t& e) {
    return Error(Code::internal, std::string("setting CURVE options: ") + e.what());
  }
  // The handler must be bound before any client connects.
  std::atomic<int> ready{0};
  zap_thread_ = std::thread([this, &ready] {
    zmq::socket_t zap(ctx_, zmq::socket_type::rep);
    try {
      zap.set(zmq::sockopt::linger, 0);
      zap.bind("inproc://zeromq.zap.01");
      ready = 1;
    } catch (const zmq::error_t& e) {
      PROCAM_LOG(daemon, error) << "ZAP handler: " << e.what();
      ready = -1;
      return;
    }
    while (!zap_stop_) {
      zmq::pollitem_t items[] = {{zap.handle(), 0, ZMQ_POLLIN, 0}};
      try {
        zmq::poll(items, 1, std::chrono::milliseconds(200));
        if (!(items[0].revents & ZMQ_POLLIN)) continue;
        std::vector<zmq::message_t> req;
        if (!zmq::recv_multipart(zap, std::back_inserter(req))) continue;
        // ZAP 1.0 (RFC 27): version, request id, domain, address, identity, mechanism, credentials...
        std::string version = req.size() > 0 ? req[0].to_string() : "";
        std::string request_id = req.size() > 1 ? req[1].to_string() : "";
        std::string address = req.size() > 3 ? req[3].to_string() : "?";
        std::string mechanism = req.size() > 5 ? req[5].to_string() : "";
        std::string key = req.size() > 6 ? req[6].to_string() : "";
        bool ok = version == "1.0" && mechanism == "CURVE" && key.size() == 32 && key_allowed(key);
        if (!ok) {
          // At most 20 lines a minute, so a flood of strangers cannot fill the disk.
          const auto now = std::chrono::steady_clock::now();
          if (now - refused_window_ > std::chrono::minutes(1)) {
            if (refused_quiet_ > 0)
              PROCAM_LOG(daemon, warn) << "refused " << refused_quiet_ << " more clients in the last minute (not logged)";
            refused_window_ = now;
            refused_logged_ = 0;
            refused_quiet_ = 0;
          }
          if (refused_logged_++ < 20) {
            char z85[41] = "-";
            if (key.size() == 32) zmq_z85_encode(z85, reinterpret_cast<const uint8_t*>(key.data()), 32);
            PROCAM_LOG(daemon, warn) << "refused " << (mechanism.empty() ? "?" : mechanism) << " client from "
                                     << address << " with key " << z85 << " (not in " << authorized_keys_path_
                                     << ")";
          } else {
            ++refused_quiet_;
          }
        } else {
          PROCAM_LOG(daemon, debug) << "accepted CURVE client from " << address;
        }
        std::array<std::string, 6> rep = {"1.0", request_id, ok ? "200" : "400",
                                          ok ? "OK" : "key not authorized", "", ""};
        for (size_t k = 0; k < rep.size(); ++k)
          zap.send(zmq::buffer(rep[k]), k + 1 < rep.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
      } catch (const zmq::error_t& e) {
        if (e.num() == ETERM) break;
        PROCAM_LOG(daemon, warn) << "ZAP handler: " << e.what();
      }
    }
  });
  while (ready == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  if (ready < 0) return Error(Code::internal, "cannot start the ZAP authentication handler");
  curve_ = true;
  PROCAM_LOG(daemon, info) << "CURVE on: server public key " << pub << ", clients from " << authorized_keys_path_;
  return Status::Ok();
}

// On the ZAP thread only. Re-reads the allowlist when its file changed.
bool Server::key_allowed(const std::string& key32) {
  const int64_t mt = mtime_ns(authorized_keys_path_);
  if (mt != authorized_mtime_) {
    authorized_mtime_ = mt;
    authorized_.clear();
    std::ifstream in(authorized_keys_path_);
    std::string line;
    size_t n = 0, bad = 0;
    while (std::getline(in, line)) {
      ++n;
      while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
      size_t b = line.find_first_not_of(" \t");
      if (b == std::string::npos || line[b] == '#') continue;
      std::string z = line.substr(b, 40);
      uint8_t bin[32];
      if (z.size() != 40 || !zmq_z85_decode(bin, z.c_str())) {
        ++bad;
        PROCAM_LOG(daemon, warn) << authorized_keys_path_ << ":" << n << ": not a Z85 public key; ignored";
        continue;
      }
      authorized_.emplace_back(reinterpret_cast<const char*>(bin), 32);
    }
    PROCAM_LOG(daemon, info) << "authorized keys: " << authorized_.size() << " from " << authorized_keys_path_
                             << (bad ? " (" + std::to_string(bad) + " bad lines)" : "");
  }
  return std::find(authorized_.begin(), authorized_.end(), key32) != authorized_.end();
}

Status Server::bind(const std::string& endpoint) {
  try {
    router_.bind(endpoint);
  } catch (const zmq::error_t& e) {
    return Error(Code::unavailable, "cannot listen on '" + endpoint + "': " + e.what(),
                 "is another procamd running? choose another endpoint with --endpoint");
  }
  PROCAM_LOG(daemon, info) << "listening on " << endpoint;
  return Status::Ok();
}

void Server::notify_event(const std::string& scan_id, const std::string& event, nlohmann::json fields) {
  {
    std::lock_guard lock(events_mu_);
    events_.push_back({scan_id, event, std::move(fields)});
  }
  uint64_t one = 1;
  [[maybe_unused]] auto n = ::write(event_fd_, &one, sizeof one);
}

void Server::drain_monitor() {
  for (int k = 0; k < 64; ++k) {
    // libzmq monitor events: [u16 event, u32 value] then the endpoint.
    std::vector<zmq::message_t> ev;
    try {
      if (!zmq::recv_multipart(monitor_, std::back_inserter(ev), zmq::recv_flags::dontwait)) return;
    } catch (const zmq::error_t&) {
      return;
    }
    if (ev.size() < 2 || ev[0].size() != 6) continue;
    uint16_t event = 0;
    uint32_t value = 0;
    std::memcpy(&event, ev[0].data(), 2);
    std::memcpy(&value, static_cast<const char*>(ev[0].data()) + 2, 4);
    on_monitor_event(event, value, ev[1].to_string());
  }
}

void Server::on_monitor_event(uint16_t event, uint32_t value, const std::string& endpoint) {
  if (event == ZMQ_EVENT_DISCONNECTED) ++connections_closed_;
  // At most 10 lines a minute, so a flood cannot fill the disk.
  const auto now = std::chrono::steady_clock::now();
  if (now - monitor_window_ > std::chrono::minutes(1)) {
    if (monitor_quiet_ > 0)
      PROCAM_LOG(daemon, info) << monitor_quiet_ << " more connections ended in the last minute (not logged)";
    monitor_window_ = now;
    monitor_logged_ = 0;
    monitor_quiet_ = 0;
  }
  if (monitor_logged_ >= 10) {
    ++monitor_quiet_;
    return;
  }
  ++monitor_logged_;
  if (event == ZMQ_EVENT_DISCONNECTED) {
    // ZeroMQ 4.3 reports a client that closed and a connection it dropped
    // (a message over the hard limit, a ZMTP error) as the same event.
    PROCAM_LOG(daemon, info) << "a client connection on " << endpoint << " ended (descriptor " << value
                             << "; " << connections_closed_ << " since start): the client closed it, or ZeroMQ "
                             << "dropped it for a message over the " << (kHardMessageBytes >> 20)
                             << " MiB hard limit or a ZMTP protocol error (proto/PROTOCOL.md section 12)";
  } else if (event == ZMQ_EVENT_HANDSHAKE_FAILED_PROTOCOL) {
    char code[16];
    std::snprintf(code, sizeof code, "0x%08x", value);
    PROCAM_LOG(daemon, warn) << "a client on " << endpoint << " failed the ZeroMQ handshake (ZMTP protocol error "
                             << code << "); is it speaking ZeroMQ (ZMTP 3)?";
  }
}

void Server::run(int stop_fd) {
  for (;;) {
    zmq::pollitem_t items[] = {{router_.handle(), 0, ZMQ_POLLIN, 0},
                               {nullptr, event_fd_, ZMQ_POLLIN, 0},
                               {nullptr, stop_fd, ZMQ_POLLIN, 0},
                               {monitor_.handle(), 0, ZMQ_POLLIN, 0}};
    try {
      // Events waiting for a slow client are retried every 5 ms.
      zmq::poll(items, monitor_ ? 4 : 3, std::chrono::milliseconds(backlog_.empty() ? -1 : 5));
    } catch (const zmq::error_t& e) {
      if (e.num() == EINTR) continue;
      PROCAM_LOG(daemon, error) << "poll failed: " << e.what();
      continue;
    }
    if (items[2].revents & ZMQ_POLLIN) {
      PROCAM_LOG(daemon, info) << "stop requested";
      drain_events();
      flush_backlog();
      return;
    }
    flush_backlog();
    if (monitor_ && (items[3].revents & ZMQ_POLLIN)) drain_monitor();
    if (items[1].revents & ZMQ_POLLIN) {
      uint64_t v;
      [[maybe_unused]] auto n = ::read(event_fd_, &v, sizeof v);
      drain_events();
    }
    if (items[0].revents & ZMQ_POLLIN) {
      // Drain everything that is ready so events cannot starve requests.
      for (int k = 0; k < 64; ++k) {
        std::vector<zmq::message_t> msg;
        zmq::recv_result_t r;
        try {
          r = zmq::recv_multipart(router_, std::back_inserter(msg), zmq::recv_flags::dontwait);
        } catch (const zmq::error_t& e) {
          PROCAM_LOG(daemon, warn) << "receive failed: " << e.what();
          break;
        }
        if (!r) break;
        handle(msg);
      }
    }
  }
}

Server::Sent Server::try_send(const Envelope& env, const std::string& body, const std::string* extra) {
  // Never block the loop on one client: a full queue is EAGAIN. The first
  // frame decides: once it is queued, ZeroMQ accepts the rest of the
  // multipart message atomically.
  const auto more = zmq::send_flags::sndmore | zmq::send_flags::dontwait;
  try {
    // env[0] is the routing id: it picks the client's queue and fails if full.
    if (env.empty()) return Sent::client_gone;
    if (!router_.send(zmq::buffer(env[0]), more).has_value()) {
      // The queue may only look full: the socket learns what the I/O thread
      // has already written to the client from commands it processes at
      // most every ~1 ms during sends (libzmq throttles them), so a fast
      // synchronous client can see its reply "dropped" with nothing queued.
      // ZMQ_EVENTS processes pending commands unthrottled; then try again.
      (void)router_.get(zmq::sockopt::events);
      if (!router_.send(zmq::buffer(env[0]), more).has_value()) return Sent::queue_full;
    }
    for (size_t k = 1; k < env.size(); ++k) router_.send(zmq::buffer(env[k]), more);
    router_.send(zmq::buffer(body), extra ? more : zmq::send_flags::dontwait);
    if (extra) router_.send(zmq::buffer(*extra), zmq::send_flags::dontwait);
    return Sent::yes;
  } catch (const zmq::error_t& e) {
    // EHOSTUNREACH: the client went away (router_mandatory reports it).
    PROCAM_LOG(daemon, debug) << "reply not sent: " << e.what();
    return Sent::client_gone;
  }
}

void Server::note_dropped(const char* what) {
  ++replies_dropped_;
  const auto now = std::chrono::steady_clock::now();
  if (now - dropped_window_ > std::chrono::minutes(1)) {
    dropped_window_ = now;
    dropped_logged_ = 0;
  }
  if (dropped_logged_++ < 10)
    PROCAM_LOG(daemon, warn) << "a client is not reading its replies: " << what << " was dropped ("
                             << replies_dropped_ << " dropped since start)";
}

void Server::reply(const Envelope& env, const std::string& body, const std::string* extra) {
  if (try_send(env, body, extra) == Sent::queue_full)
    note_dropped(("a reply (" + std::to_string(kReplyQueueMessages) + " waiting)").c_str());
}

void Server::send_event(const Envelope& env, const std::string& scan_id, bool progress, const std::string& body) {
  auto it = backlog_.find(env);
  if (it == backlog_.end()) {
    const Sent s = try_send(env, body, nullptr);
    if (s != Sent::queue_full) return;  // sent, or nobody to send to
    it = backlog_.emplace(env, std::deque<Backlogged>{}).first;
  }
  auto& q = it->second;
  if (progress && !q.empty() && q.back().progress && q.back().scan_id == scan_id) {
    q.back().body = body;  // only the newest progress matters
    return;
  }
  if (q.size() >= kEventBacklog) {
    note_dropped(("an event (" + std::to_string(kEventBacklog) + " waiting)").c_str());
    return;
  }
  q.push_back({scan_id, progress, body});
}

void Server::flush_backlog() {
  for (auto it = backlog_.begin(); it != backlog_.end();) {
    auto& q = it->second;
    while (!q.empty()) {
      const Sent s = try_send(it->first, q.front().body, nullptr);
      if (s == Sent::queue_full) break;
      if (s == Sent::client_gone) {
        q.clear();
        break;
      }
      q.pop_front();
    }
    it = q.empty() ? backlog_.erase(it) : std::next(it);
  }
}

void Server::drain_events() {
  std::deque<PendingEvent> batch;
  {
    std::lock_guard lock(events_mu_);
    batch.swap(events_);
  }
  for (auto& ev : batch) {
    const uint64_t seq = seq_[ev.scan_id]++;
    const bool final_state = ev.event == "state" &&
                             (ev.fields.value("state", "") == "done" || ev.fields.value("state", "") == "failed");
    auto it = subscribers_.find(ev.scan_id);
    if (it != subscribers_.end()) {
      const std::string body = proto::encode_event(ev.scan_id, seq, ev.event, ev.fields);
      for (const auto& env : it->second) send_event(env, ev.scan_id, ev.event == "progress", body);
      if (final_state) subscribers_.erase(it);
    }
    if (final_state) seq_.erase(ev.scan_id);
  }
}

void Server::handle(std::vector<zmq::message_t>& msg) {
  // Envelope: routing id, then everything up to and including the first empty
  // delimiter frame (REQ / REQ-style DEALER). Body: the rest; exactly one frame.
  Envelope env;
  size_t i = 0;
  if (msg.empty()) return;
  env.push_back(msg[0].to_string());
  for (i = 1; i < msg.size(); ++i) {
    const bool empty = msg[i].size() == 0;
    if (empty) {
      env.emplace_back();
      ++i;
      break;
    }
    if (i == 1) break;  // DEALER without delimiter: body starts here
  }
  if (msg.size() - i != 1) {
    ++requests_;
    ++bad_requests_;
    reply(env, proto::encode_error(std::nullopt, Error(Code::bad_message,
        "expected exactly one JSON frame after the envelope, got " + std::to_string(msg.size() - i),
        "send one frame holding a JSON object (see proto/PROTOCOL.md)")));
    PROCAM_LOG(daemon, warn) << "bad frame count from client";
    return;
  }
  const std::string_view bytes(static_cast<const char*>(msg[i].data()), msg[i].size());
  std::string id;
  ++requests_;
  auto req = proto::decode_request(bytes, &id);
  if (!req) {
    ++bad_requests_;
    PROCAM_LOG(daemon, warn) << "rejected request: " << req.status().to_string();
    reply(env, proto::encode_error(id.empty() ? std::nullopt : std::optional<std::string>(id), req.status()));
    return;
  }
  const std::string type(proto::type_name(req->body));
  PROCAM_LOG(daemon, debug) << "request " << type << " id=" << req->id;
  auto err = [&](const Status& s) { reply(env, proto::encode_error(req->id, s)); };
  auto ok = [&](nlohmann::json fields) { reply(env, proto::encode_reply(req->id, type, std::move(fields))); };

  std::visit(overloaded{
      [&](const proto::Hello& h) {
        auto v = proto::negotiate_version(h);
        if (!v) return err(v.status());
        ok({{"version", *v}, {"daemon", "procamd 0.1.0"}, {"rig", service_.rig_name()},
            {"capabilities", curve_ ? nlohmann::json{"events", "fetch", "cancel", "ping", "scan_dedupe",
                                                     "list_scans", "list_rig_options", "calibrate_geometry", "curve"}
                                    : nlohmann::json{"events", "fetch", "cancel", "ping", "scan_dedupe",
                                                     "list_scans", "list_rig_options", "calibrate_geometry"}}});
      },
      [&](const proto::ListPlugins&) {
        nlohmann::json plugins = nlohmann::json::array(), rejected = nlohmann::json::array();
        for (const auto& p : plugins_.plugins()) {
          nlohmann::json methods = nlohmann::json::array();
          for (const auto& m : p.methods) {
            // Normalise to the protocol's method object whatever the plugin wrote.
            nlohmann::json d = m.describe.is_object() ? m.describe : nlohmann::json::object();
            d["name"] = m.name;
            if (!d.contains("description") || !d["description"].is_string()) d["description"] = m.description;
            if (!d.contains("patterns")) d["patterns"] = nullptr;
            if (!d.contains("params") || !d["params"].is_array()) d["params"] = nlohmann::json::array();
            methods.push_back(std::move(d));
          }
          // PROTOCOL.md: a bare file name; the daemon's folders are not the client's business.
          plugins.push_back({{"name", p.name}, {"version", p.version},
                             {"file", std::filesystem::path(p.file).filename().string()}, {"methods", methods}});
        }
        for (const auto& r : plugins_.rejected())
          rejected.push_back({{"file", std::filesystem::path(r.file).filename().string()},
                              {"error", proto::error_to_json(r.error)}});
        ok({{"plugins", plugins}, {"rejected", rejected}});
      },
      [&](const proto::DescribeRig&) { ok({{"rig", service_.rig_description()}}); },
      [&](const proto::Scan& s) {
        engine::ScanRequest sr{s.plugin, s.method, s.label, s.params, s.rig_options, s.save_frames, {}};
        for (const auto& [name, ref] : s.inputs) sr.inputs[name] = {ref.scan_id, ref.output};
        auto r = service_.submit(sr, req->id);
        if (!r) return err(r.status());
        if (s.events) {
          const std::string sid = (*r)["scan_id"].get<std::string>();
          const std::string st = (*r).value("state", "");
          if (st == "done" || st == "failed") {
            // A repeated request for a scan that already ended: its final
            // event went out long ago, so send it again after the reply.
            ok(*r);
            nlohmann::json ev = {{"state", st}};
            if (auto summ = service_.scan_summary(sid); summ && !(*summ)["error"].is_null())
              ev["error"] = (*summ)["error"];
            send_event(env, sid, false, proto::encode_event(sid, seq_.count(sid) ? seq_[sid] : 0, "state", ev));
            return;
          }
          auto& subs = subscribers_[sid];
          if (std::find(subs.begin(), subs.end(), env) == subs.end()) subs.push_back(env);
        }
        ok(*r);
      },
      [&](const proto::ListScans& l) { ok(service_.list_scans(l.state, l.limit)); },
      [&](const proto::CalibrateGeometry& c) {
        auto r = service_.submit_calibration(c.scans, proto::board_json(c), c.label, req->id);
        if (!r) return err(r.status());
        if (c.events) {  // state events of the calibration record, as for a scan
          auto& subs = subscribers_[(*r)["scan_id"].get<std::string>()];
          if (std::find(subs.begin(), subs.end(), env) == subs.end()) subs.push_back(env);
        }
        ok(*r);
      },
      [&](const proto::ListRigOptions&) { ok(service_.rig_options()); },
      [&](const proto::Cancel& c) {
        auto r = service_.cancel(c.scan_id);
        if (!r) return err(r.status());
        ok(*r);
      },
      [&](const proto::Ping&) {
        ok({{"uptime_s", service_.uptime_s()}, {"time_utc", proto::utc_timestamp(std::chrono::system_clock::now())}});
      },
      [&](const proto::StatusQuery& q) {
        if (!q.scan_id) {
          auto d = service_.daemon_status();
          d["metrics"]["requests"] = requests_;
          d["metrics"]["bad_requests"] = bad_requests_;
          d["metrics"]["replies_dropped"] = replies_dropped_;
          d["metrics"]["connections_closed"] = connections_closed_;
          d["metrics"]["curve"] = curve_;
          return ok({{"daemon", std::move(d)}});
        }
        auto r = service_.scan_summary(*q.scan_id);
        if (!r) return err(r.status());
        ok({{"scan", *r}});
      },
      [&](const proto::ResultQuery& q) {
        auto m = service_.manifest(q.scan_id);
        if (!m) return err(m.status());
        ok({{"scan_id", q.scan_id}, {"state", (*m).value("state", "")}, {"manifest", *m}});
      },
      [&](const proto::Fetch& f) {
        auto path = service_.file_path(f.scan_id, f.file);
        if (!path) return err(path.status());
        std::ifstream in(*path, std::ios::binary | std::ios::ate);
        if (!in) return err(Error(Code::io_error, "cannot read '" + f.file + "' of scan " + f.scan_id));
        const uint64_t size = static_cast<uint64_t>(in.tellg());
        if (f.offset > size)
          return err(Error(Code::invalid_argument, "offset " + std::to_string(f.offset) + " is past the end (" +
                                                       std::to_string(size) + " bytes)"));
        const uint64_t n = std::min<uint64_t>(f.max_bytes, size - f.offset);
        std::string data(static_cast<size_t>(n), '\0');
        in.seekg(static_cast<std::streamoff>(f.offset));
        in.read(data.data(), static_cast<std::streamsize>(n));
        if (!in) return err(Error(Code::io_error, "reading '" + f.file + "' failed"));
        const std::string header = proto::encode_reply(
            req->id, type, {{"scan_id", f.scan_id}, {"file", f.file}, {"offset", f.offset}, {"bytes", n},
                            {"size", size}, {"eof", f.offset + n >= size}});
        reply(env, header, &data);
      },
  }, req->body);
}

}  // namespace procam::daemon
