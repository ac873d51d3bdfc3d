// SPDX-License-Identifier: MIT
// Scan inputs (plugin ABI 2, proto/PROTOCOL.md 5.4 "inputs"): maps read from
// files -- a finished scan's stored output, or a file given to
// `procam decode --input name=FILE` -- and the views create_session takes.
//
// Format: what procam writes F32 maps as (PROTOCOL.md 10, "exr-f32"): a
// 1-channel float OpenEXR; any file OpenImageIO reads works (TIFF float,
// PFM, ...), but only 1-channel float data is an image_f32 input (an 8/16-bit
// PNG is read and then refused by the plugin host's kind check).
// Size: every input map must match camera 0 (the maps are per camera pixel).
// Ownership: LoadedInputs owns the pixels; views() point into it and stay
// valid while it lives and is not modified. Errors name the input and the
// file, and say what to do. Thread-safety: reentrant.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "procam/core/image.hpp"
#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::engine {

class LoadedInputs {
 public:
  void add(std::string name, std::string unit, std::string description, Image image);
  bool empty() const { return entries_.empty(); }
  // One view per added map, in the order added; valid until the next add().
  std::vector<host::InputImage> views() const;

 private:
  struct Entry {
    std::string name, unit, description;
    Image image;
  };
  std::vector<Entry> entries_;
};

// Reads input `name` from `path` (read_image, channels kept). Fails with
// not_found / io_error / corrupt_data when the file cannot be read, and
// invalid_argument when it has more than one channel or is not
// cam_width x cam_height (`what` names its origin in messages, e.g.
// "output depth_mm of scan X" or "file d.exr").
Result<Image> read_input_map(const std::string& name, const std::string& path, const std::string& what,
                             uint32_t cam_width, uint32_t cam_height);

// Offline: `name=FILE` items (procam decode --input) read with
// read_input_map. invalid_argument for a malformed item or a name given twice.
Result<LoadedInputs> load_input_files(const std::vector<std::string>& items, uint32_t cam_width,
                                      uint32_t cam_height);

// Camera 0's size from a plugin rig description (rig_json.hpp); {0, 0} when absent.
std::pair<uint32_t, uint32_t> camera0_size(const nlohmann::json& plugin_rig);

}  // namespace procam::engine
