// SPDX-License-Identifier: MIT
// procam::sdk::Outputs — owns a session's named results (maps, scalars, point
// clouds, JSON reports) and exposes them as the C procam_output array.
//
// Names become file names: lower_snake_case ([a-z][a-z0-9_]*), unique, and
// carry their unit where one applies ("depth_mm", "proj_col_px").
// Ownership: the Outputs object owns every byte the view points to; the SDK
// keeps each Outputs it handed to the host alive until session_destroy (the
// ABI promises get_outputs results live that long).
// Errors: the add_* functions throw std::invalid_argument for a plugin bug (bad
// name, duplicate, size mismatch) and std::bad_alloc; the SDK's ABI wrapper
// turns both into error codes.
// Thread-safety: thread-bound (docs/threading.md), like the session that owns it.
#pragma once

#include <cstdint>
#include <deque>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/plugin_abi.h"
#include "procam/sdk/image.hpp"

namespace procam::sdk {

// True for lower_snake_case: [a-z][a-z0-9_]*.
inline bool is_output_name(const std::string& name) noexcept {
  if (name.empty() || name[0] < 'a' || name[0] > 'z') return false;
  for (char ch : name)
    if (!((ch >= 'a' && ch <= 'z') || (ch >= '0' && ch <= '9') || ch == '_')) return false;
  return true;
}

class Outputs {
 public:
  Outputs() = default;
  Outputs(const Outputs&) = delete;
  Outputs& operator=(const Outputs&) = delete;
  // Hands every image's storage to the release hooks, if set.
  ~Outputs() {
    for (Entry& e : entries_) {
      if (e.out.kind != PROCAM_OUTPUT_IMAGE) continue;
      if (release_f32_ != nullptr && !e.f32.empty()) release_f32_(std::move(e.f32));
      if (release_u8_ != nullptr && !e.u8.empty()) release_u8_(std::move(e.u8));
    }
  }

  // Optional: functions that take each F32 / U8 image's storage when this
  // object is destroyed (session_destroy, once the host is done with the
  // maps), so a plugin can reuse memory whose pages are already mapped in its
  // next session instead of having the kernel fault and zero fresh pages.
  // They run on the thread destroying the session and must not throw.
  using ReleaseF32 = void (*)(std::vector<float>&&) noexcept;
  using ReleaseU8 = void (*)(std::vector<uint8_t>&&) noexcept;
  void set_release(ReleaseF32 f32, ReleaseU8 u8) noexcept {
    release_f32_ = f32;
    release_u8_ = u8;
  }

  // A map of width x height single-channel pixels, row-major. F32 maps use
  // NaN where invalid (ABI rule). `pixels.size()` must be width*height.
  void add_image(std::string name, std::string unit, std::string description, uint32_t width,
                 uint32_t height, std::vector<float> pixels) {
    check_size(name, pixels.size(), width, height);
    Entry& e = add(std::move(name), PROCAM_OUTPUT_IMAGE, std::move(unit), std::move(description));
    e.f32 = std::move(pixels);
    e.out.image = gray_view(static_cast<const float*>(nullptr), width, height);  // data: view()
  }
  void add_image(std::string name, std::string unit, std::string description, uint32_t width,
                 uint32_t height, std::vector<uint8_t> pixels) {
    check_size(name, pixels.size(), width, height);
    Entry& e = add(std::move(name), PROCAM_OUTPUT_IMAGE, std::move(unit), std::move(description));
    e.u8 = std::move(pixels);
    e.out.image = gray_view(static_cast<const uint8_t*>(nullptr), width, height);
  }
  void add_image(std::string name, std::string unit, std::string description, uint32_t width,
                 uint32_t height, std::vector<uint16_t> pixels, uint32_t bit_depth = 16) {
    check_size(name, pixels.size(), width, height);
    Entry& e = add(std::move(name), PROCAM_OUTPUT_IMAGE, std::move(unit), std::move(description));
    e.u16 = std::move(pixels);
    e.out.image = gray_view(static_cast<const uint16_t*>(nullptr), width, height, bit_depth);
  }

  void add_scalar(std::string name, std::string unit, std::string description, double value) {
    Entry& e = add(std::move(name), PROCAM_OUTPUT_SCALAR, std::move(unit), std::move(description));
    e.out.scalar = value;
  }

  // A point cloud: `points.size() / stride` rows of `stride` floats; the first
  // three are x, y, z in mm in the camera frame. `fields` names every column,
  // comma-separated ("x,y,z,intensity"), so it must list `stride` names.
  void add_points(std::string name, std::string description, std::string fields, uint32_t stride,
                  std::vector<float> points) {
    size_t field_count = 1;
    for (char ch : fields) field_count += (ch == ',') ? 1u : 0u;
    if (stride < 3 || field_count != stride || fields.rfind("x,y,z", 0) != 0)
      throw std::invalid_argument("output '" + name +
                                  "': fields must start with x,y,z and list stride names");
    if (points.size() % stride != 0)
      throw std::invalid_argument("output '" + name + "': float count is not a multiple of stride");
    Entry& e = add(std::move(name), PROCAM_OUTPUT_POINTS, "mm", std::move(description));
    e.fields = std::move(fields);
    e.f32 = std::move(points);
    e.out.point_count = e.f32.size() / stride;
    e.out.point_stride = stride;
  }

  // A JSON document (the caller makes sure it is valid JSON, e.g. json::dump()).
  void add_json(std::string name, std::string description, std::string json) {
    Entry& e = add(std::move(name), PROCAM_OUTPUT_JSON, "", std::move(description));
    e.json = std::move(json);
  }

  // A categorical map (one class value per pixel) and its key: the image gets
  // unit "class" and a JSON output "<name>_legend" =
  // {"classes": [{"value", "name", "meaning"}, ...]} names each value, so
  // hosts can show a coloured preview with a key instead of raw numbers.
  struct ClassName {
    uint8_t value;
    std::string name;     // short, lower_snake_case, e.g. "interreflection"
    std::string meaning;  // one line for the key
  };
  void add_class_map(const std::string& name, std::string description, uint32_t width, uint32_t height,
                     std::vector<uint8_t> pixels, const std::vector<ClassName>& classes) {
    add_image(name, "class", std::move(description), width, height, std::move(pixels));
    nlohmann::json legend = {{"classes", nlohmann::json::array()}};
    for (const ClassName& c : classes)
      legend["classes"].push_back({{"value", c.value}, {"name", c.name}, {"meaning", c.meaning}});
    add_json(name + "_legend", "the classes of " + name + " (value, name, meaning)", legend.dump());
  }

  uint32_t size() const noexcept { return static_cast<uint32_t>(entries_.size()); }
  bool contains(const std::string& name) const noexcept {
    for (const Entry& e : entries_)
      if (e.name == name) return true;
    return false;
  }

  // The C view; valid while this object lives and is not modified.
  const procam_output* view() {
    view_.clear();
    view_.reserve(entries_.size());
    for (Entry& e : entries_) {
      procam_output o = e.out;
      o.name = e.name.c_str();
      o.unit = e.unit.c_str();
      o.description = e.description.c_str();
      if (o.kind == PROCAM_OUTPUT_IMAGE)
        o.image.data = !e.f32.empty()   ? static_cast<const void*>(e.f32.data())
                       : !e.u16.empty() ? static_cast<const void*>(e.u16.data())
                                        : static_cast<const void*>(e.u8.data());
      if (o.kind == PROCAM_OUTPUT_POINTS) {
        o.points = e.f32.data();
        o.point_fields = e.fields.c_str();
      }
      if (o.kind == PROCAM_OUTPUT_JSON) o.json = e.json.c_str();
      view_.push_back(o);
    }
    return view_.data();
  }

 private:
  struct Entry {
    std::string name, unit, description, fields, json;
    std::vector<float> f32;
    std::vector<uint8_t> u8;
    std::vector<uint16_t> u16;
    procam_output out{};
  };

  Entry& add(std::string name, procam_output_kind kind, std::string unit, std::string description) {
    if (!is_output_name(name))
      throw std::invalid_argument("output name '" + name + "' is not lower_snake_case");
    if (contains(name)) throw std::invalid_argument("output name '" + name + "' used twice");
    Entry e;
    e.name = std::move(name);
    e.unit = std::move(unit);
    e.description = std::move(description);
    e.out.kind = kind;
    entries_.push_back(std::move(e));
    return entries_.back();
  }
  static void check_size(const std::string& name, size_t n, uint32_t width, uint32_t height) {
    if (width == 0 || height == 0 || n != size_t{width} * height)
      throw std::invalid_argument("output '" + name + "': pixel count does not match " +
                                  std::to_string(width) + "x" + std::to_string(height));
  }

  std::deque<Entry> entries_;  // deque: entries never move once added
  std::vector<procam_output> view_;
  ReleaseF32 release_f32_ = nullptr;
  ReleaseU8 release_u8_ = nullptr;
};

}  // namespace procam::sdk
