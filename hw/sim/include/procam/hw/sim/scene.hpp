// SPDX-License-Identifier: MIT
// Simulated scenes: planes, boxes, spheres, cylinders and bowls with materials, loaded from JSON
// (schema in hw/sim/SCENES.md).
//
// Frame: the world frame is the frame of camera 0 (x right, y down, z forward),
// lengths in millimetres. Irradiance is in the sim's irradiance unit "iu"
// (SCENES.md "Units"), the same unit the projector delivers.
//
// Threads: plain data; loading functions are reentrant. Errors are returned
// (never thrown) and name the file and the JSON field, e.g.
// "configs/scenes/x.json: objects[2].radius_mm: must be > 0".
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/base/geometry.hpp"
#include "procam/core/status.hpp"
#include "procam/hw/sim/texture.hpp"

namespace procam::sim {

// Surface reflectance from physical parameters (SCENES.md "material", docs/sim.md).
// Defaults give the original opaque Lambertian surface, so old scenes load
// unchanged. Invariants checked by the parser: albedo + specular <= 1,
// albedo + transmittance <= 1, and a translucent body (mean_free_path_mm > 0)
// cannot also be a thin sheet (transmittance > 0).
struct Material {
  double albedo = 0.5;              // total diffuse reflectance, 0..1 (surface + sub-surface)
  double specular = 0;              // glossy (metal) reflectance, 0..1
  double roughness_rad = 0.1;       // glossy lobe: Gaussian σ of the reflected direction, radians
  double mean_free_path_mm = 0;     // transport mean free path ℓ (translucent body); 0: opaque
  double scattering_albedo = 0.99;  // single-scattering albedo α' of the body, 0..1 (translucent only)
  double ior = 1.5;                 // refractive index of the body (translucent only)
  double transmittance = 0;         // thin sheet: fraction of irradiance passed diffusely to the back, 0..1

  bool translucent() const { return mean_free_path_mm > 0; }
  bool glossy() const { return specular > 0; }
  bool sheet() const { return transmittance > 0; }
  // Fresnel reflectance at normal incidence, ((n − 1)/(n + 1))²: the part of
  // the albedo reflected at the surface of a translucent body.
  double surface_reflectance() const { return ((ior - 1) / (ior + 1)) * ((ior - 1) / (ior + 1)); }
  // Albedo of light reflected at the point it arrived (the direct component):
  // all of it for opaque surfaces, the Fresnel part for translucent bodies.
  double direct_albedo() const { return translucent() ? std::min(albedo, surface_reflectance()) : albedo; }
  // Diffusion length ℓ_d = ℓ / √(3 (1 − α')) (1/σ_tr of the dipole model,
  // Jensen et al. 2001), mm: the width of the sub-surface profile.
  double diffusion_length_mm() const {
    return mean_free_path_mm / std::sqrt(3.0 * std::max(1e-6, 1.0 - scattering_albedo));
  }
};

// Infinite plane, or a w×h rectangle centred on point_mm when finite.
struct Plane {
  Vec3 point_mm;
  Vec3 normal{0, 0, -1};  // unit; the side it points to is "outside" (planes are two-sided)
  bool finite = false;
  double width_mm = 0, height_mm = 0;  // extents along u_axis / v_axis when finite
  Vec3 u_axis{1, 0, 0};  // unit, orthogonal to normal
  Vec3 v_axis{0, 1, 0};  // unit, normal × u_axis
};

// Oriented box: world_from_box = rotation (R = Rz·Ry·Rx of euler_deg) about centre.
struct Box {
  Vec3 center_mm;
  Vec3 size_mm{100, 100, 100};  // full edge lengths along the box's own x, y, z
  Mat3 rotation;                // world_from_box rotation
};

struct Sphere {
  Vec3 center_mm;
  double radius_mm = 100;
};

// Finite cylinder: the lateral surface of radius radius_mm around the axis
// through center_mm, from −height/2 to +height/2 along `axis`; with `caps` the
// two end discs too. Two-sided, so its inside can be seen (a concave shell).
struct Cylinder {
  Vec3 center_mm;
  Vec3 axis{0, 1, 0};  // unit
  double radius_mm = 50;
  double height_mm = 100;
  bool caps = true;
};

// Hemispherical shell (bowl, lamp shade): the points of the sphere
// (center_mm, radius_mm) with (p − c)·opening ≤ 0, i.e. the half away from the
// opening direction. Two-sided: inside and outside are both surfaces.
struct Bowl {
  Vec3 center_mm;
  double radius_mm = 100;  // rim radius
  double depth_mm = 100;   // centre of the rim disc to the bottom; = radius_mm: hemisphere
  Vec3 opening{0, 0, -1};  // unit, from the centre out through the rim's disc
};

using Shape = std::variant<Plane, Box, Sphere, Cylinder, Bowl>;

struct Object {
  std::string name;  // optional label from the file ("" if none)
  Shape shape;
  Material material;
  // Albedo texture (planes only, opaque materials): replaces material.albedo
  // for the light the surface itself reflects to the camera (direct and
  // ambient, the radiosity gather at its pixels). Light it passes on to other
  // surfaces (inter-reflection patches, glossy targets) still uses
  // material.albedo. texture.hpp.
  std::optional<ChessboardTexture> texture = std::nullopt;
};

// Homogeneous participating medium (SCENES.md "medium", docs/media.md),
// filling the whole scene or an axis-aligned box (a tank) in the world frame.
// Mono: one σ, β, g for the sim's single channel. Invariants checked by the
// parser: 0 <= β <= σ, |g| < 1, box_min < box_max on every axis.
struct Medium {
  // Polarization of single-scattered light (thesis appendix, Eq. 5.35-5.36):
  // rayleigh: Mueller matrix of Rayleigh-type scattering normalised to the
  //           Henyey-Greenstein intensity (m11 = p_HG(θ), m12/m11 = −sin²θ/(1+cos²θ),
  //           m22/m11 = 1, m33/m11 = 2cosθ/(1+cos²θ));
  // none:     the medium depolarizes (m12 = m22 = m33 = 0).
  enum class DopModel { rayleigh, none };
  double sigma_t_per_mm = 0;  // extinction σ, 1/mm
  double sigma_s_per_mm = 0;  // scattering β, 1/mm (β <= σ; absorption σ − β)
  double g = 0;               // Henyey-Greenstein asymmetry, |g| < 1 (> 0: forward)
  DopModel dop_model = DopModel::rayleigh;
  // Backscatter of orders >= 2 in the projector-lit renderer (docs/media.md
  // "Multiple scattering"): none: single scattering only (Eq. 5.13);
  // diffuse: plus a depolarized, low-pass term whose magnitude comes from the
  // Monte Carlo reference at a few pixels when the view is prepared.
  enum class MultipleScattering { none, diffuse };
  MultipleScattering multiple_scattering = MultipleScattering::none;
  bool whole_scene = true;    // false: only inside [box_min_mm, box_max_mm]
  Vec3 box_min_mm, box_max_mm;
  // Where σ, β, g came from when the scene named a library material
  // (medium_library.hpp): the spec as written ("Merlot", "milk + espresso 1:3",
  // or the parts joined by " + "), its volume in the tank, the tank's litres
  // and the RGB column. Empty `material`: σ, β, g were given as numbers.
  std::string material;
  double volume_ml = 0, tank_litres = 0;
  std::string channel;
  // The dilution rig's light source (thesis §4.2.1, §4.3.3; docs/media.md
  // "Tank rig"): a spherical diffuse (Lambertian) bulb inside the tank. With a
  // bulb the projector does not light the medium; it only dims the bulb (the
  // bulb emits in proportion to the frame's mean emitted light).
  struct Bulb {
    Vec3 center_mm;               // world frame, inside the tank
    double radius_mm = 10;        // sphere radius
    double irradiance_at_1m = 0.01;  // iu at 1 m in clear medium per unit emitted light: I0 = 10⁶ × this (iu·mm²)
    int samples = 10;             // the visible cap is sampled samples × samples (§4.3.3: ~10×10)
    double intensity() const { return irradiance_at_1m * 1e6; }
    // Radiance of the bulb's surface (ru per unit emitted light): a Lambertian
    // sphere of radiance L has intensity π r² L in every direction.
    double radiance() const { return intensity() / (3.14159265358979323846 * radius_mm * radius_mm); }
  };
  std::optional<Bulb> bulb;
};

// Dynamic, non-homogeneous medium simulated in the Legendre domain
// (SCENES.md "legendre_medium", docs/legendre.md; thesis ch. 6): a closed,
// axis-aligned box (world frame) of fog whose density is advected by a swirl
// and rendered per frame at that frame's time. Mono, like Medium. Checked by
// the parser: box non-empty, 3 <= n <= 8, 0 <= beta <= sigma, |g| < 1.
struct LegendreMediumSpec {
  struct Blob {
    Vec3 center_mm;
    double radius_mm = 1;  // density peak * exp(-|x - c|^2 / radius^2)
    double peak = 1;
  };
  Vec3 box_min_mm, box_max_mm;
  int n = 5;                     // Legendre polynomials per axis (K = n^3)
  double density_uniform = 0;    // added to the blobs (dimensionless)
  std::vector<Blob> blobs;
  double swirl_mm_s = 0;         // peak speed of a swirl about the box's z axis
  double viscosity_mm2_s = 0;
  double dissipation_per_s = 0;
  double sigma_t_per_mm = 0;     // extinction at density 1
  double sigma_s_per_mm = 0;     // scattering at density 1
  double g = 0;                  // Henyey-Greenstein asymmetry
  // Polarization of the air-light: the homogeneous medium's Mueller model
  // (Medium::DopModel, docs/media.md): rayleigh keeps it, none depolarizes.
  Medium::DopModel dop_model = Medium::DopModel::rayleigh;
  // Advected single-scattering albedo omega = beta / sigma (a passive scalar
  // carried by the swirl like the density): omega(x) = clamp(albedo_uniform
  // + sum of albedo_blobs, 0, 1), beta(x) = omega(x) sigma_t_per_mm. Unset
  // (NaN, no blobs): beta = sigma_s_per_mm everywhere.
  double albedo_uniform = std::numeric_limits<double>::quiet_NaN();
  std::vector<Blob> albedo_blobs;
  bool has_albedo() const { return !albedo_blobs.empty() || albedo_uniform == albedo_uniform; }
  double frame_period_s = 1.0 / 30.0;  // medium time advanced per captured frame
};

struct Scene {
  std::string name;         // "name" field, else the file stem
  std::string description;  // free text
  std::string source;       // file it was loaded from ("" when parsed from JSON in memory)
  double ambient = 0;       // ambient irradiance on every surface, iu (unshadowed)
  std::vector<Object> objects;
  std::optional<Medium> medium;  // "medium" field; none = clear air
  std::optional<LegendreMediumSpec> legendre_medium;  // "legendre_medium"; none = no dynamic medium
};

// Parse a scene object. `source` prefixes error messages (normally the path).
Result<Scene> parse_scene(const nlohmann::json& j, const std::string& source);

// Read and parse one scene file. not_found if it does not exist, invalid_argument
// for bad JSON or fields.
Result<Scene> load_scene_file(const std::string& path);

// Resolve `name_or_path` and load it:
//  - absolute path, or one containing '/' or ending in ".json": a file path;
//    relative paths are tried against `base_dir` first, then the working dir;
//  - otherwise a scene name: `<dir>/<name>.json` for each dir in `scene_dirs`,
//    first match wins. not_found lists the directories searched and the scene
//    names they hold.
Result<Scene> load_scene(const std::string& name_or_path,
                         const std::vector<std::string>& scene_dirs,
                         const std::string& base_dir = {});

// Names (file stems) of the scenes in `scene_dirs`, sorted, without duplicates.
std::vector<std::string> list_scenes(const std::vector<std::string>& scene_dirs);

// A scene name a remote client may give: 1..128 bytes of [A-Za-z0-9_-]
// segments joined by '/', no empty, "." or ".." segment, no ".json". Returns
// the file it names in the first scene folder that has it, or
// invalid_argument (bad name, or no such scene: the message lists the known
// ones). Never reads a file outside `scene_dirs`. Reentrant.
Result<std::string> resolve_scene_name(const std::string& name, const std::vector<std::string>& scene_dirs);

}  // namespace procam::sim
