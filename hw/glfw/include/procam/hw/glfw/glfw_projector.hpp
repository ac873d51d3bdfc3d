// SPDX-License-Identifier: MIT
// GLFW projector backend ("glfw"): a borderless fullscreen window on a monitor
// chosen by name or index, showing each pattern with an exact pixel mapping
// (glDrawPixels: no scaling, filtering or colour management), an optional
// response lookup table, and a presentation timestamp per pattern.
//
// Ownership/threads: the projector owns one presenter thread that makes every
// GLFW and OpenGL call (init, window, draw, swap, terminate); show() and
// wait_presented() hand work to it and may be called from any one thread.
// Errors: Status; no X display, no such monitor, a mode that does not fit →
// unavailable / not_found with the monitors listed. Units: ns CLOCK_MONOTONIC.
// Software rendering swaps at hundreds of Hz with no vsync pacing: the
// presentation stamp is taken after glfwSwapBuffers + glFinish, and the sync
// engine adds the calibrated display latency on top.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/hw/projector.hpp"

namespace procam::glfw {

struct GlfwProjectorConfig {
  std::string monitor;        // monitor name (glfwGetMonitorName) or index ("0", "1"); "" = primary
  std::string name;           // reported name; default: the monitor's name
  uint32_t width = 0, height = 0;  // expected mode (0: the monitor's current mode); mismatch → error
  std::array<uint8_t, 256> lut{};  // response LUT applied to 8-bit pattern values
  bool has_lut = false;
  bool keep_backbuffer = false;     // read GL_BACK before each swap (tests; costs a readback)
};

// Strict parse ("rig config: projector.monitor: ..."). Accepts "gamma": g
// (LUT = 255 * (v/255)^(1/g)) or "lut": [256 ints] and ignores calibration keys
// listed in `extra_keys`.
Result<GlfwProjectorConfig> parse_glfw_projector_config(const nlohmann::json& j, const std::vector<std::string>& extra_keys);

// Monitors GLFW sees on $DISPLAY: [{"index", "name", "x", "y", "width", "height", "refresh_hz"}].
Result<nlohmann::json> list_glfw_monitors();

class GlfwProjector final : public hw::Projector {
public:
  static Result<std::unique_ptr<GlfwProjector>> open(const GlfwProjectorConfig& config);
  ~GlfwProjector() override;
  GlfwProjector(const GlfwProjector&) = delete;
  GlfwProjector& operator=(const GlfwProjector&) = delete;

  const hw::ProjectorInfo& info() const override { return info_; }
  // Pattern: projector-sized, 1 channel, U8 / U16 / F32 in [0, 1]; converted to
  // 8 bits (round to nearest), mapped through the LUT, shown as grey (R=G=B).
  Status show(const procam_image& pattern, uint64_t pattern_id) override;
  Result<hw::Presentation> wait_presented(uint64_t pattern_id, std::chrono::milliseconds timeout) override;
  // Fixed lens: <= 0 / NaN accepted, anything else failed_precondition.
  Status set_focus_mm(double focus_mm) override;
  // A display has no motorised polariser: NaN accepted, any angle
  // failed_precondition ("remove projector_polarizer_deg from the plan ...").
  Status set_polarizer_deg(double deg) override;

  // The back buffer read just before the last swap (keep_backbuffer only):
  // width*height grey bytes, top row first.
  std::vector<uint8_t> last_backbuffer() const;

  struct Impl;

private:
  GlfwProjector() = default;
  std::unique_ptr<Impl> impl_;
  hw::ProjectorInfo info_;
};

}  // namespace procam::glfw
