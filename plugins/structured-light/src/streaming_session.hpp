// SPDX-License-Identifier: MIT
// What the binary-code sessions (gray_session.cpp, codes_session.cpp) share:
// ScopedMs adds the wall time of a scope, in ms, to a session's decode_ms
// (add_frame work, end_round, triangulation); StreamingSession<Decoder> owns
// the round's streaming decoder (BinaryRoundDecoder / MultiCodeDecoder) and
// forwards add_frame to it, timed; add_depth_outputs writes the triangulated
// outputs and the valid fraction the same way for both.
// Thread-safety: thread-bound, like the sessions.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <utility>

#include "procam/plugin_sdk.hpp"
#include "triangulate.hpp"

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

// depth_mm + points (when triangulated) and valid_fraction = valid / n.
inline void add_depth_outputs(sdk::Outputs& out, std::optional<DepthResult>& depth, uint32_t w,
                              uint32_t h, size_t valid, double n) {
  if (depth) {
    out.add_image("depth_mm", "mm", "z of the triangulated point, camera frame (NaN: none)", w, h,
                  std::move(depth->depth_mm));
    out.add_points("points", "triangulated points, camera frame; intensity = white / full scale",
                   "x,y,z,intensity", 4, std::move(depth->points));
  }
  out.add_scalar("valid_fraction", "", "fraction of camera pixels with a valid column",
                 n > 0 ? static_cast<double>(valid) / n : 0.0);
}

}  // namespace procam::sl
