// SPDX-License-Identifier: MIT
// Glossy transport off metal: projector light reaching radiosity patches and the camera-side view.
#include "procam/hw/sim/global.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <random>

#include "global_internal.hpp"
#include "parallel.hpp"
#include "procam/hw/sim/raycast.hpp"

namespace procam::sim {
using detail::view_normal;
using detail::view_point;

// ---- Glossy, into the radiosity patches ----------------------------------------

void add_glossy_transport(const Scene& scene, const PreparedView& view, const ProjectorModel& projector,
                          const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                          const GlobalOptions& options, RadiosityModel& m) {
  bool any = false;
  for (const auto& o : scene.objects) any = any || (o.material.glossy() && !is_planar_mirror(o));
  if (!any || m.size() == 0) return;
  const SceneTracer tracer(scene);
  const Intrinsics& Kp = projector.intrinsics;
  const Intrinsics& K = view.camera.intrinsics;
  const Rigid3 cam_from_world = world_from_cam.inverse();
  const uint32_t g = std::max(1u, options.glossy_block_px);
  const uint32_t S = std::max(1u, options.glossy_samples);
  m.glossy_block_px = g;
  const double intensity = projector.irradiance_at_1m * 1.0e6;  // iu·mm² per sr
  const Vec3 pc = world_from_proj.translation_mm;
  std::map<std::pair<uint32_t, uint32_t>, double> entries;  // (block, patch) → iu per unit emitted
  std::mt19937 rng(12345);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (uint32_t by = 0; by + g <= Kp.height; by += g)
    for (uint32_t bx = 0; bx + g <= Kp.width; bx += g) {
      const double xp = bx + 0.5 * (g - 1), yp = by + 0.5 * (g - 1);
      const Vec3 ray_p = Kp.ray(xp, yp);  // z = 1
      const Vec3 d = normalized(world_from_proj.rotation * ray_p);
      Hit h;
      if (!tracer.first_hit(pc, d, 1e-9, h)) continue;
      const Material& mat = tracer.material(h.object);
      if (!mat.glossy() || is_planar_mirror(scene.objects[static_cast<size_t>(h.object)])) continue;  // mirrors: global_mirror.cpp
      Vec3 n = h.normal;
      if (dot(n, d) > 0) n = -n;
      // Power leaving the projector through the block per unit emitted:
      // I · Ω, Ω = g² / (fx·fy·|ray|³) (pixel solid angle off axis).
      const double rn = norm(ray_p);
      const double power = intensity * g * g / (Kp.fx * Kp.fy * rn * rn * rn) * mat.specular / S;
      const Vec3 mirror = d - n * (2.0 * dot(d, n));
      const Vec3 t1 = normalized(std::abs(mirror.x) < 0.9 ? cross(mirror, Vec3{1, 0, 0}) : cross(mirror, Vec3{0, 1, 0}));
      const Vec3 t2 = cross(mirror, t1);
      const uint32_t block = static_cast<uint32_t>(m.glossy_blocks.size());
      bool used = false;
      for (uint32_t s = 0; s < S; ++s) {
        const Vec3 dir = normalized(mirror + t1 * (mat.roughness_rad * gauss(rng)) + t2 * (mat.roughness_rad * gauss(rng)));
        if (dot(dir, n) <= 0) continue;  // into the surface: absorbed
        Hit y;
        if (!tracer.first_hit(h.point_mm + n * 0.05, dir, 1e-6, y)) continue;
        const Vec3 yc = cam_from_world * y.point_mm;
        if (!(yc.z > 0)) continue;
        double u = 0, v = 0;
        K.project(yc, u, v);
        const auto iu = static_cast<int64_t>(std::floor(u + 0.5)), iv = static_cast<int64_t>(std::floor(v + 0.5));
        if (iu < 0 || iv < 0 || iu >= K.width || iv >= K.height) continue;
        const size_t i = static_cast<size_t>(iv) * view.width + static_cast<size_t>(iu);
        if (view.object[i] != y.object || std::abs(static_cast<double>(view.depth_mm[i]) - yc.z) > 1.0 + 0.01 * yc.z)
          continue;  // not what the camera sees there: hidden from the camera
        const int32_t p = m.pixel_patch[i];
        if (p < 0) continue;
        entries[{block, static_cast<uint32_t>(p)}] += power / m.patches[static_cast<size_t>(p)].area_mm2;
        used = true;
      }
      if (used) m.glossy_blocks.push_back(by * Kp.width + bx);
    }
  m.glossy.reserve(entries.size());
  for (const auto& [key, w] : entries) m.glossy.push_back({key.second, key.first, static_cast<float>(w)});
}

// ---- Glossy, camera side -------------------------------------------------------

GlossyViewModel build_glossy_view(const Scene& scene, const PreparedView& view, const ProjectorModel& projector,
                                  const Rigid3& world_from_cam, const Rigid3& world_from_proj,
                                  const GlobalOptions& options) {
  GlossyViewModel out;
  bool any = false;
  for (const auto& o : scene.objects) any = any || (o.material.glossy() && !is_planar_mirror(o));
  if (!any) return out;
  const SceneTracer tracer(scene);
  const Intrinsics& Kp = projector.intrinsics;
  const Rigid3 proj_from_world = world_from_proj.inverse();
  const Vec3 pc = world_from_proj.translation_mm;
  const double intensity = projector.irradiance_at_1m * 1.0e6;
  const uint32_t S = std::max(1u, options.glossy_samples / 4);
  const int64_t stride = static_cast<int64_t>(Kp.width) + 2;
  const double W = Kp.width, H = Kp.height;
  std::mt19937 rng(54321);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (size_t i = 0; i < view.pixel_count(); ++i) {
    if (view.object[i] < 0) continue;
    const Object& obj = scene.objects[static_cast<size_t>(view.object[i])];
    const Material& mat = obj.material;
    if (!mat.glossy() || is_planar_mirror(obj)) continue;
    const Vec3 x = world_from_cam * view_point(view, i);
    const Vec3 n = normalized(world_from_cam.rotation * view_normal(view, i));
    const Vec3 d = normalized(x - world_from_cam.translation_mm);
    const Vec3 mirror = d - n * (2.0 * dot(d, n));
    const Vec3 t1 = normalized(std::abs(mirror.x) < 0.9 ? cross(mirror, Vec3{1, 0, 0}) : cross(mirror, Vec3{0, 1, 0}));
    const Vec3 t2 = cross(mirror, t1);
    for (uint32_t s = 0; s < S; ++s) {
      const Vec3 dir = normalized(mirror + t1 * (mat.roughness_rad * gauss(rng)) + t2 * (mat.roughness_rad * gauss(rng)));
      if (dot(dir, n) <= 0) continue;
      Hit y;
      if (!tracer.first_hit(x + n * 0.05, dir, 1e-6, y)) continue;
      Vec3 ny = y.normal;
      if (dot(ny, dir) > 0) ny = -ny;  // facing the glossy point
      const Vec3 to_p = pc - y.point_mm;
      const double dist = norm(to_p);
      const double cos_p = dot(ny, to_p) / dist;
      if (!(cos_p > 0)) continue;
      const Vec3 yp = proj_from_world * y.point_mm;
      if (!(yp.z > 0)) continue;
      double u = 0, v = 0;
      Kp.project(yp, u, v);
      if (!(u >= -0.5 && u < W - 0.5 && v >= -0.5 && v < H - 0.5)) continue;
      Hit first;
      if (tracer.first_hit(pc, y.point_mm - pc, 1e-12, first) && first.t < 1.0 - 1e-6) continue;  // shadowed
      const double albedo_y = tracer.material(y.object).albedo;
      const double w = mat.specular / S * albedo_y / M_PI * intensity * cos_p / (dist * dist);
      if (!(w > 0)) continue;
      const auto iu = static_cast<int64_t>(std::floor(u + 0.5)), iv = static_cast<int64_t>(std::floor(v + 0.5));
      out.pixel.push_back(static_cast<uint32_t>(i));
      out.source.push_back(static_cast<int32_t>((iv + 1) * stride + iu + 1));
      out.weight.push_back(static_cast<float>(w));
    }
  }
  return out;
}

void GlossyViewComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                                float* radiance) const {
  const float* l0 = frame.pattern.level(0);
  const auto b = static_cast<uint32_t>(size_t{row_begin} * frame.view.width);
  const auto e = static_cast<uint32_t>(size_t{row_end} * frame.view.width);
  auto it = std::lower_bound(model_.pixel.begin(), model_.pixel.end(), b);
  for (auto k = static_cast<size_t>(it - model_.pixel.begin()); k < model_.pixel.size() && model_.pixel[k] < e; ++k)
    radiance[model_.pixel[k]] += model_.weight[k] * l0[model_.source[k]];
}

}  // namespace procam::sim
