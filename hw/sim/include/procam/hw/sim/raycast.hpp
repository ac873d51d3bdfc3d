// SPDX-License-Identifier: MIT
// Ray casting against a Scene: first hit along a ray, with the surface normal,
// material and object id.
//
// Threads: a SceneTracer is immutable after construction; first_hit() is
// thread-safe. Lengths in mm, in the scene (camera 0) frame.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "procam/base/geometry.hpp"
#include "procam/hw/sim/scene.hpp"

namespace procam::sim {

struct Hit {
  double t = std::numeric_limits<double>::infinity();  // ray parameter: point = origin + t * dir
  Vec3 point_mm;
  Vec3 normal;         // unit, geometric outward normal (a plane's own normal); not flipped to the ray
  int32_t object = -1; // index into Scene::objects, -1 when nothing was hit
};

class SceneTracer {
public:
  // Copies what it needs from `scene`; the scene may be destroyed afterwards.
  explicit SceneTracer(const Scene& scene);

  // First intersection with t > t_min along origin + t * dir (dir need not be
  // unit; t is in units of |dir|). Returns false (hit untouched) on a miss.
  bool first_hit(const Vec3& origin, const Vec3& dir, double t_min, Hit& hit) const;

  size_t object_count() const { return objects_.size(); }
  const Material& material(int32_t object) const { return objects_[static_cast<size_t>(object)].material; }

private:
  struct Entry {
    Shape shape;
    Material material;
    Mat3 box_from_world;  // boxes only
  };
  std::vector<Entry> objects_;
};

}  // namespace procam::sim
