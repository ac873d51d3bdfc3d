// SPDX-License-Identifier: MIT
// ABI glue of the media-stereo plugin. `binocular` runs on a rig with two
// calibrated cameras and a projector as the light (binocular_session.hpp).
// `helmholtz` stays library-level (helmholtz.hpp): it needs a light at each
// camera's centre, which a rig with one projector cannot express, so session
// creation refuses it with FAILED_PRECONDITION and says why (the conformance
// suite skips a method that refuses this way; see docs/media-stereo.md).
#include <nlohmann/json.hpp>

#include "binocular_session.hpp"
#include "procam/plugin_sdk.hpp"

namespace {

std::string describe() {
  nlohmann::json methods = nlohmann::json::array();
  methods.push_back(procam::media_stereo::binocular_description().to_json());
  methods.push_back({{"name", "helmholtz"},
                     {"description",
                      "Helmholtz stereo in a scattering medium (thesis Eq. 5.32-5.34); library-level only: needs "
                      ">= 3 reciprocal camera/light pairs (a light at each camera centre), which a one-projector rig "
                      "cannot express"},
                     {"params", nlohmann::json::array()},
                     {"patterns", nullptr}});
  return methods.dump();
}

procam::sdk::Error create(const procam::sdk::CreateArgs& args, std::unique_ptr<procam::sdk::Session>& out) {
  if (args.method == "binocular") return procam::media_stereo::create_binocular_session(args, out);
  return procam::sdk::failed_precondition(
      "media-stereo 'helmholtz' is library-level in this version: it needs reciprocal pairs, i.e. two "
      "camera+light units with coincident centres swapped per pair, and the rig holds one projector; use the "
      "procam_media_stereo_core library (see docs/media-stereo.md)");
}

}  // namespace

PROCAM_DEFINE_PLUGIN("media-stereo", "0.2.0", "binocular,helmholtz", describe, create);
