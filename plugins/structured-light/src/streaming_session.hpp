// SPDX-License-Identifier: MIT
// What the binary-code sessions (gray_session.cpp, codes_session.cpp) share:
// StreamingSession<Decoder> owns the round's streaming decoder
// (BinaryRoundDecoder / MultiCodeDecoder) and forwards add_frame to it, timed
// into decode_ms with sdk::ScopedMs (procam/sdk/timing.hpp). Triangulated
// outputs: sdk::add_depth_outputs (procam/sdk/triangulate.hpp); valid_fraction
// comes with sdk::add_standard_outputs.
// Thread-safety: thread-bound (docs/threading.md), like the sessions.
#pragma once

#include <cstdint>
#include <optional>
#include <utility>

#include "procam/plugin_sdk.hpp"
#include "procam/sdk/timing.hpp"
#include "procam/sdk/triangulate.hpp"

namespace procam::sl {

using sdk::ScopedMs;  // procam/sdk/timing.hpp

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
