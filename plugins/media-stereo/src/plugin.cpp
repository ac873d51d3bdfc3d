// SPDX-License-Identifier: MIT
// ABI glue of the media-stereo plugin. The numerical core (binocular.hpp,
// helmholtz.hpp, medium_fit.hpp) is library-level in this version: the
// methods are declared and described, but session creation refuses every rig
// with FAILED_PRECONDITION and says why (two cameras with a light at each
// camera position are needed, and the rig/plan wiring is not done yet; see
// README.md). The conformance suite skips a method that refuses this way.
#include <nlohmann/json.hpp>

#include "procam/plugin_sdk.hpp"

namespace {

std::string describe() {
  nlohmann::json methods = nlohmann::json::array();
  methods.push_back({{"name", "binocular"},
                     {"description",
                      "binocular stereo in a scattering medium (thesis Eq. 5.22-5.23); library-level only: needs "
                      "two cameras and a fixed point light, not yet wired to a rig"},
                     {"params", nlohmann::json::array()},
                     {"patterns", nullptr}});
  methods.push_back({{"name", "helmholtz"},
                     {"description",
                      "Helmholtz stereo in a scattering medium (thesis Eq. 5.32-5.34); library-level only: needs "
                      ">= 3 reciprocal camera/light pairs, not yet wired to a rig"},
                     {"params", nlohmann::json::array()},
                     {"patterns", nullptr}});
  return methods.dump();
}

procam::sdk::Error create(const procam::sdk::CreateArgs& args, std::unique_ptr<procam::sdk::Session>&) {
  return procam::sdk::failed_precondition(
      "media-stereo '" + std::string(args.method) +
      "' is library-level in this version: it needs two camera+light units (a point light at each camera "
      "position) and the plan/rig wiring is not done; use the procam_media_stereo_core library (see "
      "plugins/media-stereo/README.md)");
}

}  // namespace

PROCAM_DEFINE_PLUGIN("media-stereo", "0.1.0", "binocular,helmholtz", describe, create);
