// SPDX-License-Identifier: MIT
// What the binary-code sessions (gray_session.cpp, codes_session.cpp) share:
// StreamingSession<Decoder> owns the round's streaming decoder
// (BinaryRoundDecoder / MultiCodeDecoder) and forwards add_frame to it, timed
// into decode_ms with sdk::ScopedMs (procam/sdk/timing.hpp);
// add_depth_outputs writes the triangulated outputs the same way for both
// (valid_fraction comes with sdk::add_standard_outputs).
// Thread-safety: thread-bound, like the sessions.
#pragma once

#include <cstdint>
#include <optional>
#include <utility>

#include "procam/plugin_sdk.hpp"
#include "procam/sdk/timing.hpp"
#include "triangulate.hpp"

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

// depth_mm + points (when triangulated).
inline void add_depth_outputs(sdk::Outputs& out, std::optional<DepthResult>& depth, uint32_t w,
                              uint32_t h) {
  if (depth) {
    out.add_image("depth_mm", "mm", "z of the triangulated point, camera frame (NaN: none)", w, h,
                  std::move(depth->depth_mm));
    out.add_points("points", "triangulated points, camera frame; intensity = white / full scale",
                   "x,y,z,intensity", 4, std::move(depth->points));
  }
}

}  // namespace procam::sl
