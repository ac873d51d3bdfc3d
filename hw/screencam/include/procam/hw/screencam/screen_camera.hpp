// SPDX-License-Identifier: MIT
// Loopback "screen camera" backend ("screencam"): captures what an X display
// shows in a rectangle (by default exactly the glfw projector's monitor) with
// XGetImage, so the real projector backend, the sync engine and a decoder can
// be tested end to end with exact pixels. Frames are grey (the green channel:
// the glfw projector draws grey as R = G = B).
//
// Ownership: owns its X connection. Threads: thread-bound (docs/threading.md) like every Camera.
// Errors: no display → unavailable naming DISPLAY; a region outside the
// screen → invalid_argument. Units: pixels; ns CLOCK_MONOTONIC stamps (taken
// just before the grab: the grab shows the screen at or after that time).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "procam/hw/camera.hpp"

namespace procam::screencam {

struct ScreenCameraConfig {
  std::string display;      // X display name; "" = $DISPLAY
  std::string id = "screen0";
  int32_t x = 0, y = 0;     // region on the root window
  uint32_t width = 0, height = 0;  // 0: the whole screen
};

class ScreenCamera final : public hw::Camera {
public:
  static Result<std::unique_ptr<ScreenCamera>> open(const ScreenCameraConfig& config);
  ~ScreenCamera() override;
  ScreenCamera(const ScreenCamera&) = delete;
  ScreenCamera& operator=(const ScreenCamera&) = delete;

  const hw::CameraInfo& info() const override { return info_; }
  // Exposure/gain have no meaning here: accepted and ignored; polarizer → failed_precondition.
  Status configure(const hw::CameraSettings& settings) override;
  // Grabs the region now (software trigger).
  Result<hw::Frame> capture(std::chrono::milliseconds timeout) override;
  nlohmann::json stats() const override;

private:
  ScreenCamera() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  hw::CameraInfo info_;
  ScreenCameraConfig config_;
  uint64_t next_id_ = 1;
  double grab_ms_sum_ = 0;
};

}  // namespace procam::screencam
