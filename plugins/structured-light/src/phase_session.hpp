// SPDX-License-Identifier: MIT
// Baselines the thesis compares against (§3.3.3 results; docs/techniques.md C8):
//   "phase-shift": sinusoids of 3 frequencies x 6 shifts (18 images),
//     temporal phase unwrapping from the single-period frequency down;
//   "modulated-phase-shift" (Chen et al. 2008): every phase-shift pattern is
//     multiplied by 9 shifted high-frequency dot masks (162 images); per pixel
//     the direct component of each phase-shift image is max - min over its 9
//     modulated images (fast direct/global separation), and the phases are
//     computed from those direct components.
// Errors: INVALID_ARGUMENT for bad params/rig; BAD_FRAME for bad frames.
// Thread-safety: thread-bound (docs/threading.md) like every Session; uses rig.threads threads.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace procam::sl {

inline constexpr const char* kPhaseMethods[] = {"phase-shift", "modulated-phase-shift"};

sdk::MethodDescription describe_phase_method(const std::string& method);
sdk::Error create_phase_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::sl
