// SPDX-License-Identifier: MIT
// procam::sdk::Inputs — the scan inputs a session receives at creation
// (plugin ABI 2, plugin_abi.h "Scan inputs"): outputs of an earlier scan, such
// as its depth_mm map, that a method declared in describe()'s "inputs"
// (sdk::MethodDescription::inputs, method.hpp).
//
// Use in a factory (CreateArgs::inputs):
//   std::vector<float> depth;
//   if (sdk::Error e = args.inputs.image_f32("depth_mm", cam_w, cam_h, depth); !e.ok()) return e;
//
// Ownership: an Inputs built by the SDK from the ABI call is a set of views
// into host memory valid ONLY while the factory runs; image_f32() copies.
// Never keep an Inputs (or a pointer into it) in a session. An Inputs built
// in a test with add_image_f32() owns its maps (copies share them).
// Values: image_f32() turns every non-finite value (NaN, ±inf) into NaN, so
// a finite value is always a valid pixel and NaN always an invalid one.
// Errors: PROCAM_ERR_INVALID_ARGUMENT naming the input and saying how to
// supply it (missing / not an F32 image / wrong size).
// Thread-safety: reentrant (const members may run concurrently on one object).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "procam/plugin_abi.h"
#include "procam/sdk/error.hpp"
#include "procam/sdk/image.hpp"

namespace procam::sdk {

class Inputs {
 public:
  Inputs() = default;

  // Views of the host's array (the SDK's session_create2 glue). Entries must
  // outlive this object; NULL with count 0 is an empty set.
  static Inputs from_abi(const procam_output* inputs, uint32_t count) {
    Inputs in;
    for (uint32_t i = 0; inputs != nullptr && i < count; ++i) {
      const procam_output& o = inputs[i];
      if (o.name == nullptr) continue;  // the host never sends one; ignore rather than crash
      in.items_.push_back({o.name, o.kind, o.image});
    }
    return in;
  }

  // Tests and offline tools: adds an owned width x height F32 map (row-major,
  // `values.size()` must be width*height; otherwise the entry is added with
  // no pixels and image_f32() reports it as malformed).
  void add_image_f32(std::string name, uint32_t width, uint32_t height, std::vector<float> values) {
    auto data = std::make_shared<std::vector<float>>(std::move(values));
    const bool fits = data->size() == size_t{width} * height;
    const procam_image img = gray_view(fits ? data->data() : nullptr, width, height);
    owned_.push_back(std::move(data));
    items_.push_back({std::move(name), PROCAM_OUTPUT_IMAGE, img});
  }

  bool has(const std::string& name) const { return find(name) != nullptr; }
  bool empty() const { return items_.empty(); }
  size_t size() const { return items_.size(); }
  // Names of the inputs present, in the host's order (for messages).
  std::vector<std::string> names() const {
    std::vector<std::string> n;
    for (const Item& it : items_) n.push_back(it.name);
    return n;
  }

  // Copies input `name`, which must be a 1-channel F32 map of exactly
  // width x height, into `out` (row-major, resized). Non-finite values
  // become NaN. `out` is left empty on error.
  Error image_f32(const std::string& name, uint32_t width, uint32_t height,
                  std::vector<float>& out) const {
    out.clear();
    const Item* it = find(name);
    const std::string how =
        "supply it as \"inputs\": {\"" + name + "\": {\"scan\": \"<scan id>\", \"output\": \"" + name +
        "\"}} in the scan request (procam scan --input " + name +
        "=SCAN_ID), or offline with procam decode --input " + name + "=FILE.exr";
    if (it == nullptr)
      return invalid_argument("input '" + name + "' is missing: " + how);
    const procam_image& im = it->image;
    if (it->kind != PROCAM_OUTPUT_IMAGE || im.pixel_type != PROCAM_PIXEL_F32 || im.channels != 1)
      return invalid_argument("input '" + name +
                              "' is not a 1-channel float (F32) image; name a float map output such "
                              "as depth_mm (stored as .exr), not a PNG mask or a scalar");
    if (im.width != width || im.height != height)
      return invalid_argument("input '" + name + "' is " + std::to_string(im.width) + "x" +
                              std::to_string(im.height) + ", this method needs " +
                              std::to_string(width) + "x" + std::to_string(height) +
                              " (camera 0's size): use a map from a scan on this rig");
    if (im.data == nullptr || im.stride_bytes < size_t{width} * sizeof(float))
      return invalid_argument("input '" + name + "' has no pixels or a row stride shorter than " +
                              std::to_string(width) + " floats");
    out.resize(size_t{width} * height);
    for (uint32_t y = 0; y < height; ++y) {
      const auto* row = static_cast<const unsigned char*>(im.data) + size_t{y} * im.stride_bytes;
      float* dst = out.data() + size_t{y} * width;
      std::memcpy(dst, row, size_t{width} * sizeof(float));  // rows may be unaligned
      for (uint32_t x = 0; x < width; ++x)
        if (!std::isfinite(dst[x])) dst[x] = std::nanf("");
    }
    return ok();
  }

 private:
  struct Item {
    std::string name;
    uint32_t kind = 0;  // procam_output_kind
    procam_image image{};
  };
  const Item* find(const std::string& name) const {
    for (const Item& it : items_)
      if (it.name == name) return &it;
    return nullptr;
  }

  std::vector<Item> items_;
  std::vector<std::shared_ptr<const std::vector<float>>> owned_;  // add_image_f32's maps
};

}  // namespace procam::sdk
