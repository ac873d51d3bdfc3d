// SPDX-License-Identifier: MIT
// ABI glue of the polarized-striping plugin: the exported info struct and create function.
#include "polarized_striping_session.hpp"

namespace {

std::string describe() { return procam::polarized_striping::describe_methods().dump(); }

}  // namespace

PROCAM_DEFINE_PLUGIN("polarized-striping", "0.1.0", "flood,polarized-flood,striping,polarized-striping", describe,
                     procam::polarized_striping::create_session);
