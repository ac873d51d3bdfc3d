// SPDX-License-Identifier: MIT
// The medium plugin's sessions (thesis ch. 4; docs/medium.md):
//   measure        one HDR bracket of the tank lit by the bulb; sigma, beta, g
//                  (and kappa) by the single-scattering fit (M4 + M2 + M5)
//   concentration  one HDR bracket per dilution (a round each); sigma-hat by
//                  the bulb's attenuation (Eq. 4.3), linearity, the best
//                  volume, and a stop beyond single scattering (M3)
//
// Streaming: each frame is folded into the HDR sums as it arrives
// (hdr_merge.hpp); end_round fits (measure) or reduces the round to a few
// numbers (concentration). Units: DN in, DN/us radiance, mm, 1/mm, ml.
// Threads: a session is thread-bound (docs/threading.md); it uses
// sdk::parallel_rows workers inside add_frame.
// Errors: sdk::Error, never exceptions out of a session call.
#pragma once

#include <memory>

#include <nlohmann/json.hpp>

#include "procam/plugin_sdk.hpp"

namespace procam::medium {

// describe() JSON array: one object per method, in PROCAM_DEFINE_PLUGIN order.
nlohmann::json describe_methods();

// The factory for every method (args.method is one of them).
sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::medium
