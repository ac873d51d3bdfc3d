// SPDX-License-Identifier: MIT
// The rig description handed to plugins (plugin_abi.h session_create's
// rig_json), built from a live Rig or straight from a rig config file.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"
#include "procam/hw/rig.hpp"

namespace procam::engine {

// {"projector":{"width","height","intrinsics"},"cameras":[{"width","height",
//  "bit_depth","calibration":{"intrinsics","cam_from_proj"}}],"threads":n}
nlohmann::json plugin_rig_json(hw::Rig& rig, unsigned threads);

// Same, from a rig config (configs/rigs/*.json) without opening any hardware:
// used by offline decoding. Errors name the missing/invalid field.
Result<nlohmann::json> plugin_rig_json_from_config(const nlohmann::json& rig_config,
                                                   unsigned threads);

// Reads a JSON file; errors name the file and the parse position.
Result<nlohmann::json> read_json_file(const std::string& path);

// Writes bytes to `path` atomically (temporary sibling + fsync + rename).
Status write_file_atomic(const std::string& path, const std::string& bytes);

}  // namespace procam::engine
