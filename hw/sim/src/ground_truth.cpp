// SPDX-License-Identifier: MIT
// Ground-truth maps from a prepared view, and their files.
#include "procam/hw/sim/ground_truth.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "procam/core/image_io.hpp"

#include "medium.hpp"
#include "tank.hpp"
#include "procam/hw/sim/sensor.hpp"

namespace procam::sim {
namespace {

// The full-white pattern (value 1 everywhere) through the projector's emission curve.
Result<PreparedPattern> white_pattern(const ProjectorModel& projector) {
  Image white(projector.intrinsics.width, projector.intrinsics.height, PixelType::f32);
  std::fill(white.ptr<float>(), white.ptr<float>() + white.pixel_count(), 1.f);
  return PreparedPattern::from_pattern(white.view(), projector);
}

}  // namespace

hw::GroundTruth ground_truth_from_view(const PreparedView& v) {
  hw::GroundTruth gt;
  gt.depth_mm = Image(v.width, v.height, PixelType::f32);
  gt.proj_col = Image(v.width, v.height, PixelType::f32);
  gt.proj_row = Image(v.width, v.height, PixelType::f32);
  gt.lit = Image(v.width, v.height, PixelType::u8);
  gt.object = Image(v.width, v.height, PixelType::u8);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  float* depth = gt.depth_mm.ptr<float>();
  float* col = gt.proj_col.ptr<float>();
  float* row = gt.proj_row.ptr<float>();
  uint8_t* lit = gt.lit.ptr<uint8_t>();
  uint8_t* object = gt.object.ptr<uint8_t>();
  for (size_t i = 0; i < v.pixel_count(); ++i) {
    depth[i] = v.depth_mm[i];
    const bool l = v.lit[i] != 0;
    col[i] = l ? v.proj_x[i] : nan;
    row[i] = l ? v.proj_y[i] : nan;
    lit[i] = l ? 255 : 0;
    const int32_t o = v.object[i];  // scenes hold at most 254 objects here; more share 255
    object[i] = o < 0 ? 0 : static_cast<uint8_t>(std::min<int32_t>(o + 1, 255));
  }
  return gt;
}

Status write_ground_truth(const hw::GroundTruth& truth, const std::string& folder,
                          const std::map<std::string, std::string>& attributes) {
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec)
    return Error(Code::io_error, "cannot create ground-truth folder '" + folder + "': " + ec.message());
  const std::filesystem::path dir(folder);
  struct Item { const char* file; const Image* image; const char* unit; };
  const Item items[] = {{"depth_mm.exr", &truth.depth_mm, "mm"},
                        {"proj_col.exr", &truth.proj_col, "px"},
                        {"proj_row.exr", &truth.proj_row, "px"},
                        {"lit.png", &truth.lit, ""},
                        {"object.png", &truth.object, ""},
                        {"medium_direct.exr", &truth.medium_direct, "DN"},
                        {"medium_indirect.exr", &truth.medium_indirect, "DN"},
                        {"medium_backscatter.exr", &truth.medium_backscatter, "DN"},
                        {"medium_backscatter_dop.exr", &truth.medium_backscatter_dop, ""},
                        {"medium_source.exr", &truth.medium_source, "DN"}};
  for (const Item& it : items) {
    const bool optional = it.image == &truth.object || it.image == &truth.medium_direct ||
                          it.image == &truth.medium_indirect || it.image == &truth.medium_backscatter ||
                          it.image == &truth.medium_backscatter_dop || it.image == &truth.medium_source;
    if (it.image->empty() && optional) continue;
    if (it.image->empty())
      return Error(Code::invalid_argument, std::string("ground truth map for '") + it.file + "' is empty");
    std::map<std::string, std::string> attrs = attributes;
    if (*it.unit) attrs["procam:unit"] = it.unit;
    const std::string path = (dir / it.file).string();
    Status st = write_image(path, *it.image, std::string(it.file).ends_with(".exr") ? attrs : std::map<std::string, std::string>{});
    if (!st.ok()) return st.with_context("writing ground truth '" + path + "'");
  }
  if (truth.medium.is_object() && truth.medium.contains("tank")) {
    // The tank rig's geometry for a plugin's params (docs/media.md "Tank rig").
    const std::string path = (dir / "tank.json").string();
    std::ofstream out(path);
    out << truth.medium["tank"].dump(1) << "\n";
    if (!out) return Error(Code::io_error, "cannot write ground truth '" + path + "'");
  }
  return Status::Ok();
}

Result<ComponentTruth> component_truth(const Renderer& renderer, PreparedPattern& pattern,
                                       const ProjectorModel& projector) {
  const uint32_t w = renderer.width(), h = renderer.height();
  ComponentTruth t{Image(w, h, PixelType::f32), Image(w, h, PixelType::f32), Image(w, h, PixelType::f32)};
  Status st = renderer.render_radiance_parts(pattern, t.direct.ptr<float>(), false, Renderer::Parts::direct_only);
  if (st.ok()) st = renderer.render_radiance_parts(pattern, t.global.ptr<float>(), false, Renderer::Parts::global_only);
  if (!st.ok()) return st;
  auto pw = white_pattern(projector);
  if (!pw.ok()) return pw.status();
  std::vector<float> d(size_t{w} * h), g(d.size());
  st = renderer.render_radiance_parts(*pw, d.data(), false, Renderer::Parts::direct_only);
  if (st.ok()) st = renderer.render_radiance_parts(*pw, g.data(), false, Renderer::Parts::global_only);
  if (!st.ok()) return st;
  float* r = t.global_direct_ratio_white.ptr<float>();
  for (size_t i = 0; i < d.size(); ++i) r[i] = d[i] > 0.f ? g[i] / d[i] : std::numeric_limits<float>::quiet_NaN();
  return t;
}

Status add_white_components(hw::GroundTruth& truth, const Renderer& renderer, const ProjectorModel& projector,
                            const SensorModel& sensor, double exposure_us, double gain_db) {
  const uint32_t w = renderer.width(), h = renderer.height();
  auto pw = white_pattern(projector);
  if (!pw.ok()) return pw.status();
  Image direct(w, h, PixelType::f32), global(w, h, PixelType::f32);
  Status st = renderer.render_radiance_parts(*pw, direct.ptr<float>(), false, Renderer::Parts::direct_only);
  if (st.ok()) st = renderer.render_radiance_parts(*pw, global.ptr<float>(), false, Renderer::Parts::global_only);
  if (!st.ok()) return st;
  // expected_dn is linear in radiance: one factor per frame.
  const double dn_per_ru = expected_dn(sensor, 1.0, exposure_us, gain_db);
  for (Image* im : {&direct, &global}) {
    float* p = im->ptr<float>();
    for (size_t i = 0; i < im->pixel_count(); ++i) p[i] = static_cast<float>(double(p[i]) * dn_per_ru);
  }
  truth.direct = std::move(direct);
  truth.global = std::move(global);
  return Status::Ok();
}

Status add_medium_components(hw::GroundTruth& truth, const Renderer& renderer, const Medium* medium,
                             const ProjectorModel& projector, const SensorModel& sensor, double exposure_us,
                             double gain_db, double projector_polarizer_deg) {
  const PreparedView& v = renderer.view();
  if (medium == nullptr || v.camera_transmittance.empty()) return Status::Ok();
  const uint32_t w = renderer.width(), h = renderer.height();
  auto pw = white_pattern(projector);
  if (!pw.ok()) return pw.status();
  Image d(w, h, PixelType::f32), a(w, h, PixelType::f32), b(w, h, PixelType::f32), dop(w, h, PixelType::f32);
  Status st = renderer.render_radiance_parts(*pw, d.ptr<float>(), false, Renderer::Parts::direct_only);
  if (st.ok()) st = renderer.render_radiance_parts(*pw, b.ptr<float>(), false, Renderer::Parts::volume_only);
  if (!st.ok()) return st;
  if (st.ok()) st = renderer.render_component(*pw, a.ptr<float>(), "medium-indirect");  // zeros if not modelled
  if (!st.ok()) return st;
  Image src;
  if (v.tank) {  // tank rig: B is the bulb's single scattering, the bulb itself apart
    src = Image(w, h, PixelType::f32);
    st = renderer.render_component(*pw, b.ptr<float>(), "tank-bulb-scatter");
    if (st.ok()) st = renderer.render_component(*pw, src.ptr<float>(), "tank-bulb-source");
    if (!st.ok()) return st;
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::fill(dop.ptr<float>(), dop.ptr<float>() + dop.pixel_count(), nan);
  if (v.medium) {
    const BackscatterStokes s = backscatter_stokes(*v.medium, *pw, projector_polarizer_deg, 1);
    float* p = dop.ptr<float>();
    for (size_t i = 0; i < s.i.size(); ++i)
      if (s.i[i] > 0.f)
        p[i] = std::min(1.f, std::sqrt(s.q[i] * s.q[i] + s.u[i] * s.u[i]) / s.i[i]);
  }
  if (v.tank) {  // the bulb is unpolarized
    const float* bp = b.ptr<float>();
    float* p = dop.ptr<float>();
    for (size_t i = 0; i < dop.pixel_count(); ++i) p[i] = bp[i] > 0.f ? 0.f : nan;
  }
  const double dn_per_ru = expected_dn(sensor, 1.0, exposure_us, gain_db);
  for (Image* im : {&d, &a, &b, &src}) {
    if (im->empty()) continue;
    float* p = im->ptr<float>();
    for (size_t i = 0; i < im->pixel_count(); ++i) p[i] = static_cast<float>(double(p[i]) * dn_per_ru);
  }
  truth.medium_direct = std::move(d);
  truth.medium_indirect = std::move(a);
  truth.medium_backscatter = std::move(b);
  truth.medium_backscatter_dop = std::move(dop);
  truth.medium_source = std::move(src);
  truth.medium = {{"extinction_per_mm", medium->sigma_t_per_mm},
                  {"scattering_per_mm", medium->sigma_s_per_mm},
                  {"hg_g", medium->g}};
  if (v.medium && !v.medium->ms_gain.empty())  // B includes orders >= 2 (docs/media.md "Multiple scattering")
    truth.medium["multiple_scattering"] = {{"model", "diffuse"},
                                           {"ratio_to_single", v.medium->ms_ratio},
                                           {"ratio_standard_error", v.medium->ms_ratio_se},
                                           {"polarized_share", v.medium->ms_keep},
                                           {"kernel_sigma_px", v.medium->ms_sigma_px}};
  if (!medium->material.empty())
    truth.medium["library"] = {{"material", medium->material},
                               {"volume_ml", medium->volume_ml},
                               {"tank_litres", medium->tank_litres},
                               {"channel", medium->channel}};
  if (v.tank) {
    nlohmann::json t = v.tank->geometry.to_json();
    t["dn_per_ru"] = dn_per_ru;  // frames' DN = dn_per_ru × ru at this exposure and gain
    t["exposure_us"] = exposure_us;
    truth.medium["tank"] = std::move(t);
  }
  return Status::Ok();
}

}  // namespace procam::sim
