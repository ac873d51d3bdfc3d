// SPDX-License-Identifier: MIT
// Ideal planar mirrors: projector light reaching a point through a mirror,
// defocused over its unfolded path (see global.hpp "Planar mirrors").
#include <algorithm>
#include <cmath>

#include "global_internal.hpp"
#include "procam/hw/sim/global.hpp"
#include "procam/hw/sim/raycast.hpp"

namespace procam::sim {

bool is_planar_mirror(const Object& object) {
  const auto* plane = std::get_if<Plane>(&object.shape);
  return plane != nullptr && plane->finite && object.material.specular > 0 && object.material.roughness_rad <= 0.002;
}

MirrorModel build_mirror_paths(const Scene& scene, const PreparedView& view, const ProjectorModel& projector,
                               const Rigid3& world_from_cam, const Rigid3& world_from_proj) {
  MirrorModel out;
  const SceneTracer tracer(scene);
  const Intrinsics& Kp = projector.intrinsics;
  const Rigid3 proj_from_world = world_from_proj.inverse();
  const Vec3 c = world_from_proj.translation_mm;                         // projector centre
  const Vec3 axis = normalized(world_from_proj.rotation * Vec3{0, 0, 1});  // its optical axis
  const double intensity = projector.irradiance_at_1m * 1.0e6;          // iu·mm²
  const double W = Kp.width, H = Kp.height;
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    if (!is_planar_mirror(scene.objects[o])) continue;
    const Plane& m = std::get<Plane>(scene.objects[o].shape);
    const Vec3 n = m.normal;
    // Virtual projector: centre and axis reflected in the mirror plane.
    const Vec3 c_virtual = c - n * (2.0 * dot(c - m.point_mm, n));
    const Vec3 axis_virtual = axis - n * (2.0 * dot(axis, n));
    for (size_t i = 0; i < view.pixel_count(); ++i) {
      if (view.object[i] < 0 || static_cast<size_t>(view.object[i]) == o) continue;
      const Vec3 x = world_from_cam * detail::view_point(view, i);
      const Vec3 nx = normalized(world_from_cam.rotation * detail::view_normal(view, i));
      const Vec3 d = x - c_virtual;
      const double den = dot(d, n);
      if (std::abs(den) < 1e-12) continue;
      const double s = dot(m.point_mm - c_virtual, n) / den;
      if (!(s > 0 && s < 1)) continue;  // the mirror must lie between the virtual centre and x
      const Vec3 p = c_virtual + d * s;  // mirror point
      const Vec3 q = p - m.point_mm;
      if (std::abs(dot(q, m.u_axis)) > 0.5 * m.width_mm || std::abs(dot(q, m.v_axis)) > 0.5 * m.height_mm) continue;
      // x must face the mirror point on the side the camera sees (view normals face the camera).
      const Vec3 to_p = p - x;
      const double dist_px = norm(to_p);
      const double cos_x = dot(nx, to_p) / dist_px;
      if (!(cos_x > 0)) continue;
      // The projector pixel that lights the mirror point.
      const Vec3 pp = proj_from_world * p;
      if (!(pp.z > 0)) continue;
      double u = 0, v = 0;
      Kp.project(pp, u, v);
      if (!(u >= -0.5 && u < W - 0.5 && v >= -0.5 && v < H - 0.5)) continue;
      // Both legs unoccluded: projector -> mirror point, mirror point -> x.
      Hit hit;
      if (tracer.first_hit(c, p - c, 1e-12, hit) && (hit.t < 1.0 - 1e-6 || static_cast<size_t>(hit.object) != o))
        continue;
      if (tracer.first_hit(p, x - p, 1e-6, hit) && hit.t < 1.0 - 1e-6) continue;
      const double unfolded = norm(x - c_virtual);
      const double gain = scene.objects[o].material.specular * static_cast<double>(view.albedo[i]) / M_PI *
                          intensity * cos_x / (unfolded * unfolded);
      out.pixel.push_back(static_cast<uint32_t>(i));
      out.gain.push_back(static_cast<float>(gain));
      out.proj_x.push_back(static_cast<float>(u));
      out.proj_y.push_back(static_cast<float>(v));
      out.z_virtual_mm.push_back(static_cast<float>(dot(x - c_virtual, axis_virtual)));
    }
  }
  // Ascending pixel order (several mirrors may add to one pixel).
  std::vector<size_t> order(out.pixel.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return out.pixel[a] < out.pixel[b]; });
  MirrorModel sorted;
  for (size_t k : order) {
    sorted.pixel.push_back(out.pixel[k]);
    sorted.gain.push_back(out.gain[k]);
    sorted.proj_x.push_back(out.proj_x[k]);
    sorted.proj_y.push_back(out.proj_y[k]);
    sorted.z_virtual_mm.push_back(out.z_virtual_mm[k]);
  }
  return sorted;
}

MirrorComponent::MirrorComponent(MirrorModel model, ProjectorModel projector)
    : model_(std::move(model)), projector_(std::move(projector)) {}

size_t MirrorComponent::levels_needed(double focus_mm) const {
  size_t need = 1;
  for (float z : model_.z_virtual_mm) {
    const double sigma = projector_.aperture_mm > 0 ? projector_.blur_sigma_px(double(z), focus_mm) : 0.0;
    const auto [k, w] = detail::blur_level(sigma);
    need = std::max(need, size_t{k} + (w > 0 ? 2u : 1u));
  }
  return need;
}

void MirrorComponent::apply(const FrameContext& frame, uint32_t row_begin, uint32_t row_end,
                            float* radiance) const {
  const size_t stride = frame.pattern.stride();
  const double focus = frame.defocus.focus_mm;
  const auto b = static_cast<uint32_t>(size_t{row_begin} * frame.view.width);
  const auto e = static_cast<uint32_t>(size_t{row_end} * frame.view.width);
  auto it = std::lower_bound(model_.pixel.begin(), model_.pixel.end(), b);
  // Sample level L at (x, y) as the renderer does: level 0 is the sharp image
  // of box pixels (nearest), blurred levels are read bilinearly.
  auto sample = [&](size_t level, float x, float y) -> float {
    const float* L = frame.pattern.level(level);
    if (L == nullptr) return 0.f;
    if (level == 0) {
      const auto ix = static_cast<int64_t>(std::floor(x + 0.5f)), iy = static_cast<int64_t>(std::floor(y + 0.5f));
      return L[static_cast<size_t>(iy + 1) * stride + static_cast<size_t>(ix + 1)];
    }
    const float x0 = std::floor(x), y0 = std::floor(y), fx = x - x0, fy = y - y0;
    const float* p = L + static_cast<size_t>(static_cast<int64_t>(y0) + 1) * stride +
                     static_cast<size_t>(static_cast<int64_t>(x0) + 1);
    const float top = p[0] + fx * (p[1] - p[0]);
    const float bot = p[stride] + fx * (p[stride + 1] - p[stride]);
    return top + fy * (bot - top);
  };
  for (auto k = static_cast<size_t>(it - model_.pixel.begin()); k < model_.pixel.size() && model_.pixel[k] < e; ++k) {
    const double z = static_cast<double>(model_.z_virtual_mm[k]);
    const double sigma = projector_.aperture_mm > 0 ? projector_.blur_sigma_px(z, focus) : 0.0;
    const auto [lv, w] = detail::blur_level(sigma);
    const float a = sample(lv, model_.proj_x[k], model_.proj_y[k]);
    const float value = w > 0.f ? a + w * (sample(size_t{lv} + 1, model_.proj_x[k], model_.proj_y[k]) - a) : a;
    radiance[model_.pixel[k]] += model_.gain[k] * value;
  }
}

}  // namespace procam::sim
