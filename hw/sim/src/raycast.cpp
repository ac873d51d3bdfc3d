// SPDX-License-Identifier: MIT
// Analytic ray intersections with planes, oriented boxes (slab test), spheres,
// finite cylinders (lateral surface + optional caps) and bowls (half-ellipsoids; hemispheres by default).
#include "procam/hw/sim/raycast.hpp"

#include <algorithm>
#include <cmath>

namespace procam::sim {

SceneTracer::SceneTracer(const Scene& scene) {
  objects_.reserve(scene.objects.size());
  for (const auto& o : scene.objects) {
    Entry e{o.shape, o.material, Mat3::identity()};
    if (const Box* b = std::get_if<Box>(&o.shape)) e.box_from_world = b->rotation.transposed();
    objects_.push_back(e);
  }
}

namespace {

bool hit_plane(const Plane& p, const Vec3& o, const Vec3& d, double t_min, double t_best, double& t,
               Vec3& n) {
  const double denom = dot(p.normal, d);
  if (std::abs(denom) < 1e-15) return false;
  t = dot(p.normal, p.point_mm - o) / denom;
  if (!(t > t_min && t < t_best)) return false;
  if (p.finite) {
    const Vec3 rel = o + d * t - p.point_mm;
    if (std::abs(dot(rel, p.u_axis)) > 0.5 * p.width_mm || std::abs(dot(rel, p.v_axis)) > 0.5 * p.height_mm)
      return false;
  }
  n = p.normal;
  return true;
}

bool hit_sphere(const Sphere& s, const Vec3& o, const Vec3& d, double t_min, double t_best, double& t,
                Vec3& n) {
  // |o + t d - c|^2 = r^2  ->  a t^2 + 2 b t + c0 = 0
  const Vec3 oc = o - s.center_mm;
  const double a = dot(d, d), b = dot(oc, d), c0 = dot(oc, oc) - s.radius_mm * s.radius_mm;
  const double disc = b * b - a * c0;
  if (disc < 0) return false;
  const double sq = std::sqrt(disc);
  // Numerically stable roots.
  const double q = -(b + std::copysign(sq, b));
  double t0 = q / a, t1 = q != 0 ? c0 / q : t0;
  if (t0 > t1) std::swap(t0, t1);
  t = t0 > t_min ? t0 : t1;
  if (!(t > t_min && t < t_best)) return false;
  n = normalized(o + d * t - s.center_mm);
  return true;
}

bool hit_box(const Box& b, const Mat3& box_from_world, const Vec3& o, const Vec3& d, double t_min,
             double t_best, double& t, Vec3& n) {
  const Vec3 ob = box_from_world * (o - b.center_mm);
  const Vec3 db = box_from_world * d;
  const double half[3] = {0.5 * b.size_mm.x, 0.5 * b.size_mm.y, 0.5 * b.size_mm.z};
  double t_near = -std::numeric_limits<double>::infinity(), t_far = std::numeric_limits<double>::infinity();
  int axis_near = -1, axis_far = -1;
  for (int a = 0; a < 3; ++a) {
    const double oa = ob[a], da = db[a];
    if (std::abs(da) < 1e-15) {
      if (std::abs(oa) > half[a]) return false;
      continue;
    }
    double t1 = (-half[a] - oa) / da, t2 = (half[a] - oa) / da;
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > t_near) { t_near = t1; axis_near = a; }
    if (t2 < t_far) { t_far = t2; axis_far = a; }
  }
  if (t_near > t_far) return false;
  int axis;
  if (t_near > t_min) { t = t_near; axis = axis_near; }
  else { t = t_far; axis = axis_far; }  // origin inside the box
  if (!(t > t_min && t < t_best) || axis < 0) return false;
  const double coord = ob[axis] + t * db[axis];
  double nb[3] = {0, 0, 0};
  nb[axis] = coord > 0 ? 1.0 : -1.0;
  n = box_from_world.transposed() * Vec3{nb[0], nb[1], nb[2]};
  return true;
}

// Smallest accepted root of a t² + 2 b t + c0 = 0 in (t_min, t_best); `accept`
// filters roots by the point they give.
template <typename Accept>
bool quadratic_hit(double a, double b, double c0, double t_min, double t_best, double& t, Accept accept) {
  const double disc = b * b - a * c0;
  if (disc < 0 || a == 0) return false;
  const double sq = std::sqrt(disc);
  const double q = -(b + std::copysign(sq, b));
  double t0 = q / a, t1 = q != 0 ? c0 / q : t0;
  if (t0 > t1) std::swap(t0, t1);
  for (double r : {t0, t1}) {
    if (r > t_min && r < t_best && accept(r)) {
      t = r;
      return true;
    }
  }
  return false;
}

bool hit_cylinder(const Cylinder& c, const Vec3& o, const Vec3& d, double t_min, double t_best, double& t,
                  Vec3& n) {
  // Lateral surface: |(o + t d − c)⊥|² = r², ⊥ = component orthogonal to the axis.
  const Vec3 oc = o - c.center_mm;
  const Vec3 op = oc - c.axis * dot(oc, c.axis), dp = d - c.axis * dot(d, c.axis);
  const double half = 0.5 * c.height_mm;
  bool found = false;
  double tl = 0;
  if (quadratic_hit(dot(dp, dp), dot(op, dp), dot(op, op) - c.radius_mm * c.radius_mm, t_min, t_best, tl,
                    [&](double r) { return std::abs(dot(oc + d * r, c.axis)) <= half; })) {
    t = tl;
    t_best = tl;
    const Vec3 rel = oc + d * tl;
    n = normalized(rel - c.axis * dot(rel, c.axis));
    found = true;
  }
  if (c.caps) {
    const double da = dot(d, c.axis);
    if (std::abs(da) > 1e-15) {
      for (double s : {-1.0, 1.0}) {
        const double tc = (s * half - dot(oc, c.axis)) / da;
        if (!(tc > t_min && tc < t_best)) continue;
        const Vec3 rel = oc + d * tc;
        const Vec3 radial = rel - c.axis * dot(rel, c.axis);
        if (dot(radial, radial) > c.radius_mm * c.radius_mm) continue;
        t = tc;
        t_best = tc;
        n = c.axis * s;
        found = true;
      }
    }
  }
  return found;
}

bool hit_bowl(const Bowl& b, const Vec3& o, const Vec3& d, double t_min, double t_best, double& t, Vec3& n) {
  // Half-ellipsoid |p⊥|²/r² + (p·a)²/h² = 1 with p·a <= 0 (a = opening, h =
  // depth, p relative to the centre). Scaling the axial component by r/h
  // maps it onto the sphere of radius r (t is unchanged by the linear map);
  // h = r is the hemisphere. Normal = gradient p⊥/r² + a (p·a)/h².
  const Vec3 oc = o - b.center_mm;
  const double s = b.radius_mm / b.depth_mm;
  const double oa = dot(oc, b.opening), da = dot(d, b.opening);
  const Vec3 os = oc + b.opening * (oa * (s - 1.0)), ds = d + b.opening * (da * (s - 1.0));
  double tb = 0;
  if (!quadratic_hit(dot(ds, ds), dot(os, ds), dot(os, os) - b.radius_mm * b.radius_mm, t_min, t_best, tb,
                     [&](double r) { return oa + da * r <= 0; }))
    return false;
  t = tb;
  const Vec3 p = oc + d * tb;
  const double pa = dot(p, b.opening);
  const Vec3 radial = p - b.opening * pa;
  n = normalized(radial * (1.0 / (b.radius_mm * b.radius_mm)) + b.opening * (pa / (b.depth_mm * b.depth_mm)));
  return true;
}

}  // namespace

bool SceneTracer::first_hit(const Vec3& origin, const Vec3& dir, double t_min, Hit& hit) const {
  double t_best = std::numeric_limits<double>::infinity();
  int32_t best = -1;
  Vec3 n_best;
  for (size_t i = 0; i < objects_.size(); ++i) {
    const Entry& e = objects_[i];
    double t = 0;
    Vec3 n;
    bool h = false;
    if (const Plane* p = std::get_if<Plane>(&e.shape)) h = hit_plane(*p, origin, dir, t_min, t_best, t, n);
    else if (const Sphere* s = std::get_if<Sphere>(&e.shape)) h = hit_sphere(*s, origin, dir, t_min, t_best, t, n);
    else if (const Box* b = std::get_if<Box>(&e.shape)) h = hit_box(*b, e.box_from_world, origin, dir, t_min, t_best, t, n);
    else if (const Cylinder* c = std::get_if<Cylinder>(&e.shape)) h = hit_cylinder(*c, origin, dir, t_min, t_best, t, n);
    else if (const Bowl* w = std::get_if<Bowl>(&e.shape)) h = hit_bowl(*w, origin, dir, t_min, t_best, t, n);
    if (h) {
      t_best = t;
      best = static_cast<int32_t>(i);
      n_best = n;
    }
  }
  if (best < 0) return false;
  hit.t = t_best;
  hit.point_mm = origin + dir * t_best;
  hit.normal = n_best;
  hit.object = best;
  return true;
}

}  // namespace procam::sim
