// SPDX-License-Identifier: MIT
// libFuzzer harness over the protocol decoder (proto::decode_request, the
// daemon's first contact with every client byte) and the client-side
// decode_incoming. Properties: never throws or crashes; a request that
// decodes re-encodes to one that decodes to the same value; an error always
// encodes to a valid error reply.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "procam/proto/protocol.hpp"

// PROCAM_FUZZ_ENTRY renames the entry point for the regression test, which
// links both harnesses into one gtest binary.
#ifndef PROCAM_FUZZ_ENTRY
#define PROCAM_FUZZ_ENTRY LLVMFuzzerTestOneInput
#endif

extern "C" int PROCAM_FUZZ_ENTRY(const uint8_t* data, size_t size);
extern "C" int PROCAM_FUZZ_ENTRY(const uint8_t* data, size_t size) {
  using namespace procam::proto;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  std::string id;
  auto req = decode_request(bytes, &id);
  if (req.ok()) {
    const std::string again = encode_request(*req);
    auto back = decode_request(again);
    if (!back.ok() || !(*back == *req)) std::abort();  // round trip must hold
    (void)type_name(req->body);
  } else {
    if (req.status().ok()) std::abort();
    const std::string reply = encode_error(id.empty() ? std::nullopt : std::optional<std::string>(id), req.status());
    auto in = decode_incoming(reply);
    if (!in.ok()) std::abort();  // our own error replies must be readable
  }
  (void)decode_incoming(bytes);
  return 0;
}
