// SPDX-License-Identifier: MIT
// Rig calibration (pinhole intrinsics with optional lens distortion +
// cam_from_proj) and its JSON form, the
// one used in rig configs, in the rig description sent to plugins, and on the
// wire (proto/PROTOCOL.md "Rig description"). Header-only so plugins can use it.
//
// Conventions: pixel centres at integer coordinates (OpenCV); the camera frame
// has x right, y down, z forward; lengths in mm. A projector pixel column c is
// the plane through the projector centre containing the rays x_p/z_p = (c-cx)/fx.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/base/geometry.hpp"

namespace procam {

struct Intrinsics {
  uint32_t width = 0, height = 0;  // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  // Lens distortion, OpenCV's 5-coefficient model (k1, k2, p1, p2, k3) on
  // normalised coordinates (x, y) = ((u-cx)/fx, (v-cy)/fy) of the ideal
  // pinhole: r^2 = x^2 + y^2, radial = 1 + k1 r^2 + k2 r^4 + k3 r^6,
  //   x_d = x radial + 2 p1 x y + p2 (r^2 + 2 x^2),
  //   y_d = y radial + p1 (r^2 + 2 y^2) + 2 p2 x y.
  // All zero (the default): a pinhole, and every function below is exact.
  std::array<double, 5> distortion{};

  bool distorted() const {
    for (double d : distortion)
      if (d != 0.0) return true;
    return false;
  }
  // Ideal normalised (x, y) -> distorted normalised (the model above).
  void distort(double x, double y, double& xd, double& yd) const {
    const double k1 = distortion[0], k2 = distortion[1], p1 = distortion[2], p2 = distortion[3],
                 k3 = distortion[4];
    const double r2 = x * x + y * y;
    const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
  }
  // Pixel (u, v) -> ideal normalised (x, y): the inverse of distort by
  // fixed-point iteration (OpenCV's scheme, 20 steps: converges to < 1e-9
  // for any lens whose distortion is monotonic over the image).
  void undistort(double u, double v, double& x, double& y) const {
    const double xd = (u - cx) / fx, yd = (v - cy) / fy;
    x = xd;
    y = yd;
    if (!distorted()) return;
    const double k1 = distortion[0], k2 = distortion[1], p1 = distortion[2], p2 = distortion[3],
                 k3 = distortion[4];
    for (int i = 0; i < 20; ++i) {
      const double r2 = x * x + y * y;
      const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
      const double dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
      const double dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
      x = (xd - dx) / radial;
      y = (yd - dy) / radial;
    }
  }
  // Unit-depth ray direction through pixel (u, v): (x/z, y/z, 1), undistorted.
  Vec3 ray(double u, double v) const {
    if (!distorted()) return {(u - cx) / fx, (v - cy) / fy, 1.0};
    double x, y;
    undistort(u, v, x, y);
    return {x, y, 1.0};
  }
  // Projection of a point in this device's frame (with distortion); z must be > 0.
  void project(const Vec3& p, double& u, double& v) const {
    double x = p.x / p.z, y = p.y / p.z;
    if (distorted()) distort(p.x / p.z, p.y / p.z, x, y);
    u = fx * x + cx;
    v = fy * y + cy;
  }
  bool valid() const { return width > 0 && height > 0 && fx > 0 && fy > 0; }
};

// One camera of the rig, calibrated against the projector.
struct CameraCalibration {
  Intrinsics intrinsics;
  Rigid3 cam_from_proj;  // x_cam = R * x_proj + t
};

// Triangulate camera pixel (u, v) against projector column `col` (continuous,
// pixel centres at integers, of the ideal undistorted projector image: see
// sdk/triangulate.hpp for correcting a distorted projector's columns with
// the decoded row). Returns the point in the camera frame, or
// nullopt when the ray is (nearly) parallel to the column plane or the point
// lies behind either device. Ray–plane intersection:
//   plane normal in the projector frame n_p = (fx_p, 0, -(col - cx_p)) through
//   the projector centre; in the camera frame n = R n_p through t, so
//   s = (n·t) / (n·d) for the camera ray x = s d.
inline std::optional<Vec3> triangulate_column(const CameraCalibration& cam,
                                              const Intrinsics& proj, double u, double v,
                                              double col) {
  const Vec3 d = cam.intrinsics.ray(u, v);
  const Vec3 n_p{proj.fx, 0.0, -(col - proj.cx)};
  const Vec3 n = cam.cam_from_proj.rotation * n_p;
  const Vec3& t = cam.cam_from_proj.translation_mm;
  const double denom = dot(n, d);
  if (std::abs(denom) < 1e-12 * norm(n) * norm(d)) return std::nullopt;
  const double s = dot(n, t) / denom;
  if (!(s > 0) || !std::isfinite(s)) return std::nullopt;
  const Vec3 x = d * s;
  const Vec3 x_proj = cam.cam_from_proj.inverse() * x;
  if (!(x_proj.z > 0)) return std::nullopt;
  return x;
}

// ---- JSON ----------------------------------------------------------------
// Intrinsics: {"width":1280,"height":800,"fx":..,"fy":..,"cx":..,"cy":..,
//              "distortion":[k1,k2,p1,p2,k3]}  ("distortion" optional: 0, 4 or
//              5 numbers; written only when non-zero)
// Rigid3:     {"rotation":[r00,r01,r02,r10,...,r22],"translation_mm":[x,y,z]}
//             or {"euler_deg":[rx,ry,rz],"translation_mm":[...]} (R = Rz Ry Rx)
// These throw nlohmann::json exceptions on bad input: call them inside a
// try-block at the boundary and turn failures into a Status.
inline void to_json(nlohmann::json& j, const Intrinsics& k) {
  j = {{"width", k.width}, {"height", k.height}, {"fx", k.fx},
       {"fy", k.fy},       {"cx", k.cx},         {"cy", k.cy}};
  if (k.distorted()) j["distortion"] = k.distortion;
}
inline void from_json(const nlohmann::json& j, Intrinsics& k) {
  j.at("width").get_to(k.width);
  j.at("height").get_to(k.height);
  j.at("fx").get_to(k.fx);
  j.at("fy").get_to(k.fy);
  j.at("cx").get_to(k.cx);
  j.at("cy").get_to(k.cy);
  k.distortion = {};
  if (j.contains("distortion")) {
    const auto d = j.at("distortion").get<std::vector<double>>();
    if (d.size() != 4 && d.size() != 5)
      throw nlohmann::json::other_error::create(
          501, "distortion must be [k1, k2, p1, p2] or [k1, k2, p1, p2, k3], got " +
                   std::to_string(d.size()) + " numbers", &j);
    for (size_t i = 0; i < d.size(); ++i) {
      if (!std::isfinite(d[i]))
        throw nlohmann::json::other_error::create(501, "distortion coefficients must be finite", &j);
      k.distortion[i] = d[i];
    }
  }
}
inline void to_json(nlohmann::json& j, const Rigid3& r) {
  j = {{"rotation", r.rotation.m},
       {"translation_mm", {r.translation_mm.x, r.translation_mm.y, r.translation_mm.z}}};
}
inline void from_json(const nlohmann::json& j, Rigid3& r) {
  if (j.contains("euler_deg")) {
    auto e = j.at("euler_deg").get<std::array<double, 3>>();
    r.rotation = rotation_from_euler_deg(e[0], e[1], e[2]);
  } else {
    r.rotation.m = j.at("rotation").get<std::array<double, 9>>();
  }
  auto t = j.at("translation_mm").get<std::array<double, 3>>();
  r.translation_mm = {t[0], t[1], t[2]};
}
inline void to_json(nlohmann::json& j, const CameraCalibration& c) {
  j = {{"intrinsics", c.intrinsics}, {"cam_from_proj", c.cam_from_proj}};
}
inline void from_json(const nlohmann::json& j, CameraCalibration& c) {
  j.at("intrinsics").get_to(c.intrinsics);
  j.at("cam_from_proj").get_to(c.cam_from_proj);
}

}  // namespace procam
