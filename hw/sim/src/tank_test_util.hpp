// SPDX-License-Identifier: MIT
// Test helpers for the tank rig (tank_test.cpp, tank_mc_test.cpp): the default
// tank scene, a small far camera, and brute-force references of Eq. 4.2
// written without the tank code's angle substitution or cap sampling.
#pragma once

#include <cmath>
#include <string>

#include "medium.hpp"
#include "medium_test_util.hpp"
#include "tank.hpp"

namespace procam::sim::tank_test {

using test::render;
using test::renderer_for;

// Tank 300 × 250 × 300 mm (x, y, depth) with its front face 5 m from the
// camera, bulb 20 mm from the left wall at mid height and mid depth.
inline Scene tank_scene(const std::string& medium_fields, double bulb_radius_mm = 10.0, int samples = 10) {
  const std::string text = R"({"objects": [{"type": "plane", "name": "back wall", "point_mm": [0, 0, 5301],
                                "normal": [0, 0, -1], "material": {"albedo": 0}}],
                               "medium": {)" + medium_fields +
                           R"(, "box_min_mm": [-150, -125, 5000], "box_max_mm": [150, 125, 5300],
                               "bulb": {"center_mm": [-130, 0, 5150], "radius_mm": )" +
                           std::to_string(bulb_radius_mm) + R"(, "irradiance_at_1m": 5e-4, "samples": )" +
                           std::to_string(samples) + "}}}";
  auto s = parse_scene(nlohmann::json::parse(text), "tank-test");
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  return s.ok() ? *s : Scene{};
}

// The default rig with a 160×100 camera of focal length 2000 px: 2.5 mm per
// pixel at the tank's front face, the face 120 × 100 px.
inline SimRigConfig tank_rig() {
  SimRigConfig rig = test::small_rig();
  Intrinsics& k = rig.cameras[0].calibration.intrinsics;
  k.fx = k.fy = 2000;
  return rig;
}

inline TankGeometry geometry_of(const Scene& s) {
  const Result<TankGeometry> g = tank_geometry(*s.medium, Rigid3{}, tank_rig().cameras[0].calibration.intrinsics);
  EXPECT_TRUE(g.ok()) << g.status().to_string();
  return g.ok() ? *g : TankGeometry{};
}

inline PreparedPattern flat_pattern(const ProjectorModel& proj, float value) {
  return test::emitted_pattern(proj, std::vector<float>(size_t{proj.intrinsics.width} * proj.intrinsics.height, value));
}

inline size_t centre_of_bulb_pixel(const PreparedView& v, const TankGeometry& g) {
  return static_cast<size_t>(std::lround(g.bulb_v_px)) * v.width + static_cast<size_t>(std::lround(g.bulb_u_px));
}

// Eq. 4.1-4.2 for an isotropic point source at the bulb's centre, midpoint
// rule in z over the whole depth (ρ must exceed the bulb's radius).
inline double eq42_point_source(const Medium& m, double rho, int steps) {
  const Medium::Bulb& b = *m.bulb;
  const double z0 = m.box_min_mm.z, z1 = m.box_max_mm.z, dz = (z1 - z0) / steps;
  double sum = 0;
  for (int k = 0; k < steps; ++k) {
    const double z = z0 + (k + 0.5) * dz;
    const double dzb = z - b.center_mm.z;
    const double d2 = rho * rho + dzb * dzb, d = std::sqrt(d2);
    sum += m.sigma_s_per_mm * b.intensity() / d2 * std::exp(-m.sigma_t_per_mm * (d + z - z0)) *
           hg_phase(m.g, -dzb / d) * dz;
  }
  return sum;
}

// The area bulb by brute force: the whole sphere on an n × n grid uniform in
// area (cos θ, φ), each point kept if it faces Y; midpoint rule in z.
inline double area_bulb_brute_force(const Medium& m, double rho, int z_steps, int n) {
  const Medium::Bulb& b = *m.bulb;
  const double r = b.radius_mm, L = b.radiance();
  const double z0 = m.box_min_mm.z, z1 = m.box_max_mm.z, dz = (z1 - z0) / z_steps;
  const double dA = r * r * (2.0 / n) * (2 * 3.14159265358979323846 / n);
  double sum = 0;
  for (int k = 0; k < z_steps; ++k) {
    const Vec3 y{b.center_mm.x + rho, b.center_mm.y, z0 + (k + 0.5) * dz};
    double in = 0;
    for (int i = 0; i < n; ++i) {
      const double mu = -1 + (i + 0.5) * 2.0 / n, s = std::sqrt(1 - mu * mu);
      for (int j = 0; j < n; ++j) {
        const double phi = (j + 0.5) * 2 * 3.14159265358979323846 / n;
        const Vec3 nq{s * std::cos(phi), s * std::sin(phi), mu};
        const Vec3 w = y - (b.center_mm + nq * r);
        const double l = norm(w), c = dot(nq, w) / l;
        if (c <= 0) continue;
        in += L * c * dA / (l * l) * std::exp(-m.sigma_t_per_mm * l) * hg_phase(m.g, -w.z / l);
      }
    }
    sum += m.sigma_s_per_mm * in * std::exp(-m.sigma_t_per_mm * (y.z - z0)) * dz;
  }
  return sum;
}

}  // namespace procam::sim::tank_test
