// SPDX-License-Identifier: MIT
// The polarized-striping plugin's sessions (thesis §5.2; docs/polarized-striping.md):
//   flood               one white frame, no polariser
//   polarized-flood     polarised white light, analyser crossed (best, E_b) and
//                       parallel (worst, E_w); signal by Eq. 5.6
//   striping            K vertical light sheets; composite CI = max_k SI_k (Eq. 5.7)
//   polarized-striping  the sheets polarised, each seen through the crossed
//                       (best) and the parallel (worst) analyser (§5.2.1)
//
// Streaming: flood frames are kept as float maps (one or two); stripe frames
// fold into StripeStack (O(pixels) whatever K). end_round estimates S, B, p
// and the quality measures (media_model.hpp); outputs() moves the maps out.
// Units: frame units (DN) in, DN out; angles in degrees; depth in mm.
// Threads: a session is thread-bound (docs/threading.md); it uses
// sdk::parallel_rows workers inside add_frame.
// Errors: sdk::Error, never exceptions out of a session call.
#pragma once

#include <cstdint>
#include <memory>

#include <nlohmann/json.hpp>

#include "procam/plugin_sdk.hpp"

namespace procam::polarized_striping {

// describe() JSON array: one object per method, in PROCAM_DEFINE_PLUGIN order.
nlohmann::json describe_methods();

// The factory for every method (args.method is one of them).
sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::polarized_striping
