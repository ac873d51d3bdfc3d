// SPDX-License-Identifier: MIT
// Scene JSON parsing and lookup by name (schema: hw/sim/SCENES.md).
#include "procam/hw/sim/scene.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "procam/core/json_fields.hpp"
#include "procam/hw/sim/medium_library.hpp"

namespace procam::sim {
namespace fs = std::filesystem;

namespace {

Material parse_material(FieldReader& obj) {
  Material m;
  const nlohmann::json* mj = obj.object("material", false);
  if (mj == nullptr) return m;
  FieldReader r(*mj, obj.field("material"), obj.errors());
  r.only({"albedo", "specular", "roughness_rad", "mean_free_path_mm", "scattering_albedo", "ior",
          "transmittance"});
  m.albedo = r.number("albedo", 0.5, "diffuse reflectance 0..1", 0.0, 1.0);
  m.specular = r.number("specular", 0.0, "glossy reflectance 0..1", 0.0, 1.0);
  m.roughness_rad = r.number("roughness_rad", 0.1, "glossy lobe sigma, radians", 0.001, 1.0);
  m.mean_free_path_mm = r.number("mean_free_path_mm", 0.0, "mm, 0 = opaque", 0.0, 100.0);
  m.scattering_albedo = r.number("scattering_albedo", 0.99, "0..1", 0.0, 0.999999);
  m.ior = r.number("ior", 1.5, "refractive index", 1.0, 4.0);
  m.transmittance = r.number("transmittance", 0.0, "0..1", 0.0, 1.0);
  if (!r.errors().ok()) return m;
  if (m.albedo + m.specular > 1.0 + 1e-12)
    r.fail("specular", "albedo + specular must be <= 1 (energy conservation), got " + std::to_string(m.albedo + m.specular));
  else if (m.albedo + m.transmittance > 1.0 + 1e-12)
    r.fail("transmittance", "albedo + transmittance must be <= 1 (energy conservation), got " +
                                std::to_string(m.albedo + m.transmittance));
  else if (m.translucent() && m.sheet())
    r.fail("transmittance", "a translucent body (mean_free_path_mm > 0) cannot also be a thin sheet",
           "use mean_free_path_mm for thick translucent bodies, transmittance for thin sheets");
  return m;
}

// Unit vector from a field; fails if (near) zero.
Vec3 unit_vec(FieldReader& r, const char* key, std::optional<Vec3> def) {
  Vec3 v = r.vec3(key, def, "direction, any length");
  if (r.errors().ok() && !(norm(v) > 1e-12)) {
    r.fail(key, "must be a non-zero vector");
    return {0, 0, 1};
  }
  return normalized(v);
}

Plane parse_plane(FieldReader& r) {
  r.only({"type", "name", "material", "point_mm", "normal", "size_mm", "u_axis", "texture"});
  Plane p;
  p.point_mm = r.vec3("point_mm", std::nullopt, "a point on the plane, mm");
  p.normal = unit_vec(r, "normal", std::nullopt);
  if (r.has("size_mm")) {
    auto s = r.numbers<2>("size_mm", std::nullopt, "[width, height] mm");
    if (r.errors().ok() && !(s[0] > 0 && s[1] > 0)) r.fail("size_mm", "both extents must be > 0");
    p.finite = true;
    p.width_mm = s[0];
    p.height_mm = s[1];
  } else if (r.has("u_axis")) {
    r.fail("u_axis", "only meaningful with size_mm (a finite rectangle)", "add \"size_mm\": [w, h] or remove u_axis");
  }
  // u axis: given, else camera x projected into the plane (camera y if x is ~normal).
  Vec3 u = r.has("u_axis") ? unit_vec(r, "u_axis", std::nullopt) : Vec3{1, 0, 0};
  if (!r.has("u_axis") && std::abs(dot(u, p.normal)) > 0.99) u = {0, 1, 0};
  Vec3 u_in = u - p.normal * dot(u, p.normal);
  if (r.errors().ok() && !(norm(u_in) > 1e-6)) {
    r.fail("u_axis", "must not be parallel to normal");
    return p;
  }
  p.u_axis = normalized(u_in);
  p.v_axis = cross(p.normal, p.u_axis);
  return p;
}

Box parse_box(FieldReader& r) {
  r.only({"type", "name", "material", "center_mm", "size_mm", "euler_deg"});
  Box b;
  b.center_mm = r.vec3("center_mm", std::nullopt, "box centre, mm");
  b.size_mm = r.vec3("size_mm", std::nullopt, "[sx, sy, sz] full edge lengths, mm");
  if (r.errors().ok() && !(b.size_mm.x > 0 && b.size_mm.y > 0 && b.size_mm.z > 0))
    r.fail("size_mm", "all three edge lengths must be > 0");
  Vec3 e = r.vec3("euler_deg", Vec3{0, 0, 0}, "[rx, ry, rz] degrees, R = Rz*Ry*Rx");
  b.rotation = rotation_from_euler_deg(e.x, e.y, e.z);
  return b;
}

Sphere parse_sphere(FieldReader& r) {
  r.only({"type", "name", "material", "center_mm", "radius_mm"});
  Sphere s;
  s.center_mm = r.vec3("center_mm", std::nullopt, "sphere centre, mm");
  s.radius_mm = r.positive("radius_mm", std::nullopt, "mm");
  return s;
}

Cylinder parse_cylinder(FieldReader& r) {
  r.only({"type", "name", "material", "center_mm", "axis", "radius_mm", "height_mm", "caps"});
  Cylinder c;
  c.center_mm = r.vec3("center_mm", std::nullopt, "centre of the axis segment, mm");
  c.axis = unit_vec(r, "axis", Vec3{0, 1, 0});
  c.radius_mm = r.positive("radius_mm", std::nullopt, "mm");
  c.height_mm = r.positive("height_mm", std::nullopt, "mm");
  c.caps = r.boolean("caps", true);
  return c;
}

Bowl parse_bowl(FieldReader& r) {
  r.only({"type", "name", "material", "center_mm", "radius_mm", "depth_mm", "opening"});
  Bowl b;
  b.center_mm = r.vec3("center_mm", std::nullopt, "centre of the rim disc, mm");
  b.radius_mm = r.positive("radius_mm", std::nullopt, "mm");
  b.depth_mm = r.positive("depth_mm", b.radius_mm, "mm (default: radius_mm, a hemisphere)");
  b.opening = unit_vec(r, "opening", Vec3{0, 0, -1});
  return b;
}

// "image" texture fields: {"file": PGM path (relative: to the scene file's
// folder), "size_mm": [width, height] printed size}.
void parse_image_texture(FieldReader& r, ChessboardTexture& t, const std::string& source) {
  const std::string file = r.string("file", std::nullopt);
  const auto size = r.numbers<2>("size_mm", std::nullopt, "[width, height] printed size, mm");
  if (!r.errors().ok()) return;
  if (!(size[0] > 0 && size[1] > 0)) {
    r.fail("size_mm", "both extents must be > 0");
    return;
  }
  fs::path path(file);
  if (path.is_relative() && !source.empty()) path = fs::path(source).parent_path() / path;
  auto bmp = read_pgm(path.string());
  if (!bmp.ok()) {
    r.fail("file", bmp.status().message(), bmp.status().hint());
    return;
  }
  t.image = std::make_shared<const GreyBitmap>(std::move(*bmp));
  t.image_width_mm = size[0];
  t.image_height_mm = size[1];
}

// "texture" of a plane (texture.hpp): {"type": "chessboard", "inner_corners":
// [cols, rows], "square_mm", "dark", "light", "border_squares"} or {"type":
// "image", "file", "size_mm", "dark", "light"}. The plane's material must be
// opaque and not a sheet, and a finite plane must hold the textured area.
ChessboardTexture parse_texture(FieldReader& obj, const Plane& plane, const Material& m, const std::string& source) {
  ChessboardTexture t;
  const nlohmann::json* tj = obj.object("texture", true);
  if (tj == nullptr) return t;
  FieldReader r(*tj, obj.field("texture"), obj.errors());
  const std::string type = r.string("type", std::nullopt);
  if (r.errors().ok() && type != "chessboard" && type != "image") {
    r.fail("type", "unknown texture type '" + type + "'", "use \"chessboard\" or \"image\"");
    return t;
  }
  if (type == "image") {
    r.only({"type", "file", "size_mm", "dark", "light", "comment"});
    parse_image_texture(r, t, source);
  } else {
    r.only({"type", "inner_corners", "square_mm", "dark", "light", "border_squares", "comment"});
    const auto ic = r.numbers<2>("inner_corners", std::nullopt, "[cols, rows] inner corners");
    if (r.errors().ok()) {
      for (double c : ic)
        if (!(c >= 2 && c <= 100 && c == std::floor(c))) {
          r.fail("inner_corners", "both counts must be integers in [2, 100], got [" + FieldReader::num_str(ic[0]) +
                                      ", " + FieldReader::num_str(ic[1]) + "]");
          return t;
        }
      t.cols = static_cast<int>(ic[0]);
      t.rows = static_cast<int>(ic[1]);
    }
    t.square_mm = r.number("square_mm", std::nullopt, "edge of one square, mm", 0.1, 1000.0);
    t.border_squares = static_cast<int>(r.integer("border_squares", 1, 0, 100));
  }
  t.dark = r.number("dark", 0.05, "albedo of the dark squares", 0.0, 1.0);
  t.light = r.number("light", 0.9, "albedo of the light squares and the border", 0.0, 1.0);
  if (!r.errors().ok()) return t;
  if (m.translucent() || m.sheet()) {
    obj.fail("texture", "a texture needs an opaque material (no mean_free_path_mm, no transmittance)");
  } else if (std::max(t.dark, t.light) + m.specular > 1.0 + 1e-12) {
    r.fail("light", "max(dark, light) + material.specular must be <= 1 (energy conservation)");
  } else if (plane.finite && (plane.width_mm < 2 * t.half_width_mm() - 1e-9 ||
                              plane.height_mm < 2 * t.half_height_mm() - 1e-9)) {
    obj.fail("size_mm", "the plane (" + FieldReader::num_str(plane.width_mm) + " x " +
                            FieldReader::num_str(plane.height_mm) + " mm) must hold the board with its border (" +
                            FieldReader::num_str(2 * t.half_width_mm()) + " x " +
                            FieldReader::num_str(2 * t.half_height_mm()) + " mm)",
             "enlarge size_mm or lower border_squares / square_mm");
  }
  return t;
}

std::string read_file(const std::string& path, Status& st) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    st = Error(fs::exists(path) ? Code::io_error : Code::not_found,
               "scene file '" + path + "' " + (fs::exists(path) ? "cannot be read" : "does not exist"),
               "check the path, or give a scene name found in the scene directories");
    return {};
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

// "medium" σ, β, g from the library (medium_library.hpp): "material" is a
// name, a "a + b 1:3" spec (with "volume_ml" the total), or a list of
// {"name", "volume_ml"}.
static void parse_medium_material(FieldReader& r, Medium& m) {
  for (const char* k : {"sigma_t_per_mm", "sigma_s_per_mm", "g"})
    if (r.has(k)) {
      r.fail(k, "not allowed together with \"material\"", "give either a library material or sigma/beta/g numbers");
      return;
    }
  m.tank_litres = r.number("tank_litres", 23.0, "litres in the tank (thesis: 23)", 1e-6, 1e6);
  m.channel = r.string("channel", std::string("green"));
  if (!r.errors().ok()) return;
  const Result<ColorChannel> channel = parse_color_channel(m.channel);
  if (!channel.ok()) {
    r.fail("channel", channel.status().message(), channel.status().hint());
    return;
  }
  const nlohmann::json* mat = r.get("material");
  std::vector<MixturePart> parts;
  if (mat->is_string()) {
    m.material = mat->get<std::string>();
    m.volume_ml = r.positive("volume_ml", std::nullopt, "ml of the material (or mixture) in the tank");
    if (!r.errors().ok()) return;
    Result<std::vector<MixturePart>> p = parse_mixture_spec(m.material, m.volume_ml);
    if (!p.ok()) {
      r.fail("material", p.status().message(), p.status().hint());
      return;
    }
    parts = std::move(*p);
  } else if (mat->is_array() && !mat->empty()) {
    if (r.has("volume_ml")) {
      r.fail("volume_ml", "not allowed with a list of materials", "give each part its own volume_ml");
      return;
    }
    for (size_t i = 0; i < mat->size() && r.errors().ok(); ++i) {
      FieldReader pr((*mat)[i], r.field("material") + "[" + std::to_string(i) + "]", r.errors());
      pr.only({"name", "volume_ml"});
      MixturePart part;
      part.name = pr.string("name", std::nullopt);
      part.volume_ml = pr.positive("volume_ml", std::nullopt, "ml of this material in the tank");
      m.material += (m.material.empty() ? "" : " + ") + part.name;
      m.volume_ml += part.volume_ml;
      parts.push_back(part);
    }
    if (!r.errors().ok()) return;
  } else {
    r.fail("material", std::string("must be a name or a non-empty list of {name, volume_ml}, got ") + mat->type_name(),
           "e.g. \"Merlot\" or \"milk + espresso 1:3\"");
    return;
  }
  const Result<Medium> lib = mixture_medium(parts, m.tank_litres, *channel);
  if (!lib.ok()) {
    r.fail("material", lib.status().message(), lib.status().hint());
    return;
  }
  m.sigma_t_per_mm = lib->sigma_t_per_mm;
  m.sigma_s_per_mm = lib->sigma_s_per_mm;
  m.g = std::clamp(lib->g, -0.999, 0.999);
}

// "medium"."bulb": the tank rig's light source; needs the tank (a box) with
// the whole sphere inside it.
static void parse_bulb(FieldReader& medium, Medium& m) {
  const nlohmann::json* bj = medium.object("bulb", false);
  if (bj == nullptr) return;
  FieldReader r(*bj, medium.field("bulb"), medium.errors());
  r.only({"center_mm", "radius_mm", "irradiance_at_1m", "samples", "comment"});
  Medium::Bulb b;
  b.center_mm = r.vec3("center_mm", std::nullopt, "bulb centre, mm, world frame");
  b.radius_mm = r.number("radius_mm", 10.0, "mm", 0.1, 1000.0);
  b.irradiance_at_1m = r.positive("irradiance_at_1m", 0.01, "iu at 1 m per unit emitted light");
  b.samples = static_cast<int>(r.integer("samples", 10, 1, 64));
  if (!r.errors().ok()) return;
  if (m.whole_scene) {
    r.fail("center_mm", "a bulb needs the tank: give medium.box_min_mm and box_max_mm");
    return;
  }
  const Vec3& c = b.center_mm;
  const double rr = b.radius_mm;
  if (!(c.x - rr > m.box_min_mm.x && c.x + rr < m.box_max_mm.x && c.y - rr > m.box_min_mm.y &&
        c.y + rr < m.box_max_mm.y && c.z - rr > m.box_min_mm.z && c.z + rr < m.box_max_mm.z))
    r.fail("center_mm", "the bulb (centre ± radius_mm) must lie inside the tank box",
           "move it inwards or make it smaller");
  m.bulb = b;
}

// "medium" (SCENES.md): homogeneous, whole scene or an axis-aligned box;
// σ, β, g as numbers or from the material library.
Medium parse_medium(FieldReader& root) {
  Medium m;
  const nlohmann::json* mj = root.object("medium", false);
  if (mj == nullptr) return m;
  FieldReader r(*mj, root.field("medium"), root.errors());
  r.only({"sigma_t_per_mm", "sigma_s_per_mm", "g", "material", "volume_ml", "tank_litres", "channel", "dop_model",
          "multiple_scattering", "box_min_mm", "box_max_mm", "bulb", "comment"});
  if (r.has("material")) {
    parse_medium_material(r, m);
  } else {
    for (const char* k : {"volume_ml", "tank_litres", "channel"})
      if (r.has(k)) r.fail(k, "only meaningful with \"material\"", "name a library material, or remove it");
    m.sigma_t_per_mm = r.number("sigma_t_per_mm", std::nullopt, "extinction, 1/mm", 0.0, 10.0);
    m.sigma_s_per_mm = r.number("sigma_s_per_mm", std::nullopt, "scattering, 1/mm", 0.0, 10.0);
    m.g = r.number("g", 0.0, "Henyey-Greenstein asymmetry, |g| < 1", -0.999, 0.999);
  }
  const std::string dop = r.string("dop_model", std::string("rayleigh"));
  if (!r.errors().ok()) return m;
  if (dop == "rayleigh") m.dop_model = Medium::DopModel::rayleigh;
  else if (dop == "none") m.dop_model = Medium::DopModel::none;
  else r.fail("dop_model", "unknown model '" + dop + "'", "use \"rayleigh\" or \"none\"");
  const std::string ms = r.string("multiple_scattering", std::string("none"));
  if (ms == "none") m.multiple_scattering = Medium::MultipleScattering::none;
  else if (ms == "diffuse") m.multiple_scattering = Medium::MultipleScattering::diffuse;
  else r.fail("multiple_scattering", "unknown model '" + ms + "'", "use \"none\" or \"diffuse\"");
  if (m.sigma_s_per_mm > m.sigma_t_per_mm)
    r.fail("sigma_s_per_mm", "scattering must not exceed extinction (beta <= sigma), got beta " +
                                 std::to_string(m.sigma_s_per_mm) + " > sigma " + std::to_string(m.sigma_t_per_mm),
           "sigma_t_per_mm = scattering + absorption");
  if (r.has("box_min_mm") != r.has("box_max_mm")) {
    r.fail(r.has("box_min_mm") ? "box_max_mm" : "box_min_mm", "missing: a tank needs both box_min_mm and box_max_mm",
           "give both corners, or neither for a medium filling the whole scene");
    return m;
  }
  if (r.has("box_min_mm")) {
    m.whole_scene = false;
    m.box_min_mm = r.vec3("box_min_mm", std::nullopt, "mm, world frame");
    m.box_max_mm = r.vec3("box_max_mm", std::nullopt, "mm, world frame");
    if (r.errors().ok() && !(m.box_max_mm.x > m.box_min_mm.x && m.box_max_mm.y > m.box_min_mm.y &&
                             m.box_max_mm.z > m.box_min_mm.z))
      r.fail("box_max_mm", "empty box: box_max_mm must exceed box_min_mm on every axis");
  }
  if (r.errors().ok()) parse_bulb(r, m);
  return m;
}

// "legendre_medium" (SCENES.md): a dynamic medium in a closed box.
LegendreMediumSpec parse_legendre_medium(FieldReader& root) {
  LegendreMediumSpec m;
  const nlohmann::json* mj = root.object("legendre_medium", false);
  if (mj == nullptr) return m;
  FieldReader r(*mj, root.field("legendre_medium"), root.errors());
  r.only({"box_min_mm", "box_max_mm", "n", "density_uniform", "blobs", "swirl_mm_s", "viscosity_mm2_s",
          "dissipation_per_s", "sigma_t_per_mm", "sigma_s_per_mm", "g", "dop_model", "albedo_uniform", "albedo_blobs", "frame_period_s",
          "comment"});
  m.box_min_mm = r.vec3("box_min_mm", std::nullopt, "mm, world frame");
  m.box_max_mm = r.vec3("box_max_mm", std::nullopt, "mm, world frame");
  m.n = static_cast<int>(r.integer("n", 5, 3, 8));
  m.density_uniform = r.number("density_uniform", 0.0, "dimensionless", 0.0, 100.0);
  m.swirl_mm_s = r.number("swirl_mm_s", 0.0, "mm/s", -1e4, 1e4);
  m.viscosity_mm2_s = r.number("viscosity_mm2_s", 0.0, "mm^2/s", 0.0, 1e6);
  m.dissipation_per_s = r.number("dissipation_per_s", 0.0, "1/s", 0.0, 1e3);
  m.sigma_t_per_mm = r.number("sigma_t_per_mm", std::nullopt, "extinction at density 1, 1/mm", 0.0, 10.0);
  m.sigma_s_per_mm = r.number("sigma_s_per_mm", std::nullopt, "scattering at density 1, 1/mm", 0.0, 10.0);
  m.g = r.number("g", 0.0, "Henyey-Greenstein asymmetry, |g| < 1", -0.999, 0.999);
  m.frame_period_s = r.number("frame_period_s", 1.0 / 30.0, "s per captured frame", 1e-6, 60.0);
  const std::string dop = r.string("dop_model", std::string("rayleigh"));
  if (dop == "rayleigh") m.dop_model = Medium::DopModel::rayleigh;
  else if (dop == "none") m.dop_model = Medium::DopModel::none;
  else r.fail("dop_model", "unknown model '" + dop + "'", "use \"rayleigh\" or \"none\"");
  if (r.has("albedo_uniform"))
    m.albedo_uniform = r.number("albedo_uniform", 0.0, "single-scattering albedo beta/sigma", 0.0, 1.0);
  auto read_blobs = [&](const char* key, double peak_min, std::vector<LegendreMediumSpec::Blob>& out) {
    const nlohmann::json* blobs = r.get(key);
    if (blobs == nullptr) return;
    if (!blobs->is_array()) r.fail(key, std::string("must be an array, got ") + blobs->type_name());
    for (size_t i = 0; r.errors().ok() && blobs->is_array() && i < blobs->size(); ++i) {
      FieldReader b((*blobs)[i], r.field(key) + "[" + std::to_string(i) + "]", r.errors());
      if (!r.errors().ok()) break;
      b.only({"center_mm", "radius_mm", "peak", "comment"});
      LegendreMediumSpec::Blob blob;
      blob.center_mm = b.vec3("center_mm", std::nullopt, "mm, world frame");
      blob.radius_mm = b.positive("radius_mm", std::nullopt, "mm");
      blob.peak = b.number("peak", 1.0, "dimensionless", peak_min, 100.0);
      out.push_back(blob);
    }
  };
  read_blobs("blobs", 0.0, m.blobs);
  read_blobs("albedo_blobs", -1.0, m.albedo_blobs);  // may lower the albedo locally
  if (!r.errors().ok()) return m;
  if (!(m.box_max_mm.x > m.box_min_mm.x && m.box_max_mm.y > m.box_min_mm.y && m.box_max_mm.z > m.box_min_mm.z))
    r.fail("box_max_mm", "empty box: box_max_mm must exceed box_min_mm on every axis");
  if (m.sigma_s_per_mm > m.sigma_t_per_mm)
    r.fail("sigma_s_per_mm", "scattering must not exceed extinction (beta <= sigma)", "sigma_t_per_mm = scattering + absorption");
  return m;
}

Result<Scene> parse_scene(const nlohmann::json& j, const std::string& source) {
  try {
    ParseErrors errors{source.empty() ? std::string("scene") : source, {}};
    FieldReader root(j, "", errors);
    root.only({"name", "description", "comment", "ambient", "objects", "medium", "legendre_medium"});
    Scene scene;
    scene.source = source;
    scene.name = root.string("name", fs::path(source).stem().string());
    scene.description = root.string("description", std::string());
    scene.ambient = root.number("ambient", 0.0, "irradiance, iu", 0.0);
    if (root.has("medium")) {
      Medium m = parse_medium(root);
      if (!errors.ok()) return errors.first;
      scene.medium = m;
    }
    if (root.has("legendre_medium")) {
      LegendreMediumSpec m = parse_legendre_medium(root);
      if (!errors.ok()) return errors.first;
      scene.legendre_medium = m;
    }
    const nlohmann::json* objs = root.get("objects");
    if (objs == nullptr) {
      root.fail("objects", "missing (required array of objects)");
    } else if (!objs->is_array()) {
      root.fail("objects", std::string("must be an array, got ") + objs->type_name());
    } else {
      for (size_t i = 0; i < objs->size() && errors.ok(); ++i) {
        FieldReader r((*objs)[i], "objects[" + std::to_string(i) + "]", errors);
        if (!errors.ok()) break;
        Object o;
        std::string type = r.string("type", std::nullopt);
        o.name = r.string("name", std::string());
        if (!errors.ok()) break;
        if (type != "plane" && r.has("texture")) {
          r.fail("texture", "only planes take a texture", "put the board on a \"plane\" object");
          break;
        }
        if (type == "plane") {
          o.shape = parse_plane(r);
        } else if (type == "box") {
          o.shape = parse_box(r);
        } else if (type == "sphere") {
          o.shape = parse_sphere(r);
        } else if (type == "cylinder") {
          o.shape = parse_cylinder(r);
        } else if (type == "bowl") {
          o.shape = parse_bowl(r);
        } else {
          r.fail("type", "unknown object type '" + type + "'", "use one of: plane, box, sphere, cylinder, bowl");
          break;
        }
        o.material = parse_material(r);
        if (r.has("texture") && errors.ok())
          o.texture = parse_texture(r, std::get<Plane>(o.shape), o.material, source);
        scene.objects.push_back(std::move(o));
      }
    }
    if (!errors.ok()) return errors.first;
    return scene;
  } catch (const std::exception& e) {
    return Error(Code::internal, (source.empty() ? std::string("scene") : source) +
                                     ": unexpected error while parsing: " + e.what());
  }
}

Result<Scene> load_scene_file(const std::string& path) {
  Status st;
  std::string text = read_file(path, st);
  if (!st.ok()) return st;
  nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    // Re-parse with exceptions only to get the position for the message.
    std::string detail;
    try {
      const nlohmann::json again = nlohmann::json::parse(text);
      detail = "parse error";
    } catch (const std::exception& e) {
      detail = e.what();
    }
    return Error(Code::invalid_argument, path + ": not valid JSON: " + detail,
                 "fix the syntax (see hw/sim/SCENES.md for the schema)");
  }
  return parse_scene(j, path);
}

std::vector<std::string> list_scenes(const std::vector<std::string>& scene_dirs) {
  std::set<std::string> names;
  for (const auto& dir : scene_dirs) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) continue;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      if (entry.path().extension() == ".json") names.insert(entry.path().stem().string());
    }
  }
  return {names.begin(), names.end()};
}

Result<std::string> resolve_scene_name(const std::string& name, const std::vector<std::string>& scene_dirs) {
  auto known = [&] {
    std::string k;
    for (const auto& n : list_scenes(scene_dirs)) k += (k.empty() ? "" : ", ") + n;
    return k.empty() ? std::string("no scene files in the rig's scene folders") : "scenes: " + k;
  };
  bool ok = !name.empty() && name.size() <= 128;
  size_t seg = 0;
  for (size_t i = 0; ok && i <= name.size(); ++i) {
    if (i == name.size() || name[i] == '/') {
      const std::string part = name.substr(seg, i - seg);
      ok = !part.empty() && part != "." && part != "..";
      seg = i + 1;
      continue;
    }
    const char c = name[i];
    ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  }
  if (!ok)
    return Error(Code::invalid_argument,
                 "scene '" + name + "' is not a scene name (letters, digits, '_', '-', '/' between parts)",
                 "name a scene of the rig's scene folders, not a file; " + known());
  for (const auto& dir : scene_dirs) {
    const fs::path p = fs::path(dir) / (name + ".json");
    std::error_code ec;
    if (fs::is_regular_file(p, ec)) return p.string();
  }
  return Error(Code::invalid_argument, "scene '" + name + "' is not one of the rig's scenes", known());
}

Result<Scene> load_scene(const std::string& name_or_path, const std::vector<std::string>& scene_dirs,
                         const std::string& base_dir) {
  try {
    if (name_or_path.empty())
      return Error(Code::invalid_argument, "scene: empty scene name", "give a scene name such as \"plane\" or a path to a .json file");
    const bool is_path = name_or_path.find('/') != std::string::npos ||
                         fs::path(name_or_path).extension() == ".json";
    if (is_path) {
      fs::path p(name_or_path);
      if (p.is_relative() && !base_dir.empty() && fs::exists(fs::path(base_dir) / p))
        return load_scene_file((fs::path(base_dir) / p).string());
      return load_scene_file(p.string());
    }
    std::string searched;
    for (const auto& dir : scene_dirs) {
      fs::path p = fs::path(dir) / (name_or_path + ".json");
      if (fs::exists(p)) return load_scene_file(p.string());
      searched += (searched.empty() ? "" : ", ") + dir;
    }
    std::string known;
    for (const auto& n : list_scenes(scene_dirs)) known += (known.empty() ? "" : ", ") + n;
    return Error(Code::not_found,
                 "scene '" + name_or_path + "' not found in scene directories [" + searched + "]",
                 known.empty() ? "no scene files found; pass a path to a scene .json file"
                               : "available scenes: " + known);
  } catch (const std::exception& e) {
    return Error(Code::io_error, "scene '" + name_or_path + "': " + e.what());
  }
}

}  // namespace procam::sim
