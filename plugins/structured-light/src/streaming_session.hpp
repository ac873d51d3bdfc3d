// SPDX-License-Identifier: MIT
// What the binary-code sessions (gray_session.cpp, codes_session.cpp) share:
// ScopedMs adds the wall time of a scope, in ms, to a session's decode_ms
// (add_frame work, end_round, triangulation); StreamingSession<Decoder> owns
// the round's streaming decoder (BinaryRoundDecoder / MultiCodeDecoder) and
// forwards add_frame to it, timed. (Their triangulated outputs and valid
// fraction: sdk::add_depth_outputs, procam/sdk/triangulate.hpp.)
// Thread-safety: thread-bound, like the sessions.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <utility>

#include "procam/plugin_sdk.hpp"

namespace procam::sl {

class ScopedMs {
 public:
  explicit ScopedMs(double& total) : total_(total), t0_(std::chrono::steady_clock::now()) {}
  ~ScopedMs() {
    total_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count();
  }
  ScopedMs(const ScopedMs&) = delete;
  ScopedMs& operator=(const ScopedMs&) = delete;

 private:
  double& total_;
  std::chrono::steady_clock::time_point t0_;
};

template <class Decoder>
class StreamingSession : public sdk::Session {
 public:
  sdk::Error add_frame(uint32_t index, const procam_image& frame) override {
    const ScopedMs timed(decode_ms_);
    return decoder_->add_frame(index, frame);
  }

 protected:
  std::optional<Decoder> decoder_;  // the current round's decoder
  double decode_ms_ = 0;
};

}  // namespace procam::sl
