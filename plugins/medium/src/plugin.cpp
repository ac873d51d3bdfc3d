// SPDX-License-Identifier: MIT
// ABI glue of the medium plugin: the exported info struct and create function.
#include "medium_session.hpp"

namespace {

std::string describe() { return procam::medium::describe_methods().dump(); }

}  // namespace

PROCAM_DEFINE_PLUGIN("medium", "0.1.0", "measure,concentration", describe, procam::medium::create_session);
