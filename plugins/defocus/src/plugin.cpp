// SPDX-License-Identifier: MIT
// ABI glue of the defocus plugin: the exported info struct and create function.
#include "defocus_session.hpp"

PROCAM_DEFINE_PLUGIN("defocus", "0.1.0", "multi-focal,two-focal,single-focal,invariance,calibrate-multi-focal,calibrate-two-focal,calibrate-single-focal", procam::defocus::describe_methods,
                     procam::defocus::create_session);
