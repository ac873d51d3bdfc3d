// SPDX-License-Identifier: MIT
// Capture folders -> calibration views (procam/calibration/geometric.hpp):
// each folder holds one board pose under a Gray code with column AND row
// planes (any layout `procam decode --layout` reads). The folder is decoded
// offline with a structured-light method (default gray, rows on) and the
// view's white image is the per-pixel maximum over every frame of the folder:
// the white frame where there is one, else the lit level of the
// pattern/inverse pairs (so layouts without white work too).
// A scan folder with saved frames (frame-r<round>-<index>.png beside the
// scan's outputs and previews) is read as its frames only.
// Thread-safety: one call per PluginHost at a time. Errors: the decode's
// Status (naming the folder), or invalid_argument for a folder without
// images / with mixed sizes.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "procam/calibration/geometric.hpp"
#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::calibration {

struct DecodeOptions {
  uint32_t projector_width = 0, projector_height = 0;  // required
  std::string layout = "procam";                       // frame_layout.hpp names or a JSON file
  std::string plugin = "structured-light", method = "gray";
  nlohmann::json params = {{"rows", true}};
  uint32_t threads = 2;
};

Result<View> decode_capture(const host::PluginHost& host, const std::string& dir, const DecodeOptions& options);

}  // namespace procam::calibration
