// SPDX-License-Identifier: MIT
// procam client library: talks to procamd over ZeroMQ using proto/'s codec.
// Used by the `procam` CLI; usable by any C++ program.
//
// Threads: a Client is thread-bound (one ZeroMQ DEALER socket); use one per thread.
// Errors: every call returns Result/Status; a daemon that does not answer in
// time gives `unavailable` with a hint, a daemon error reply is returned as
// its Status (code, message, hint from the daemon). Nothing throws.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"
#include "procam/proto/protocol.hpp"

namespace procam::client {

inline constexpr const char* kDefaultEndpoint = "tcp://127.0.0.1:5560";

// $PROCAM_ENDPOINT or kDefaultEndpoint.
std::string default_endpoint();

class Client {
public:
  explicit Client(std::string endpoint,
                  std::chrono::milliseconds timeout = std::chrono::milliseconds(10000));
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  const std::string& endpoint() const { return endpoint_; }

  // Sends one request and waits for its reply; returns the reply's fields
  // (everything but procam/id/type/ok) or the daemon's error.
  Result<nlohmann::json> call(const proto::RequestBody& body);

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
  Result<proto::Reply> roundtrip(const proto::RequestBody& body, std::string* extra_frame);
  struct Impl;
  std::string endpoint_;
  std::chrono::milliseconds timeout_;
  std::unique_ptr<Impl> impl_;
  std::vector<proto::Event> pending_events_;
  uint64_t next_id_ = 1;
};

}  // namespace procam::client
