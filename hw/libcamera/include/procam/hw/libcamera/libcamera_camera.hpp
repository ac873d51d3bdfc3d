// SPDX-License-Identifier: MIT
// libcamera camera backend ("libcamera"): enumerate cameras, configure one
// stream (size, pixel format), capture through requests; frame sequence
// numbers and sensor timestamps from the request metadata.
//
// No libcamera camera can exist on the CI machines (no /dev/video*, and
// libcamera 0.0.3 has no software-only pipeline): open() then fails with
// not_found "no libcamera camera ..." listing what was looked for.
//
// Ownership: owns its CameraManager, Camera, allocator and requests; no
// libcamera types leak through this header. Threads: thread-bound (docs/threading.md) like every
// Camera; completion arrives on libcamera's thread and is handed over with a
// condition variable. Errors: Status (libcamera's negative errno → message).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "procam/hw/camera.hpp"

namespace procam::libcam {

struct LibcameraCameraConfig {
  std::string camera;              // libcamera id, or index ("0"); "" = first
  std::string id;                  // reported id; default the libcamera id
  uint32_t width = 0, height = 0;  // 0: the pipeline's default
  std::string pixel_format = "R8"; // "R8" (grey) or "YUV420" (Y plane used); also "R16"
  double exposure_us = 0;          // <= 0: auto/default
  double gain = 0;                 // analogue gain factor (<= 0: default)
  int buffers = 4;
};

// Strict parse; errors name the field.
Result<LibcameraCameraConfig> parse_libcamera_camera_config(const nlohmann::json& j, const std::string& field,
                                                            const std::vector<std::string>& extra_keys = {});

// Cameras libcamera enumerates: [{"index", "id", "model"}] (empty here).
Result<nlohmann::json> list_libcamera_cameras();

class LibcameraCamera final : public hw::Camera {
public:
  static Result<std::unique_ptr<LibcameraCamera>> open(const LibcameraCameraConfig& config);
  ~LibcameraCamera() override;
  LibcameraCamera(const LibcameraCamera&) = delete;
  LibcameraCamera& operator=(const LibcameraCamera&) = delete;

  const hw::CameraInfo& info() const override { return info_; }
  Status configure(const hw::CameraSettings& settings) override;
  // Queues one request and waits for it (software trigger semantics).
  Result<hw::Frame> capture(std::chrono::milliseconds timeout) override;
  nlohmann::json stats() const override;

  struct Impl;

private:
  LibcameraCamera() = default;
  std::unique_ptr<Impl> impl_;
  hw::CameraInfo info_;
};

}  // namespace procam::libcam
