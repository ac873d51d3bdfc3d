// SPDX-License-Identifier: MIT
// The rig description a host passes to session_create, parsed into procam
// calibration types (procam/base/calibration.hpp).
//
// Format (fixed; proto/PROTOCOL.md "Rig description"):
//   {"projector": {"width": 1280, "height": 800,
//                  "intrinsics": {"width":1280,"height":800,"fx":..,"fy":..,"cx":..,"cy":..}},
//    "cameras": [{"width": 1280, "height": 800, "bit_depth": 8,
//                 "calibration": {"intrinsics": {...},
//                                 "cam_from_proj": {"rotation":[r00..r22],
//                                                   "translation_mm":[x,y,z]}}}],
//    "threads": 2,
//    "calibration_tables": {"defocus.multi-focal": {...}}}
// "intrinsics" and "calibration" may be absent (an uncalibrated rig: plugins
// can still decode correspondences but not depth); when present they must
// match the device size. "threads" is optional (default 1; 0 = all cores).
// "calibration_tables" is optional: table name -> table JSON
// (procam/sdk/calibration_table.hpp); parse_rig checks only that it is an
// object of objects, a plugin parses the tables it uses with parse_table.
// Errors: PROCAM_ERR_INVALID_ARGUMENT naming the field ("rig: cameras[0].bit_depth
// must be an integer in 1..16 or 32, got \"8\""). Thread-safety: reentrant.
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/base/calibration.hpp"
#include "procam/sdk/error.hpp"
#include "procam/sdk/params.hpp"

namespace procam::sdk {

struct RigCamera {
  uint32_t width = 0, height = 0;  // pixels
  uint32_t bit_depth = 8;          // significant bits of integer frames; 32 = float camera
  bool calibrated = false;         // calibration below is meaningful
  CameraCalibration calibration;   // intrinsics + cam_from_proj (x_cam = R x_proj + t, mm)
};

struct Rig {
  uint32_t projector_width = 0, projector_height = 0;  // pixels
  bool projector_calibrated = false;
  Intrinsics projector;                                // valid when projector_calibrated
  std::vector<RigCamera> cameras;                      // at least one
  uint32_t threads = 1;                                // host's suggestion, >= 1
  nlohmann::json calibration_tables = nlohmann::json::object();  // name -> table JSON

  // The table called `name`, or nullptr when the rig has none.
  const nlohmann::json* table(const std::string& name) const {
    auto it = calibration_tables.find(name);
    return it == calibration_tables.end() ? nullptr : &*it;
  }

  // Projector and camera `i` are both calibrated: triangulation is possible.
  bool can_triangulate(size_t i) const {
    return projector_calibrated && i < cameras.size() && cameras[i].calibrated;
  }
};

namespace detail {
// Reads a positive 32-bit integer field `key` of `j`, or fails naming `path`.
inline Error rig_uint(const nlohmann::json& j, const char* key, const std::string& path,
                      uint32_t lo, uint32_t hi, uint32_t& out) {
  const std::string where = "rig: " + path + key;
  if (!j.is_object() || !j.contains(key)) return invalid_argument(where + " is missing");
  const nlohmann::json& v = j.at(key);
  if (!v.is_number_integer() || v.get<int64_t>() < lo || v.get<int64_t>() > hi)
    return invalid_argument(where + " must be an integer in " + std::to_string(lo) + ".." +
                            std::to_string(hi) + ", got " + shown(v));
  out = static_cast<uint32_t>(v.get<int64_t>());
  return ok();
}
inline Error rig_intrinsics(const nlohmann::json& j, const std::string& path, uint32_t width,
                            uint32_t height, Intrinsics& out) {
  try {
    j.get_to(out);
  } catch (const nlohmann::json::exception& e) {
    return invalid_argument("rig: " + path + " is malformed (" + e.what() + ")");
  }
  if (!out.valid() || !std::isfinite(out.cx) || !std::isfinite(out.cy) ||
      !std::isfinite(out.fx) || !std::isfinite(out.fy))
    return invalid_argument("rig: " + path + " needs positive width, height, fx, fy");
  if (out.width != width || out.height != height)
    return invalid_argument("rig: " + path + " is for " + std::to_string(out.width) + "x" +
                            std::to_string(out.height) + " but the device is " +
                            std::to_string(width) + "x" + std::to_string(height));
  return ok();
}
}  // namespace detail

inline Error parse_rig(const nlohmann::json& j, Rig& rig) {
  rig = Rig{};
  if (!j.is_object()) return invalid_argument("rig description must be a JSON object");
  if (!j.contains("projector")) return invalid_argument("rig: projector is missing");
  const nlohmann::json& p = j.at("projector");
  constexpr uint32_t kMaxSide = 1u << 16;
  if (Error e = detail::rig_uint(p, "width", "projector.", 1, kMaxSide, rig.projector_width);
      !e.ok())
    return e;
  if (Error e = detail::rig_uint(p, "height", "projector.", 1, kMaxSide, rig.projector_height);
      !e.ok())
    return e;
  if (p.contains("intrinsics")) {
    if (Error e = detail::rig_intrinsics(p.at("intrinsics"), "projector.intrinsics",
                                         rig.projector_width, rig.projector_height, rig.projector);
        !e.ok())
      return e;
    rig.projector_calibrated = true;
  }
  if (!j.contains("cameras") || !j.at("cameras").is_array() || j.at("cameras").empty())
    return invalid_argument("rig: cameras must be a non-empty array");
  const nlohmann::json& cams = j.at("cameras");
  for (size_t i = 0; i < cams.size(); ++i) {
    const std::string path = "cameras[" + std::to_string(i) + "].";
    const nlohmann::json& c = cams.at(i);
    RigCamera cam;
    if (Error e = detail::rig_uint(c, "width", path, 1, kMaxSide, cam.width); !e.ok()) return e;
    if (Error e = detail::rig_uint(c, "height", path, 1, kMaxSide, cam.height); !e.ok()) return e;
    if (c.contains("bit_depth")) {
      const nlohmann::json& b = c.at("bit_depth");
      if (!b.is_number_integer() ||
          !((b.get<int64_t>() >= 1 && b.get<int64_t>() <= 16) || b.get<int64_t>() == 32))
        return invalid_argument("rig: " + path + "bit_depth must be an integer in 1..16 or 32, got " +
                                detail::shown(b));
      cam.bit_depth = static_cast<uint32_t>(b.get<int64_t>());
    }
    if (c.contains("calibration")) {
      const nlohmann::json& cal = c.at("calibration");
      if (!cal.is_object() || !cal.contains("intrinsics") || !cal.contains("cam_from_proj"))
        return invalid_argument("rig: " + path + "calibration needs intrinsics and cam_from_proj");
      if (Error e = detail::rig_intrinsics(cal.at("intrinsics"), path + "calibration.intrinsics",
                                           cam.width, cam.height, cam.calibration.intrinsics);
          !e.ok())
        return e;
      try {
        cal.at("cam_from_proj").get_to(cam.calibration.cam_from_proj);
      } catch (const nlohmann::json::exception& e) {
        return invalid_argument("rig: " + path + "calibration.cam_from_proj is malformed (" +
                                e.what() + ")");
      }
      cam.calibrated = true;
    }
    rig.cameras.push_back(cam);
  }
  if (j.contains("threads")) {
    const nlohmann::json& t = j.at("threads");
    if (!t.is_number_integer() || t.get<int64_t>() < 0 || t.get<int64_t>() > 1024)
      return invalid_argument("rig: threads must be an integer in 0..1024, got " +
                              detail::shown(t));
    rig.threads = static_cast<uint32_t>(t.get<int64_t>());
    if (rig.threads == 0) rig.threads = std::max(1u, std::thread::hardware_concurrency());
  }
  if (j.contains("calibration_tables")) {
    const nlohmann::json& t = j.at("calibration_tables");
    if (!t.is_object())
      return invalid_argument("rig: calibration_tables must be an object (table name -> table)");
    for (const auto& [name, table] : t.items())
      if (!table.is_object())
        return invalid_argument("rig: calibration_tables." + name + " must be a table object");
    rig.calibration_tables = t;
  }
  return ok();
}

}  // namespace procam::sdk
