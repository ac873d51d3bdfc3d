// SPDX-License-Identifier: MIT
// ABI glue of the media-stereo plugin. `binocular` runs on a rig with two
// calibrated cameras and a projector as the light (binocular_session.hpp);
// `helmholtz` on a rig of camera+light units (rig "lights", plugin ABI 3;
// helmholtz_session.hpp), which also holds `medium` (the §5.4.1 image of
// the medium alone that helmholtz takes as an input). They refuse a rig that lacks what they need with
// FAILED_PRECONDITION saying what to use (docs/media-stereo.md).
#include <nlohmann/json.hpp>

#include "binocular_session.hpp"
#include "helmholtz_session.hpp"
#include "procam/plugin_sdk.hpp"

namespace {

std::string describe() {
  nlohmann::json methods = nlohmann::json::array();
  methods.push_back(procam::media_stereo::binocular_description().to_json());
  methods.push_back(procam::media_stereo::helmholtz_description().to_json());
  methods.push_back(procam::media_stereo::medium_description().to_json());
  return methods.dump();
}

procam::sdk::Error create(const procam::sdk::CreateArgs& args, std::unique_ptr<procam::sdk::Session>& out) {
  if (args.method == "binocular") return procam::media_stereo::create_binocular_session(args, out);
  if (args.method == "medium") return procam::media_stereo::create_medium_session(args, out);
  return procam::media_stereo::create_helmholtz_session(args, out);
}

}  // namespace

PROCAM_DEFINE_PLUGIN("media-stereo", "0.3.0", "binocular,helmholtz,medium", describe, create);
