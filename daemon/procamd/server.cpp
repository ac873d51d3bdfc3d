// SPDX-License-Identifier: MIT
// ROUTER request loop: decode → dispatch to ScanService → encode reply.
#include "server.hpp"

#include <sys/eventfd.h>
#include <unistd.h>

#include <fstream>
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
  // Drop (with a log line in libzmq) anything absurdly large before it is
  // buffered; requests between 1 MiB and this get a too_large reply.
  router_.set(zmq::sockopt::maxmsgsize, int64_t{8} << 20);
  router_.set(zmq::sockopt::router_mandatory, false);
  // Heartbeats let clients tell a dead daemon from a slow one.
  router_.set(zmq::sockopt::heartbeat_ivl, 2000);
  router_.set(zmq::sockopt::heartbeat_timeout, 6000);
}

Server::~Server() {
  if (event_fd_ >= 0) ::close(event_fd_);
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

void Server::run(int stop_fd) {
  for (;;) {
    zmq::pollitem_t items[] = {{router_.handle(), 0, ZMQ_POLLIN, 0},
                               {nullptr, event_fd_, ZMQ_POLLIN, 0},
                               {nullptr, stop_fd, ZMQ_POLLIN, 0}};
    try {
      zmq::poll(items, 3, std::chrono::milliseconds(-1));
    } catch (const zmq::error_t& e) {
      if (e.num() == EINTR) continue;
      PROCAM_LOG(daemon, error) << "poll failed: " << e.what();
      continue;
    }
    if (items[2].revents & ZMQ_POLLIN) {
      PROCAM_LOG(daemon, info) << "stop requested";
      drain_events();
      return;
    }
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

void Server::reply(const Envelope& env, const std::string& body, const std::string* extra) {
  try {
    for (const auto& f : env) router_.send(zmq::buffer(f), zmq::send_flags::sndmore);
    router_.send(zmq::buffer(body), extra ? zmq::send_flags::sndmore : zmq::send_flags::none);
    if (extra) router_.send(zmq::buffer(*extra), zmq::send_flags::none);
  } catch (const zmq::error_t& e) {
    PROCAM_LOG(daemon, warn) << "reply not sent: " << e.what();
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
      for (const auto& env : it->second) reply(env, body);
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
    reply(env, proto::encode_error(std::nullopt, Error(Code::bad_message,
        "expected exactly one JSON frame after the envelope, got " + std::to_string(msg.size() - i),
        "send one frame holding a JSON object (see proto/PROTOCOL.md)")));
    PROCAM_LOG(daemon, warn) << "bad frame count from client";
    return;
  }
  const std::string_view bytes(static_cast<const char*>(msg[i].data()), msg[i].size());
  std::string id;
  auto req = proto::decode_request(bytes, &id);
  if (!req) {
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
            {"capabilities", {"events", "fetch"}}});
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
          plugins.push_back({{"name", p.name}, {"version", p.version}, {"file", p.file}, {"methods", methods}});
        }
        for (const auto& r : plugins_.rejected())
          rejected.push_back({{"file", r.file}, {"error", proto::error_to_json(r.error)}});
        ok({{"plugins", plugins}, {"rejected", rejected}});
      },
      [&](const proto::DescribeRig&) { ok({{"rig", service_.rig_description()}}); },
      [&](const proto::Scan& s) {
        engine::ScanRequest sr{s.plugin, s.method, s.label, s.params, s.rig_options};
        auto r = service_.submit(sr);
        if (!r) return err(r.status());
        if (s.events) subscribers_[(*r)["scan_id"].get<std::string>()].push_back(env);
        ok(*r);
      },
      [&](const proto::StatusQuery& q) {
        if (!q.scan_id) return ok({{"daemon", service_.daemon_status()}});
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
