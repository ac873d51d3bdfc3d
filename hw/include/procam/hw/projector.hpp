// SPDX-License-Identifier: MIT
// Projector interface: show a pattern frame, report when it is on screen.
//
// Threads: a Projector is thread-bound (docs/threading.md) to the rig's capture thread (the scan
// worker); info() is thread-safe. Errors are returned, never thrown.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <string>

#include "procam/base/calibration.hpp"
#include "procam/core/status.hpp"
#include "procam/pixel.h"

namespace procam::hw {

struct ProjectorInfo {
  std::string backend;     // "sim", "glfw", ...
  std::string name;        // model or monitor name
  uint32_t width = 0, height = 0;
  double refresh_hz = 60;  // pattern rate the backend can sustain
  // --- additive (issue 5): where a display-based projector sits on its X
  // screen (lets a loopback screen camera grab exactly what it shows).
  std::string display;     // X display ("" for non-X backends)
  int32_t screen_x = 0, screen_y = 0;
};

struct Presentation {
  uint64_t pattern_id = 0;
  int64_t shown_ns = 0;    // CLOCK_MONOTONIC when the pattern was on screen
};

class Projector {
public:
  virtual ~Projector() = default;
  virtual const ProjectorInfo& info() const = 0;

  // Queue `pattern` (projector-sized, 1 channel, U8/U16/F32 in [0,1]) for
  // display; returns once accepted. The view is copied: the caller's buffer
  // may be released on return. Fails with invalid_argument on a wrong size.
  virtual Status show(const procam_image& pattern, uint64_t pattern_id) = 0;

  // Block until `pattern_id` is on screen; fails with timeout or unavailable.
  virtual Result<Presentation> wait_presented(uint64_t pattern_id,
                                              std::chrono::milliseconds timeout) = 0;

  // Focal-plane distance in mm (<= 0: the configured default). Backends with a
  // fixed lens return failed_precondition for any other value.
  virtual Status set_focus_mm(double focus_mm) = 0;

  // --- additive (issue 11) ---
  // Angle in degrees of a motorised polariser in front of the projector lens
  // (procam_frame_settings.projector_polarizer_deg), applied to the patterns
  // shown from now on. NaN: no polariser requested (always accepted). A finite
  // angle that the backend cannot realise is refused with failed_precondition,
  // never silently dropped; the default does exactly that, so a backend must
  // opt in by overriding. Non-finite other than NaN: invalid_argument.
  virtual Status set_polarizer_deg(double deg) {
    if (std::isnan(deg)) return Status::Ok();
    if (std::isinf(deg))
      return Error(Code::invalid_argument, "projector_polarizer_deg must be finite or NaN (none)");
    return Error(Code::failed_precondition,
                 "projector '" + info().backend + "' has no motorised polariser (asked for " +
                     std::to_string(deg) + " deg)",
                 "remove projector_polarizer_deg from the plan or use a rig with a motorised polariser");
  }
};

}  // namespace procam::hw
