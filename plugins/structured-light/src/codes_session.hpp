// SPDX-License-Identifier: MIT
// Methods "xor02", "xor04", "minsw" (one code each, thesis §3.3.1–3.3.2) and
// "ensemble" (the four codes with vote, classification map, error detection
// and error-correction rounds, thesis §3.3.3–3.4; docs/techniques.md C2–C7) as
// sdk::Sessions built on MultiCodeDecoder (finish_vote: decode + vote in one
// pass) and the streaming_session.hpp helpers; "auto" starts with
// xor04 + minsw and adds the rest of the ensemble only where they disagree.
// Errors: create_codes_session() returns INVALID_ARGUMENT for bad params/rig;
// sessions return BAD_FRAME for frames of the wrong size or format.
// Thread-safety: thread-bound (docs/threading.md) like every Session; uses rig.threads threads.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "procam/plugin_sdk.hpp"

namespace procam::sl {

// Method names served by create_codes_session, in describe() order.
inline constexpr const char* kCodeMethods[] = {"xor02", "xor04", "minsw", "ensemble", "auto"};

const std::vector<sdk::ParamSpec>& codes_param_specs(const std::string& method);
sdk::MethodDescription describe_codes_method(const std::string& method);
sdk::Error create_codes_session(const sdk::CreateArgs& args, std::unique_ptr<sdk::Session>& out);

}  // namespace procam::sl
