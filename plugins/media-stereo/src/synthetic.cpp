// SPDX-License-Identifier: MIT
#include "synthetic.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace procam::media_stereo {

Vec3 PinholeCamera::ray_world(double u, double v) const {
  return world_from_cam.rotation * Vec3{(u - cx) / fx, (v - cy) / fy, 1.0};
}

bool PinholeCamera::project(const Vec3& world, double& u, double& v, double& z) const {
  const Vec3 c = world_from_cam.rotation.transposed() * (world - world_from_cam.translation_mm);
  if (!(c.z > 1e-9)) return false;
  z = c.z;
  u = cx + fx * c.x / c.z;
  v = cy + fy * c.y / c.z;
  return true;
}

PinholeCamera look_at_camera(uint32_t width, uint32_t height, double f_px, const Vec3& centre, const Vec3& target) {
  const Vec3 zc = normalized(target - centre);
  const Vec3 xc = normalized(cross(Vec3{0, 1, 0}, zc));  // world +y stays image-down
  const Vec3 yc = cross(zc, xc);
  PinholeCamera c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = f_px;
  c.cx = (width - 1) / 2.0;
  c.cy = (height - 1) / 2.0;
  c.world_from_cam.rotation = Mat3{{xc.x, yc.x, zc.x, xc.y, yc.y, zc.y, xc.z, yc.z, zc.z}};
  c.world_from_cam.translation_mm = centre;
  return c;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Ray/plane: plane dot(n, X) = dist. Returns the parameter along `ray` or inf.
double hit_plane(const Vec3& o, const Vec3& ray, const Vec3& n, double dist) {
  const double den = dot(n, ray);
  if (std::abs(den) < 1e-12) return kInf;
  const double t = (dist - dot(n, o)) / den;
  return t > 1e-9 ? t : kInf;
}

// Ray/sphere front hit restricted to the half towards -z of the centre.
double hit_half_sphere(const Vec3& o, const Vec3& ray, const Vec3& c, double r) {
  const Vec3 oc = o - c;
  const double a = dot(ray, ray), b = dot(oc, ray), cc = dot(oc, oc) - r * r;
  const double disc = b * b - a * cc;
  if (disc < 0) return kInf;
  const double sq = std::sqrt(disc);
  for (double t : {(-b - sq) / a, (-b + sq) / a}) {
    if (t > 1e-9 && (o + ray * t).z <= c.z) return t;
  }
  return kInf;
}

}  // namespace

bool intersect(const SyntheticScene& s, const Vec3& origin, const Vec3& ray, double& t, Vec3& point, Vec3& normal) {
  t = kInf;
  switch (s.kind) {
    case SceneKind::fronto_plane:
      t = hit_plane(origin, ray, {0, 0, 1}, s.plane_z_mm);
      normal = {0, 0, -1};
      break;
    case SceneKind::inclined_plane: {
      const double a = s.incline_deg * std::numbers::pi / 180.0;
      const Vec3 n{std::sin(a), 0, -std::cos(a)};
      t = hit_plane(origin, ray, n, dot(n, Vec3{0, 0, s.plane_z_mm}));
      normal = n;
      break;
    }
    case SceneKind::half_sphere: {
      const double ts = hit_half_sphere(origin, ray, s.sphere_centre, s.sphere_radius_mm);
      const double tp = hit_plane(origin, ray, {0, 0, 1}, s.sphere_centre.z);
      if (ts <= tp) {
        t = ts;
        if (t < kInf) normal = normalized(origin + ray * t - s.sphere_centre);
      } else {
        t = tp;
        normal = {0, 0, -1};
      }
      break;
    }
  }
  if (!(t < kInf)) return false;
  point = origin + ray * t;
  if (dot(normal, ray) > 0) normal = -normal;
  return true;
}

double albedo_at(const Vec3& p) {
  // Incommensurate periods 19-41 mm: non-repeating over the scenes, smooth at
  // the test resolution (about 3 mm per pixel at 500 mm).
  const double tau = 2.0 * std::numbers::pi;
  const double v = std::sin(tau * (p.x + 0.3 * p.y) / 23.0) + std::sin(tau * (p.y - 0.45 * p.x) / 19.0 + 1.3) +
                   0.7 * std::sin(tau * (p.x + p.y + 0.5 * p.z) / 41.0 + 0.4);
  return 0.55 + 0.3 * v / 2.7;
}

double albedo_at(const SyntheticScene& s, const Vec3& p) { return s.textured ? albedo_at(p) : 0.55; }

double brdf(const SyntheticScene& s, const Vec3& p, const Vec3& n, const Vec3& to_light, const Vec3& to_view) {
  double f = albedo_at(s, p) / std::numbers::pi;
  if (s.specular > 0) {
    const Vec3 h = normalized(to_light + to_view);
    f += s.specular * (s.shininess + 2) / (2 * std::numbers::pi) * std::pow(std::max(0.0, dot(n, h)), s.shininess);
  }
  return f;
}

RenderedView render(const SyntheticScene& s, const PinholeCamera& cam, const Vec3& light, double light_intensity,
                    const MediumParams& m) {
  RenderedView out;
  out.width = cam.width;
  out.height = cam.height;
  const size_t n = size_t{cam.width} * cam.height;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  out.image.assign(n, 0.0f);
  out.direct.assign(n, 0.0f);
  out.backscatter.assign(n, 0.0f);
  out.depth_mm.assign(n, nan);
  out.normal.assign(n, Vec3{0, 0, 0});
  const Vec3 c = cam.centre();
  for (uint32_t y = 0; y < cam.height; ++y) {
    for (uint32_t x = 0; x < cam.width; ++x) {
      const size_t i = size_t{y} * cam.width + x;
      const Vec3 ray = cam.ray_world(x, y);
      const double len = norm(ray);
      double z = 0;
      Vec3 p, nrm;
      if (!intersect(s, c, ray, z, p, nrm)) continue;
      out.depth_mm[i] = static_cast<float>(z);
      out.normal[i] = nrm;
      const double d_cp = z * len;
      const Vec3 lp = light - p;
      const double d_lp = norm(lp);
      const Vec3 to_light = lp / d_lp;
      const double cos_i = dot(nrm, to_light);
      double direct = 0;
      // Cast shadow: the surface seen from P towards the light.
      double zs = 0;
      Vec3 ps, ns;
      const bool shadowed = intersect(s, p + to_light * 1e-6, to_light, zs, ps, ns) && zs < d_lp - 1e-6;
      if (cos_i > 0 && !shadowed) {
        // Eq. 5.15 / 5.25.
        direct = light_intensity * std::exp(-m.sigma_per_mm * d_lp) / (d_lp * d_lp) * cos_i *
                 brdf(s, p, nrm, to_light, normalized(c - p)) * std::exp(-m.sigma_per_mm * d_cp);
      }
      const double b = backscatter(m, light_intensity, c, ray / len, light, d_cp);  // Eq. 5.16 / 5.26
      out.direct[i] = static_cast<float>(direct);
      out.backscatter[i] = static_cast<float>(b);
      out.image[i] = static_cast<float>(direct + b);
    }
  }
  return out;
}

std::vector<float> render_medium_only(const PinholeCamera& cam, const Vec3& light, double light_intensity,
                                      const MediumParams& m, double wall_z_mm) {
  std::vector<float> img(size_t{cam.width} * cam.height);
  for (uint32_t y = 0; y < cam.height; ++y)
    for (uint32_t x = 0; x < cam.width; ++x) {
      const Vec3 ray = cam.ray_world(x, y);
      const double len = norm(ray);
      img[size_t{y} * cam.width + x] = static_cast<float>(
          backscatter(m, light_intensity, cam.centre(), ray / len, light, wall_z_mm * len, 8.0));
    }
  return img;
}

}  // namespace procam::media_stereo
