// SPDX-License-Identifier: MIT
// ABI glue of the null plugin: the exported info struct and create function.
#include "null_session.hpp"

namespace {

std::string describe() { return procam::null_plugin::describe_methods().dump(); }

}  // namespace

PROCAM_DEFINE_PLUGIN("null", "0.1.0", "null,echo", describe, procam::null_plugin::create_session);
