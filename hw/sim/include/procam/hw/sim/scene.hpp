// SPDX-License-Identifier: MIT
// Simulated scenes: planes, boxes and spheres with materials, loaded from JSON
// (schema in hw/sim/SCENES.md).
//
// Frame: the world frame is the frame of camera 0 (x right, y down, z forward),
// lengths in millimetres. Irradiance is in the sim's irradiance unit "iu"
// (SCENES.md "Units"), the same unit the projector delivers.
//
// Threads: plain data; loading functions are reentrant. Errors are returned
// (never thrown) and name the file and the JSON field, e.g.
// "configs/scenes/x.json: objects[2].radius_mm: must be > 0".
#pragma once

#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/geometry.hpp"
#include "procam/core/status.hpp"

namespace procam::sim {

// Surface reflectance. Only Lambertian for now; later issues add parameters
// (sub-surface, specular, ...) as further fields with defaults.
struct Material {
  double albedo = 0.5;  // diffuse reflectance, 0..1
};

// Infinite plane, or a w×h rectangle centred on point_mm when finite.
struct Plane {
  Vec3 point_mm;
  Vec3 normal{0, 0, -1};  // unit; the side it points to is "outside" (planes are two-sided)
  bool finite = false;
  double width_mm = 0, height_mm = 0;  // extents along u_axis / v_axis when finite
  Vec3 u_axis{1, 0, 0};  // unit, orthogonal to normal
  Vec3 v_axis{0, 1, 0};  // unit, normal × u_axis
};

// Oriented box: world_from_box = rotation (R = Rz·Ry·Rx of euler_deg) about centre.
struct Box {
  Vec3 center_mm;
  Vec3 size_mm{100, 100, 100};  // full edge lengths along the box's own x, y, z
  Mat3 rotation;                // world_from_box rotation
};

struct Sphere {
  Vec3 center_mm;
  double radius_mm = 100;
};

struct Object {
  std::string name;  // optional label from the file ("" if none)
  std::variant<Plane, Box, Sphere> shape;
  Material material;
};

struct Scene {
  std::string name;         // "name" field, else the file stem
  std::string description;  // free text
  std::string source;       // file it was loaded from ("" when parsed from JSON in memory)
  double ambient = 0;       // ambient irradiance on every surface, iu (unshadowed)
  std::vector<Object> objects;
};

// Parse a scene object. `source` prefixes error messages (normally the path).
Result<Scene> parse_scene(const nlohmann::json& j, const std::string& source);

// Read and parse one scene file. not_found if it does not exist, invalid_argument
// for bad JSON or fields.
Result<Scene> load_scene_file(const std::string& path);

// Resolve `name_or_path` and load it:
//  - absolute path, or one containing '/' or ending in ".json": a file path;
//    relative paths are tried against `base_dir` first, then the working dir;
//  - otherwise a scene name: `<dir>/<name>.json` for each dir in `scene_dirs`,
//    first match wins. not_found lists the directories searched and the scene
//    names they hold.
Result<Scene> load_scene(const std::string& name_or_path,
                         const std::vector<std::string>& scene_dirs,
                         const std::string& base_dir = {});

// Names (file stems) of the scenes in `scene_dirs`, sorted, without duplicates.
std::vector<std::string> list_scenes(const std::vector<std::string>& scene_dirs);

}  // namespace procam::sim
