// SPDX-License-Identifier: MIT
// Test helpers for the participating-medium tests (medium_test.cpp,
// medium_polarization_test.cpp): a small camera on the default rig, scenes
// with a medium, rendering to doubles.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "medium.hpp"
#include "shipped_test_util.hpp"

namespace procam::sim::test {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The default rig with a 160×100 camera of the same field of view.
inline SimRigConfig small_rig() {
  SimRigConfig rig = default_rig();
  Intrinsics& k = rig.cameras[0].calibration.intrinsics;
  k.width = 160;
  k.height = 100;
  k.fx = k.fy = 225;
  k.cx = 79.5;
  k.cy = 49.5;
  return rig;
}

inline const char* kPlane = R"({"objects": [{"type": "plane", "point_mm": [0, 0, 800], "normal": [0, 0, -1],
                                     "material": {"albedo": 0.7}}]})";

inline Scene plane_with(const std::string& medium_json) {
  auto j = nlohmann::json::parse(kPlane);
  if (!medium_json.empty()) j["medium"] = nlohmann::json::parse(medium_json);
  auto s = parse_scene(j, "test");
  EXPECT_TRUE(s.ok()) << s.status().to_string();
  return s.ok() ? *s : Scene{};
}

// A scene with the medium's multiple-scattering term off (tests of the
// single-scattering integral Eq. 5.13 on the shipped milk scenes).
inline Scene single_scattering_only(Scene s) {
  if (s.medium) s.medium->multiple_scattering = Medium::MultipleScattering::none;
  return s;
}

inline std::unique_ptr<Renderer> renderer_for(const Scene& scene, const SimRigConfig& rig) {
  const CameraCalibration& cam = rig.cameras[0].calibration;
  auto v = prepare_view(scene, rig.projector, cam, 2);
  EXPECT_TRUE(v.ok()) << v.status().to_string();
  if (!v.ok()) return nullptr;
  return std::make_unique<Renderer>(std::move(v).value(), rig.projector, 2);
}

// Radiance without ambient, widened to double for the comparisons.
inline std::vector<double> render(const Renderer& r, PreparedPattern& p, Renderer::Parts parts = Renderer::Parts::all) {
  std::vector<float> out(r.view().pixel_count());
  EXPECT_TRUE(r.render_radiance_parts(p, out.data(), false, parts).ok());
  return {out.begin(), out.end()};
}

inline Vec3 point_of(const PreparedView& v, size_t i) {
  return {static_cast<double>(v.point_mm[3 * i]), static_cast<double>(v.point_mm[3 * i + 1]),
          static_cast<double>(v.point_mm[3 * i + 2])};
}

inline PreparedPattern emitted_pattern(const ProjectorModel& proj, const std::vector<float>& e) {
  Image im(proj.intrinsics.width, proj.intrinsics.height, PixelType::f32);
  std::copy(e.begin(), e.end(), im.ptr<float>());
  auto p = PreparedPattern::from_emitted(im);
  EXPECT_TRUE(p.ok());
  return std::move(p).value();
}

}  // namespace procam::sim::test
