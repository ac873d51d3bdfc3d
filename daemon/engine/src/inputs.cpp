// SPDX-License-Identifier: MIT
// Scan input maps from files (see inputs.hpp).
#include "procam/engine/inputs.hpp"

#include <filesystem>
#include <set>

#include "procam/core/image_io.hpp"

namespace procam::engine {
namespace fs = std::filesystem;

void LoadedInputs::add(std::string name, std::string unit, std::string description, Image image) {
  entries_.push_back({std::move(name), std::move(unit), std::move(description), std::move(image)});
}

std::vector<host::InputImage> LoadedInputs::views() const {
  std::vector<host::InputImage> v;
  v.reserve(entries_.size());
  for (const Entry& e : entries_) v.push_back({e.name, e.unit, e.description, e.image.view()});
  return v;
}

Result<Image> read_input_map(const std::string& name, const std::string& path, const std::string& what,
                             uint32_t cam_width, uint32_t cam_height) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    return Error(Code::not_found, "input '" + name + "': " + what + " ('" + path + "') does not exist",
                 "check the path; procam writes float maps as <output>.exr in the scan folder");
  auto img = read_image(path, /*keep_channels=*/true);
  if (!img) return img.status().with_context("input '" + name + "': reading " + what);
  if (img->channels() != 1)
    return Error(Code::invalid_argument,
                 "input '" + name + "': " + what + " has " + std::to_string(img->channels()) +
                     " channels; an input map has one",
                 "use a 1-channel float map such as a scan's depth_mm.exr");
  if (cam_width != 0 && (img->width() != cam_width || img->height() != cam_height))
    return Error(Code::invalid_argument,
                 "input '" + name + "': " + what + " is " + std::to_string(img->width()) + "x" +
                     std::to_string(img->height()) + ", camera 0 of this rig is " + std::to_string(cam_width) +
                     "x" + std::to_string(cam_height),
                 "use a map from a scan on this rig (inputs are per camera pixel)");
  return img;
}

Result<LoadedInputs> load_input_files(const std::vector<std::string>& items, uint32_t cam_width,
                                      uint32_t cam_height) {
  LoadedInputs out;
  std::set<std::string> seen;
  for (const std::string& item : items) {
    const size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
      return Error(Code::invalid_argument, "--input '" + item + "' is not NAME=FILE",
                   "e.g. --input depth_mm=scan1/depth_mm.exr (procam plugins lists each method's inputs)");
    const std::string name = item.substr(0, eq), path = item.substr(eq + 1);
    if (!seen.insert(name).second)
      return Error(Code::invalid_argument, "--input '" + name + "' is given twice");
    auto img = read_input_map(name, path, "file", cam_width, cam_height);
    if (!img) return img.status();
    out.add(name, "", "file " + fs::path(path).filename().string(), std::move(*img));
  }
  return out;
}

std::pair<uint32_t, uint32_t> camera0_size(const nlohmann::json& rig) {
  try {
    const auto& c = rig.at("cameras").at(0);
    return {c.at("width").get<uint32_t>(), c.at("height").get<uint32_t>()};
  } catch (const std::exception&) {
    return {0, 0};
  }
}

}  // namespace procam::engine
