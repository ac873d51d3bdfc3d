// SPDX-License-Identifier: MIT
// Uses the installed procam client: encodes a request, and calls a daemon
// that is not there (so the error path with its hint runs too).
#include <cstdio>

#include "procam/client/client.hpp"

int main() {
  const std::string wire = procam::proto::encode_request({"1", procam::proto::Ping{}});
  auto back = procam::proto::decode_request(wire);
  if (!back.ok()) return 1;
  procam::client::Client c("ipc:///nonexistent/procam-consumer.sock", std::chrono::milliseconds(200));
  auto r = c.call(procam::proto::StatusQuery{});
  std::printf("request %s; no daemon: %s\n", wire.c_str(), r.status().to_string().c_str());
  return r.ok() ? 1 : 0;
}
