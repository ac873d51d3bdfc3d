// SPDX-License-Identifier: MIT
// Test helpers for hw/sim: temp files, config loading, and independent
// reference geometry (written separately from the code under test).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/base/geometry.hpp"

namespace procam::sim::test {

inline std::string source_dir() { return PROCAM_SOURCE_DIR; }
inline std::string configs_dir() { return source_dir() + "/configs"; }

inline nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return nlohmann::json::parse(ss.str());
}

// Removes the directories made by temp_dir() when the test binary exits.
struct TempDirs {
  std::vector<std::string> dirs;
  ~TempDirs() {
    std::error_code ec;
    for (const auto& d : dirs) std::filesystem::remove_all(d, ec);
  }
};
inline TempDirs& temp_dirs() {
  static TempDirs t;
  return t;
}

// A fresh, unique temporary directory per call (removed at exit).
inline std::string temp_dir(const std::string& tag) {
  static int counter = 0;
  auto p = std::filesystem::temp_directory_path() /
           ("procam_sim_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  temp_dirs().dirs.push_back(p.string());
  return p.string();
}

inline std::string write_text(const std::string& dir, const std::string& name, const std::string& text) {
  const std::string path = dir + "/" + name;
  std::ofstream(path) << text;
  return path;
}

// Reference ray/plane intersection: s with dot(n, o + s d - p) = 0, if s > 0.
inline std::optional<double> ref_ray_plane(const Vec3& o, const Vec3& d, const Vec3& p, const Vec3& n) {
  const double den = n.x * d.x + n.y * d.y + n.z * d.z;
  if (den == 0) return std::nullopt;
  const Vec3 po{p.x - o.x, p.y - o.y, p.z - o.z};
  const double s = (n.x * po.x + n.y * po.y + n.z * po.z) / den;
  if (!(s > 0)) return std::nullopt;
  return s;
}

// Reference box intersection by testing each of the 6 face rectangles
// independently (no slab test). R = world_from_box rotation, half = half sizes.
// Returns the nearest s > s_min and the face's outward normal.
inline std::optional<double> ref_ray_box(const Vec3& o, const Vec3& d, const Vec3& c, const Mat3& R,
                                         const Vec3& half, double s_min = 1e-9, Vec3* normal = nullptr) {
  std::optional<double> best;
  const Vec3 axes[3] = {R * Vec3{1, 0, 0}, R * Vec3{0, 1, 0}, R * Vec3{0, 0, 1}};
  const double h[3] = {half.x, half.y, half.z};
  for (int a = 0; a < 3; ++a) {
    for (double sign : {-1.0, 1.0}) {
      const Vec3 n = axes[a] * sign;
      const Vec3 p = c + n * h[a];
      auto s = ref_ray_plane(o, d, p, n);
      if (!s || *s <= s_min) continue;
      const Vec3 x = o + d * *s - c;
      bool inside = true;
      for (int b = 0; b < 3; ++b) {
        if (b == a) continue;
        if (std::abs(dot(x, axes[b])) > h[b] + 1e-9) inside = false;
      }
      if (inside && (!best || *s < *best)) {
        best = s;
        if (normal) *normal = n;
      }
    }
  }
  return best;
}

}  // namespace procam::sim::test
