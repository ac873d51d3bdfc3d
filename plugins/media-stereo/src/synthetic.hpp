// SPDX-License-Identifier: MIT
// Pinhole cameras and a small synthetic renderer for the stereo test scenes of
// thesis Fig. 5.14/5.17 (fronto-parallel plane, inclined plane, half-sphere on
// a back plane) in a homogeneous medium with one isotropic point light:
// I = D + B per Eq. 5.14-5.16 (scatter_model.hpp). Single scattering, no
// indirect signal (the thesis' assumption, §5.4.1), cast shadows of the
// half-sphere tested, no projector, no defocus, no sensor noise.
//
// Surfaces are Lambertian with a smooth procedural albedo (so binocular
// matching has texture), optionally plus a reciprocal Blinn-Phong lobe on the
// half vector (symmetric in light and view, so Helmholtz reciprocity holds).
// Units: mm; camera pixel centres at integers; depth = z in the camera frame.
// Threads: pure functions; render() is single-threaded.
#pragma once

#include <cstdint>
#include <vector>

#include "procam/base/geometry.hpp"
#include "scatter_model.hpp"

namespace procam::media_stereo {

struct PinholeCamera {
  uint32_t width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  Rigid3 world_from_cam{};
  Vec3 centre() const { return world_from_cam.translation_mm; }
  // World direction of pixel (u, v) whose camera-frame z component is 1 (so
  // the point at depth z is centre() + ray * z).
  Vec3 ray_world(double u, double v) const;
  // Pixel and depth of a world point; false behind the camera.
  bool project(const Vec3& world, double& u, double& v, double& z) const;
};

// Camera at `centre` looking at `target` (image x roughly along world +x,
// image y along world +y for targets ahead on +z).
PinholeCamera look_at_camera(uint32_t width, uint32_t height, double f_px, const Vec3& centre, const Vec3& target);

enum class SceneKind { fronto_plane, inclined_plane, half_sphere };

struct SyntheticScene {
  SceneKind kind = SceneKind::fronto_plane;
  double plane_z_mm = 500;        // fronto plane / back plane of the half-sphere
  double incline_deg = 30;        // inclined plane: rotation about world y through (0, 0, plane_z)
  Vec3 sphere_centre{0, 0, 560};  // half-sphere: on the back plane z = sphere_centre.z
  double sphere_radius_mm = 100;
  bool textured = true;           // false: constant albedo 0.55 (Helmholtz needs no texture)
  double specular = 0;            // weight of the reciprocal Blinn-Phong lobe (0: Lambertian)
  double shininess = 20;
};

// First surface hit along centre + ray·z (ray from ray_world); false if none.
// Outputs depth z, the point and the unit normal facing the ray's origin.
bool intersect(const SyntheticScene& s, const Vec3& origin, const Vec3& ray, double& z, Vec3& point, Vec3& normal);

// Albedo at a surface point (smooth, about 0.25..0.85).
double albedo_at(const Vec3& p);
double albedo_at(const SyntheticScene& s, const Vec3& p);

// Reciprocal BRDF f_r(ω_i, ω_o) (1/sr): albedo/π + specular lobe.
double brdf(const SyntheticScene& s, const Vec3& p, const Vec3& n, const Vec3& to_light, const Vec3& to_view);

struct RenderedView {
  uint32_t width = 0, height = 0;
  std::vector<float> image;      // I = D + B
  std::vector<float> direct;     // D (Eq. 5.15/5.25)
  std::vector<float> backscatter;// B (Eq. 5.16/5.26)
  std::vector<float> depth_mm;   // truth z, NaN where no surface
  std::vector<Vec3> normal;      // truth unit normals (world), {0,0,0} where none
};

// Renders the view of `cam` with the light at `light` (intensity I0).
RenderedView render(const SyntheticScene& s, const PinholeCamera& cam, const Vec3& light, double light_intensity,
                    const MediumParams& m);

// The medium alone (§5.4.1 "Recovering the medium parameters"): no scene, the
// rays end at a black wall at depth wall_z_mm in the camera frame.
std::vector<float> render_medium_only(const PinholeCamera& cam, const Vec3& light, double light_intensity,
                                      const MediumParams& m, double wall_z_mm);

}  // namespace procam::media_stereo
