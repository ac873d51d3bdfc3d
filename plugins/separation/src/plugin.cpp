// SPDX-License-Identifier: MIT
// ABI glue of the separation plugin: the exported info struct and create function.
#include "separation_session.hpp"

namespace {

std::string describe() { return procam::separation::describe_methods().dump(); }

}  // namespace

PROCAM_DEFINE_PLUGIN("separation", "0.1.0", "checker,checker-pair,multi-focal,one-focal-depth,calibrate-one-focal",
                     describe, procam::separation::create_session);
