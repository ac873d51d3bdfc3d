// SPDX-License-Identifier: MIT
// Method "gray": conventional binary-reflected Gray code structured light
// (thesis §3.2, docs/techniques.md C1 + C9) as an sdk::Session — one round of
// white, black and Gray bit planes (with or without inverses), decoded per
// pixel and triangulated with the rig's calibration of camera 0.
//
// Errors: create_gray_session() returns INVALID_ARGUMENT for bad params/rig;
// the session returns BAD_FRAME for frames of the wrong size or format.
// Thread-safety: thread-bound (docs/threading.md) like every Session; uses rig.threads threads.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace procam::sl {

// Parameter declarations of "gray" (used by describe() and validation).
const std::vector<sdk::ParamSpec>& gray_param_specs();

// describe() entry of "gray": {"name","description","patterns","params",...}.
sdk::MethodDescription describe_gray();

sdk::Error create_gray_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::sl
