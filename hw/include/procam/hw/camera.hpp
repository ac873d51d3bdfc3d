// SPDX-License-Identifier: MIT
// Camera interface: configure, capture a frame with id and timestamp.
//
// Threads: thread-bound (docs/threading.md) to the rig's capture thread; info() is thread-safe.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "procam/core/image.hpp"
#include "procam/core/status.hpp"

namespace procam::hw {

// How a camera's exposures are started (issue 5; used by the daemon's sync engine).
//   software: capture() triggers one exposure now (the default; sim, software-triggered GenICam)
//   hardware: an external line (e.g. the projector's sync output) triggers; capture() waits for it
//   free_run: the camera streams at its own rate; capture() returns the next frame that
//             started after the call (frames are matched to patterns by timestamp)
enum class TriggerMode { software, hardware, free_run };
inline const char* to_string(TriggerMode m) {
  return m == TriggerMode::hardware ? "hardware" : m == TriggerMode::free_run ? "free_run" : "software";
}

struct CameraInfo {
  std::string backend;      // "sim", "aravis", "libcamera", ...
  std::string id;           // serial / device id
  uint32_t width = 0, height = 0;
  uint32_t bit_depth = 8;   // significant bits of delivered frames
};

// Settings applied before a capture. Unset values keep the configured default.
struct CameraSettings {
  double exposure_us = 0;        // <= 0: default
  double gain_db = -1;           // < 0: default
  double polarizer_deg = NAN;    // NaN: no analyser / unchanged
};

struct Frame {
  Image image;               // 1 channel; U8 for <= 8 bits, else U16 right-aligned
  uint64_t frame_id = 0;     // increasing per camera (may wrap for hardware)
  int64_t timestamp_ns = 0;  // CLOCK_MONOTONIC (or camera clock mapped to it)
  uint32_t camera_index = 0;
};

class Camera {
public:
  virtual ~Camera() = default;
  virtual const CameraInfo& info() const = 0;
  virtual Status configure(const CameraSettings& settings) = 0;
  // Trigger (or wait for) the next exposure of what the projector shows now
  // and return it; fails with timeout, unavailable or corrupt_data.
  virtual Result<Frame> capture(std::chrono::milliseconds timeout) = 0;

  // --- additive (issue 5); defaults keep older backends compiling ---
  // How exposures are started (see TriggerMode).
  virtual TriggerMode trigger_mode() const { return TriggerMode::software; }
  // Backend state and stream statistics as plain JSON (e.g. {"frames": n,
  // "missing_packets": n, "lost_frames": n, "reconnects": n}); {} if none.
  virtual nlohmann::json stats() const { return nlohmann::json::object(); }
};

}  // namespace procam::hw
