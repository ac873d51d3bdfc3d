// SPDX-License-Identifier: MIT
// What a plugin returns (plans, outputs), checked and copied into the host's
// types. Shared by the in-process Session and the worker proxy, which runs
// the same checks again on what a worker process sends back: the daemon
// never trusts a worker more than a plugin.
//
// Views in the results (patterns, images, points) point into the memory the
// C structs point to; strings are copied. Nothing throws except
// std::bad_alloc (callers catch).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/plugin_abi.h"

namespace procam::host::detail {

// A plan from next_plan (returned 1), for round `round` (1-based, for
// messages). `who` is "plugin '<name>'". plugin_error naming the problem.
// `abi`: the ABI the plugin was built for; an ABI 1/2 plan's frames are read
// through procam_pattern_frame_v2 (their stride) and get light_index 0
// (plugin_abi.h "Version history", 3).
Result<Plan> plan_from_abi(const procam_plan* plan, const std::string& who, uint32_t round,
                           uint32_t abi = PROCAM_PLUGIN_ABI_VERSION);

// The outputs from get_outputs.
Result<std::vector<Output>> outputs_from_abi(const procam_output* outs, uint32_t count,
                                            const std::string& who);

}  // namespace procam::host::detail
