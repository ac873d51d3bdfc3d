// SPDX-License-Identifier: MIT
// The defocus plugin's methods (plugins/defocus/README.md): describe() and the
// session factory. Every method plans the same kind of sweep - a period-24
// stripe pattern shifted one projector pixel per frame, 24 frames per focus
// setting, focus settings in order (frame index = 24 * focus + shift) - and
// differs in what it computes from the E(3, f) maps at end_round:
//   multi-focal   fbar (Eq. 2.9) -> depth through table "defocus.multi-focal"
//   two-focal     Omega (Eq. 2.10) -> depth through table "defocus.two-focal"
//   single-focal  E/mean at one setting (Zhang & Nayar 2006) -> "defocus.single-focal"
//   invariance    E(3, f) maps and G(f) (Eq. 2.8) at given pixel pairs
//   calibrate-*   the table of the method above from a plane whose depth is
//                 known (calibration.hpp)
// Threads: sessions are thread-bound (docs/threading.md); they use
// rig.threads workers of the calling thread's pool. Errors: sdk::Error,
// never exceptions across the ABI (the SDK wrapper catches).
#pragma once

#include <memory>
#include <string>

#include "procam/plugin_sdk.hpp"

namespace procam::defocus {

std::string describe_methods();
sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::defocus
