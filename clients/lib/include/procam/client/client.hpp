// SPDX-License-Identifier: MIT
// procam client library: talks to procamd over ZeroMQ using proto/'s codec.
// Used by the `procam` CLI; usable by any C++ program.
//
// Threads: a Client is thread-bound (docs/threading.md) (one ZeroMQ DEALER socket); use one per thread.
// Errors: every call returns Result/Status; a daemon that does not answer in
// time gives `unavailable` with a hint, a daemon error reply is returned as
// its Status (code, message, hint from the daemon). Nothing throws.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"
#include "procam/proto/protocol.hpp"

namespace procam::client {

// "tcp://127.0.0.1:5560"; defined once, in the protocol (procam/proto/protocol.hpp).
using proto::kDefaultEndpoint;

// $PROCAM_ENDPOINT or kDefaultEndpoint.
std::string default_endpoint();

// CURVE keys for a daemon that requires them (PROTOCOL.md 1.6), Z85 text of
// 40 characters each. Empty server_public = no CURVE.
struct CurveKeys {
  std::string server_public;  // the daemon's public key
  std::string client_public;  // ours (derived from client_secret when empty)
  std::string client_secret;
  bool enabled() const { return !server_public.empty(); }
};

// Reads a Z85 key: `value` is either the 40-character key itself or the path
// of a file whose first non-comment line is the key (procam keygen's files).
Result<std::string> load_key(const std::string& value);

// Keys from the environment: $PROCAM_SERVER_KEY (daemon public key or its
// .pub file) and $PROCAM_CLIENT_KEY (our secret key or its .secret file).
// No CURVE (empty result) when PROCAM_SERVER_KEY is unset; an error when a
// variable is set but unreadable.
Result<CurveKeys> curve_keys_from_env();

// A new CURVE key pair: {public, secret}, Z85.
Result<std::pair<std::string, std::string>> generate_keypair();

class Client {
public:
  // Keys come from the environment (curve_keys_from_env); a bad key there
  // makes every call fail with that error.
  explicit Client(std::string endpoint,
                  std::chrono::milliseconds timeout = std::chrono::milliseconds(10000));
  // Explicit CURVE keys (keys.enabled() false: plain connection).
  Client(std::string endpoint, std::chrono::milliseconds timeout, const CurveKeys& keys);
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  const std::string& endpoint() const { return endpoint_; }

  // Sends one request and waits for its reply; returns the reply's fields
  // (everything but procam/id/type/ok) or the daemon's error. Request ids are
  // "<random 64-bit hex>-<counter>", unique across clients, so a scan
  // request retried with call_with_id() is never run twice.
  Result<nlohmann::json> call(const proto::RequestBody& body);
  // The same with a caller-chosen request id (for retries: same id, same body).
  Result<nlohmann::json> call_with_id(const std::string& id, const proto::RequestBody& body);
  // A fresh request id of the form call() uses.
  std::string new_request_id();

  // Runs a scan with events on, calling `on_event` for each event, until the
  // scan ends; returns the final scan summary (from `status`). Waits at most
  // `limit` in total. Falls back to polling `status` if events stop arriving.
  Result<nlohmann::json> scan(const proto::Scan& request,
                              const std::function<void(const proto::Event&)>& on_event,
                              std::chrono::milliseconds limit = std::chrono::minutes(30));

  // Downloads one file of a finished scan in chunks to `dest` (atomic).
  Status fetch_file(const std::string& scan_id, const std::string& file, const std::string& dest);

  // Fetches the manifest and every file it lists into `dir`; returns the manifest.
  Result<nlohmann::json> fetch_all(const std::string& scan_id, const std::string& dir);

private:
  Result<proto::Reply> roundtrip(const proto::RequestBody& body, std::string* extra_frame,
                                 const std::string& id = "");
  // Waits up to `wait` for one message from the daemon. Events are queued in
  // pending_events_ and give nullopt, as do a timeout, EINTR and an empty
  // message; a reply is returned with its binary frame (if any) in *extra_frame.
  // Errors: unavailable (poll or receive failed); a message that does not
  // decode gives the decoder's error with context "reply from procamd".
  Result<std::optional<proto::Reply>> receive_one(std::chrono::milliseconds wait,
                                                  std::string* extra_frame);
  void init(const Result<CurveKeys>& keys);
  struct Impl;
  std::string endpoint_;
  std::chrono::milliseconds timeout_;
  std::unique_ptr<Impl> impl_;
  std::vector<proto::Event> pending_events_;
  uint64_t next_id_ = 1;
  std::string id_prefix_;
};

}  // namespace procam::client
