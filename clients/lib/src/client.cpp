// SPDX-License-Identifier: MIT
// ZeroMQ DEALER client for procamd.
#include "procam/client/client.hpp"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <cstdio>
#include <fstream>
#include <random>
#include <thread>
#include <zmq.hpp>
#include <zmq_addon.hpp>

namespace procam::client {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string default_endpoint() {
  const char* e = std::getenv("PROCAM_ENDPOINT");
  return e && *e ? std::string(e) : std::string(kDefaultEndpoint);
}

Result<std::string> load_key(const std::string& value) {
  std::string key = value;
  std::error_code ec;
  if (value.size() != 40 || fs::is_regular_file(value, ec)) {  // Z85 may contain '/': a file only if one exists
    std::ifstream in(value);
    if (!in) return Error(Code::invalid_argument, "'" + value + "' is neither a 40-character Z85 key nor a readable key file",
                          "make keys with `procam keygen --out NAME`");
    key.clear();
    std::string line;
    while (std::getline(in, line)) {
      while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
      size_t b = line.find_first_not_of(" \t");
      if (b == std::string::npos || line[b] == '#') continue;
      key = line.substr(b);
      break;
    }
  }
  uint8_t bin[32];
  if (key.size() != 40 || !zmq_z85_decode(bin, key.c_str()))
    return Error(Code::invalid_argument, "'" + value + "' does not hold a 40-character Z85 CURVE key",
                 "make keys with `procam keygen --out NAME`");
  return key;
}

Result<CurveKeys> curve_keys_from_env() {
  CurveKeys k;
  const char* server = std::getenv("PROCAM_SERVER_KEY");
  if (!server || !*server) return k;
  auto sp = load_key(server);
  if (!sp) return sp.status().with_context("$PROCAM_SERVER_KEY");
  k.server_public = *sp;
  const char* client = std::getenv("PROCAM_CLIENT_KEY");
  if (!client || !*client)
    return Error(Code::invalid_argument, "$PROCAM_SERVER_KEY is set but $PROCAM_CLIENT_KEY is not",
                 "set PROCAM_CLIENT_KEY to your .secret file from `procam keygen`");
  auto cs = load_key(client);
  if (!cs) return cs.status().with_context("$PROCAM_CLIENT_KEY");
  k.client_secret = *cs;
  return k;
}

Result<std::pair<std::string, std::string>> generate_keypair() {
  if (!zmq_has("curve")) return Error(Code::unavailable, "libzmq was built without CURVE");
  char pub[41] = {}, sec[41] = {};
  if (zmq_curve_keypair(pub, sec) != 0) return Error(Code::internal, "zmq_curve_keypair failed");
  return std::make_pair(std::string(pub), std::string(sec));
}

struct Client::Impl {
  zmq::context_t ctx{1};
  zmq::socket_t sock{ctx, zmq::socket_type::dealer};
  bool connected = false;
  bool curve = false;
  Status connect_error;
};

Client::Client(std::string endpoint, std::chrono::milliseconds timeout)
    : endpoint_(std::move(endpoint)), timeout_(timeout), impl_(std::make_unique<Impl>()) {
  init(curve_keys_from_env());
}

Client::Client(std::string endpoint, std::chrono::milliseconds timeout, const CurveKeys& keys)
    : endpoint_(std::move(endpoint)), timeout_(timeout), impl_(std::make_unique<Impl>()) {
  init(keys);
}

std::string Client::new_request_id() { return id_prefix_ + "-" + std::to_string(next_id_++); }

void Client::init(const Result<CurveKeys>& keys) {
  {
    std::random_device rd;
    const uint64_t r = (uint64_t{rd()} << 32) ^ rd() ^ static_cast<uint64_t>(::getpid());
    char buf[24];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(r));
    id_prefix_ = buf;
  }
  if (!keys) {
    impl_->connect_error = keys.status();
    return;
  }
  try {
    if (keys->enabled()) {
      std::string pub = keys->client_public;
      if (pub.empty()) {
        char p[41] = {};
        if (zmq_curve_public(p, keys->client_secret.c_str()) != 0) {
          impl_->connect_error = Error(Code::invalid_argument, "the client secret key is not a valid CURVE key",
                                       "make keys with `procam keygen --out NAME`");
          return;
        }
        pub = p;
      }
      impl_->sock.set(zmq::sockopt::curve_serverkey, keys->server_public);
      impl_->sock.set(zmq::sockopt::curve_publickey, pub);
      impl_->sock.set(zmq::sockopt::curve_secretkey, keys->client_secret);
      impl_->curve = true;
    }
    impl_->sock.set(zmq::sockopt::linger, 0);
    impl_->sock.set(zmq::sockopt::heartbeat_ivl, 2000);
    impl_->sock.set(zmq::sockopt::heartbeat_timeout, 6000);
    impl_->sock.connect(endpoint_);
    impl_->connected = true;
  } catch (const zmq::error_t& e) {
    impl_->connect_error = Error(Code::invalid_argument, "bad endpoint '" + endpoint_ + "': " + e.what(),
                                 "use e.g. tcp://127.0.0.1:5560");
  }
}

Client::~Client() = default;

Result<proto::Reply> Client::roundtrip(const proto::RequestBody& body, std::string* extra, const std::string& id) {
  if (!impl_->connected) return impl_->connect_error;
  proto::Request req{id.empty() ? new_request_id() : id, body};
  const std::string bytes = proto::encode_request(req);
  try {
    impl_->sock.send(zmq::message_t(), zmq::send_flags::sndmore);
    impl_->sock.send(zmq::buffer(bytes), zmq::send_flags::none);
  } catch (const zmq::error_t& e) {
    return Error(Code::unavailable, std::string("cannot send to procamd: ") + e.what());
  }
  const auto deadline = Clock::now() + timeout_;
  for (;;) {
    auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0)
      return Error(Code::unavailable, "no reply from procamd at " + endpoint_ + " within " +
                                          std::to_string(timeout_.count()) + " ms",
                   impl_->curve ? "is procamd running, and does it list our public key in its authorized_keys? "
                                  "(with CURVE a refused key looks like no daemon)"
                                : "is procamd running? start it with `procamd --config configs/procamd.json`");
    auto got = receive_one(left, extra);
    if (!got) return got.status();
    if (!*got) continue;  // an event, a timeout or nothing
    proto::Reply& rep = **got;
    if (!rep.id.empty() && rep.id != req.id) continue;  // late reply to an earlier, timed-out call
    return std::move(rep);
  }
}

Result<std::optional<proto::Reply>> Client::receive_one(std::chrono::milliseconds wait,
                                                        std::string* extra) {
  zmq::pollitem_t items[] = {{impl_->sock.handle(), 0, ZMQ_POLLIN, 0}};
  try {
    zmq::poll(items, 1, wait);
  } catch (const zmq::error_t& e) {
    if (e.num() == EINTR) return std::optional<proto::Reply>{};
    return Error(Code::unavailable, std::string("poll: ") + e.what());
  }
  if (!(items[0].revents & ZMQ_POLLIN)) return std::optional<proto::Reply>{};
  std::vector<zmq::message_t> msg;
  try {
    (void)zmq::recv_multipart(impl_->sock, std::back_inserter(msg));
  } catch (const zmq::error_t& e) {
    return Error(Code::unavailable, std::string("receive: ") + e.what());
  }
  size_t i = 0;
  while (i < msg.size() && msg[i].size() == 0) ++i;  // delimiter
  if (i >= msg.size()) return std::optional<proto::Reply>{};
  auto in = proto::decode_incoming(std::string_view(static_cast<const char*>(msg[i].data()), msg[i].size()));
  if (!in) return in.status().with_context("reply from procamd");
  if (auto* ev = std::get_if<proto::Event>(&in->message)) {
    pending_events_.push_back(std::move(*ev));
    return std::optional<proto::Reply>{};
  }
  if (extra) *extra = i + 1 < msg.size() ? msg[i + 1].to_string() : std::string();
  return std::optional<proto::Reply>(std::move(std::get<proto::Reply>(in->message)));
}

Result<nlohmann::json> Client::call_with_id(const std::string& id, const proto::RequestBody& body) {
  auto r = roundtrip(body, nullptr, id);
  if (!r) return r.status();
  if (!r->ok) return r->error;
  return r->body;
}

Result<nlohmann::json> Client::call(const proto::RequestBody& body) {
  auto r = roundtrip(body, nullptr);
  if (!r) return r.status();
  if (!r->ok) return r->error;
  return r->body;
}

Result<nlohmann::json> Client::scan(const proto::Scan& request,
                                    const std::function<void(const proto::Event&)>& on_event,
                                    std::chrono::milliseconds limit) {
  proto::Scan s = request;
  s.events = true;
  auto accepted = call(s);
  if (!accepted) return accepted.status();
  const std::string scan_id = (*accepted).value("scan_id", "");
  const auto deadline = Clock::now() + limit;
  auto last_poll = Clock::now();
  auto deliver = [&]() -> bool {  // true when the scan ended
    bool ended = false;
    for (auto& ev : pending_events_) {
      if (ev.scan_id != scan_id) continue;
      if (on_event) on_event(ev);
      if (ev.event == "state") {
        const std::string st = ev.body.value("state", "");
        ended |= st == "done" || st == "failed";
      }
    }
    pending_events_.clear();
    return ended;
  };
  for (;;) {
    if (deliver()) break;
    if (Clock::now() > deadline)
      return Error(Code::timeout, "scan " + scan_id + " did not finish in time", "check `procam status`");
    // Wait for events; every second confirm with status (events are advisory).
    // Replies here are late answers to earlier calls (dropped); a message
    // that does not decode is skipped; poll/receive failures end the wait.
    const size_t events_before = pending_events_.size();
    auto got = receive_one(std::chrono::milliseconds(200), nullptr);
    if (!got && got.status().code() == Code::unavailable) return got.status();
    if (!got || *got || pending_events_.size() != events_before) continue;
    if (Clock::now() - last_poll > std::chrono::seconds(1)) {
      last_poll = Clock::now();
      auto st = call(proto::StatusQuery{scan_id});
      if (!st) return st.status();
      const std::string state = (*st)["scan"].value("state", "");
      if (state == "done" || state == "failed") {
        deliver();
        break;
      }
    }
  }
  auto st = call(proto::StatusQuery{scan_id});
  if (!st) return st.status();
  return (*st)["scan"];
}

Status Client::fetch_file(const std::string& scan_id, const std::string& file, const std::string& dest) {
  const std::string tmp = dest + ".part";
  std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
  if (!out) return Error(Code::io_error, "cannot write '" + tmp + "'", "check the output folder");
  uint64_t offset = 0;
  for (;;) {
    std::string data;
    proto::Fetch f{scan_id, file, offset, 4u << 20};
    auto r = roundtrip(f, &data);
    if (!r) return r.status();
    if (!r->ok) return r->error;
    const uint64_t n = r->body.value("bytes", uint64_t{0});
    if (data.size() != n) return Error(Code::corrupt_data, "fetch of '" + file + "' returned " +
                                       std::to_string(data.size()) + " bytes, header said " + std::to_string(n));
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    offset += n;
    if (r->body.value("eof", true) || n == 0) break;
  }
  out.close();
  if (!out) return Error(Code::io_error, "writing '" + dest + "' failed");
  std::error_code ec;
  fs::rename(tmp, dest, ec);
  if (ec) return Error(Code::io_error, "cannot move '" + dest + "' into place: " + ec.message());
  return Status::Ok();
}

namespace {
Status write_text_file(const std::string& path, const std::string& text) {
  std::ofstream out(path + ".part", std::ios::binary | std::ios::trunc);
  out << text;
  out.close();
  std::error_code ec;
  if (out) fs::rename(path + ".part", path, ec);
  if (!out || ec) return Error(Code::io_error, "cannot write '" + path + "'");
  return Status::Ok();
}
}  // namespace

Result<nlohmann::json> Client::fetch_all(const std::string& scan_id, const std::string& dir) {
  auto res = call(proto::ResultQuery{scan_id});
  if (!res) return res.status();
  nlohmann::json manifest = (*res)["manifest"];
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Error(Code::io_error, "cannot create '" + dir + "': " + ec.message());
  PROCAM_TRY(write_text_file((fs::path(dir) / "manifest.json").string(), manifest.dump(2)));
  for (const auto& f : manifest.value("files", nlohmann::json::array())) {
    const std::string name = f.value("name", "");
    if (!proto::is_safe_file_name(name)) continue;  // never write outside `dir`
    PROCAM_TRY(fetch_file(scan_id, name, (fs::path(dir) / name).string()));
  }
  return manifest;
}

}  // namespace procam::client
