// SPDX-License-Identifier: MIT
// The null plugin's methods: "null" projects one white frame and outputs the
// mean camera value (mean_dn); "echo" projects the same frame and also
// outputs the frame itself as an F32 map (frame_dn). Nothing is decoded: the
// plugin checks the machinery around decoders (plan, capture, frame delivery,
// outputs), and is the smallest correct plugin to copy.
//
// Units: digital numbers (DN) of the camera, as the host delivers them (a
// 12-bit camera in U16 gives 0..4095); F32 frames keep their stored values.
// Threads: a session is thread-bound (docs/threading.md) (SDK rule); nothing here is global but
// the immutable method list. Errors: sdk::Error, never exceptions out of a
// session call (the SDK's barrier catches std::bad_alloc).
#pragma once

#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "procam/plugin_sdk.hpp"

namespace procam::null_plugin {

// Mean of channel 0 over every pixel of `frame` in its own units (DN for
// integer data). The frame must have passed sdk::check_image().
double mean_value(const procam_image& frame);

// describe() JSON array: one object per method ("null", "echo").
nlohmann::json describe_methods();

// Factory for both methods; args.method is one of them (the SDK checked it).
// invalid_argument for params (these methods take none) or a rig without a
// projector or camera size.
sdk::Error create_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::null_plugin
