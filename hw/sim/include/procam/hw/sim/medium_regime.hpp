// SPDX-License-Identifier: MIT
// The sim's regime-of-validity table lives in the bottom layer
// (procam/base/medium_regime.hpp) so plugins share it; the sim's names stay.
#pragma once

#include "procam/base/medium_regime.hpp"

namespace procam::sim {
using procam::kRegimeBetaPerMm;
using procam::kRegimeMissedEnergy;
using procam::kRegimeTankDepthMm;
using procam::max_beta_for_error;
using procam::single_scattering_error;
using procam::single_scattering_valid;
}  // namespace procam::sim
