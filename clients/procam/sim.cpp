// SPDX-License-Identifier: MIT
// `procam sim`: render one pattern on a simulated scene, offline (no daemon),
// with its ground truth and the direct / global split; list the scenes.
//
//   procam sim --scene NAME_OR_FILE --pattern P --out DIR [--rig RIG.json]
//   procam sim --list scenes [--rig RIG.json]
//
// Patterns (projector-sized, 1 channel): white, black, gray:BIT[:inv] (bit BIT
// of the reflected binary Gray code of the projector column, BIT 0 = most
// significant = lowest frequency), checker:SIZE:DX:DY (SIZE-pixel squares,
// shifted by DX, DY pixels; lit where ((x+DX)/SIZE + (y+DY)/SIZE) is even), or
// an image file. Outputs (docs/sim.md "CLI"): image.png (the captured frame),
// radiance.exr, direct.exr, global.exr (ru), ratio.exr (global/direct under
// white), depth_mm.exr, proj_col.exr, proj_row.exr, lit.png, info.json;
// `--components 1` also component-<name>.exr per transport component (ru, no
// ambient: Renderer::render_component), e.g. the glossy-view and mirror paths.
// `--frames N` (scenes with a "legendre_medium", docs/legendre.md): also
// frame_000.png .. frame_N-1.png, the captured frame with the dynamic medium
// at t = k * frame_period_s (a PNG sequence of the medium's motion), and the
// same frames as animation.gif (animation.hpp; played at 1/frame_period_s,
// at most 100 fps).
// `--pattern gray-errors` prints instead the noise-free binarization error of
// every Gray bit (pattern vs inverse, thesis Eq. 3.5) on the lit pixels.
// Errors go to stderr with a non-zero exit status; nothing is thrown.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "animation.hpp"
#include "cli.hpp"
#include "procam/core/image_io.hpp"
#include "procam/hw/sim/global.hpp"
#include "procam/hw/sim/ground_truth.hpp"
#include "procam/hw/sim/sensor.hpp"
#include "procam/hw/sim/sim_rig.hpp"

namespace procam::cli {
namespace {
namespace fs = std::filesystem;
using namespace procam::sim;

#ifndef PROCAM_DEFAULT_RIG
#define PROCAM_DEFAULT_RIG "configs/rigs/sim.json"
#endif

Result<SimRigConfig> load_rig(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Error(Code::not_found, "rig config '" + path + "' cannot be read", "pass --rig configs/rigs/sim.json");
  nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded()) return Error(Code::invalid_argument, path + ": not valid JSON");
  return parse_sim_rig_config(j, path);
}

std::vector<std::string> scene_dirs_for(const std::string& rig_path) {
  return {(fs::path(rig_path).parent_path() / ".." / "scenes").lexically_normal().string()};
}

// The pattern as a U8 projector image.
Result<Image> make_pattern(const std::string& spec, uint32_t w, uint32_t h) {
  Image im(w, h, PixelType::u8);
  auto fill = [&](auto value) {
    for (uint32_t y = 0; y < h; ++y) {
      uint8_t* r = im.row<uint8_t>(y);
      for (uint32_t x = 0; x < w; ++x) r[x] = value(x, y) ? 255 : 0;
    }
  };
  const std::vector<std::string> f = split_colon(spec);
  try {
    if (spec == "white") {
      fill([](uint32_t, uint32_t) { return true; });
    } else if (spec == "black") {
      fill([](uint32_t, uint32_t) { return false; });
    } else if (f.size() >= 2 && f[0] == "gray") {
      uint32_t bits = 0;
      while ((1u << bits) < w) ++bits;
      const auto bit = static_cast<uint32_t>(std::stoul(f[1]));
      if (bit >= bits) return Error(Code::invalid_argument, "--pattern " + spec + ": BIT must be < " + std::to_string(bits));
      const bool inv = f.size() >= 3 && f[2] == "inv";
      fill([&](uint32_t x, uint32_t) {
        const uint32_t g = x ^ (x >> 1);
        return (((g >> (bits - 1 - bit)) & 1u) != 0) != inv;
      });
    } else if (f.size() == 4 && f[0] == "checker") {
      const auto size = static_cast<uint32_t>(std::stoul(f[1]));
      const auto dx = static_cast<uint32_t>(std::stoul(f[2])), dy = static_cast<uint32_t>(std::stoul(f[3]));
      if (size == 0) return Error(Code::invalid_argument, "--pattern " + spec + ": SIZE must be > 0");
      fill([&](uint32_t x, uint32_t y) { return (((x + dx) / size + (y + dy) / size) % 2) == 0; });
    } else if (fs::path(spec).has_extension()) {
      auto r = read_image(spec);
      if (!r.ok()) return r.status();
      if (r->width() != w || r->height() != h || r->channels() != 1)
        return Error(Code::invalid_argument, spec + ": pattern must be a " + std::to_string(w) + "x" + std::to_string(h) +
                                                 " single-channel image");
      return std::move(r).value();
    } else {
      return Error(Code::invalid_argument, "--pattern '" + spec + "' not understood",
                   "use white, black, gray:BIT[:inv], checker:SIZE:DX:DY or an image file");
    }
  } catch (const std::exception&) {
    return Error(Code::invalid_argument, "--pattern '" + spec + "': bad number");
  }
  return im;
}

Image f32_image(const std::vector<float>& v, uint32_t w, uint32_t h) {
  Image im(w, h, PixelType::f32);
  std::copy(v.begin(), v.end(), im.ptr<float>());
  return im;
}

int list_scenes_cmd(const Args& a, const std::string& rig_path) {
  const auto dirs = scene_dirs_for(rig_path);
  nlohmann::json out = nlohmann::json::array();
  for (const auto& name : list_scenes(dirs)) {
    auto s = load_scene(name, dirs);
    out.push_back({{"name", name}, {"description", s.ok() ? s->description : s.status().to_string()}});
  }
  if (a.json) {
    std::printf("%s\n", out.dump(2).c_str());
  } else {
    for (const auto& s : out) {
      std::string d = s["description"].get<std::string>();
      if (d.size() > 100) d = d.substr(0, 97) + "...";
      std::printf("%-16s %s\n", s["name"].get<std::string>().c_str(), d.c_str());
    }
  }
  return 0;
}

// Noise-free binarization errors per Gray bit (thesis Eq. 3.5): for every lit
// pixel, bit k is read as radiance(P_k) > radiance(P̄_k) and compared with bit
// k of the Gray code of the true projector column (rounded). Prints one line
// per bit: bit, stripe width in projector px, % of lit pixels wrong.
int gray_errors(const Args& a, const Scene& scene, const Renderer& r, const ProjectorModel& proj) {
  const PreparedView& v = r.view();
  uint32_t bits = 0;
  while ((1u << bits) < proj.intrinsics.width) ++bits;
  std::vector<float> lit_img(v.pixel_count()), dark_img(v.pixel_count());
  nlohmann::json rows = nlohmann::json::array();
  size_t lit = 0;
  for (size_t i = 0; i < v.pixel_count(); ++i) lit += v.lit[i];
  for (uint32_t bit = 0; bit < bits; ++bit) {
    auto p = make_pattern("gray:" + std::to_string(bit), proj.intrinsics.width, proj.intrinsics.height);
    auto q = make_pattern("gray:" + std::to_string(bit) + ":inv", proj.intrinsics.width, proj.intrinsics.height);
    auto pp = PreparedPattern::from_pattern(p->view(), proj), pq = PreparedPattern::from_pattern(q->view(), proj);
    Status st = r.render_radiance(*pp, lit_img.data(), true);
    if (st.ok()) st = r.render_radiance(*pq, dark_img.data(), true);
    if (!st.ok()) return report(st);
    size_t wrong = 0;
    for (size_t i = 0; i < v.pixel_count(); ++i) {
      if (!v.lit[i]) continue;
      const auto c = static_cast<uint32_t>(std::clamp(std::lround(v.proj_x[i]), 0l, static_cast<long>(proj.intrinsics.width - 1)));
      const bool truth = (((c ^ (c >> 1)) >> (bits - 1 - bit)) & 1u) != 0;
      if ((lit_img[i] > dark_img[i]) != truth) ++wrong;
    }
    rows.push_back({{"bit", bit}, {"stripe_px", 1u << (bits - 1 - bit)},
                    {"wrong_fraction", lit ? static_cast<double>(wrong) / static_cast<double>(lit) : 0.0}});
  }
  if (a.json) {
    std::printf("%s\n", nlohmann::json{{"scene", scene.name}, {"lit_pixels", lit}, {"bits", rows}}.dump(2).c_str());
  } else {
    std::printf("%s:", scene.name.c_str());
    for (const auto& row : rows) std::printf(" %.1f", 100.0 * row["wrong_fraction"].get<double>());
    std::printf("   (%% of %zu lit px wrong per Gray bit, bit 0 = widest stripes)\n", lit);
  }
  return 0;
}

}  // namespace

int cmd_sim(const Args& a) {
  const std::string rig_path = a.get("rig", PROCAM_DEFAULT_RIG);
  if (a.has("list")) {
    if (a.get("list") != "scenes") return usage_error("sim --list: only 'scenes' can be listed");
    return list_scenes_cmd(a, rig_path);
  }
  if (!a.has("scene") || (!a.has("out") && a.get("pattern") != "gray-errors"))
    return usage_error("sim needs --scene and --out (or --list scenes, or --pattern gray-errors)");
  auto rig = load_rig(rig_path);
  if (!rig.ok()) return report(rig.status());
  auto scene = load_scene(a.get("scene"), scene_dirs_for(rig_path));
  if (!scene.ok()) return report(scene.status());
  const ProjectorModel& proj = rig->projector;
  const SimCameraConfig& cam = rig->cameras[0];
  const int threads = rig->threads > 0 ? rig->threads : 2;
  PrepStats prep;
  auto ren = make_scene_renderer(*scene, proj, cam.calibration, cam.calibration.cam_from_proj, GlobalOptions{},
                                 threads, &prep);
  if (!ren.ok()) return report(ren.status());
  Renderer& r = **ren;
  r.set_camera_lens(cam.lens);
  if (a.get("pattern") == "gray-errors") return gray_errors(a, *scene, r, proj);
  auto pattern = make_pattern(a.get("pattern", "white"), proj.intrinsics.width, proj.intrinsics.height);
  if (!pattern.ok()) return report(pattern.status());
  auto prepared = PreparedPattern::from_pattern(pattern->view(), proj);
  if (!prepared.ok()) return report(prepared.status());
  const uint32_t w = r.width(), h = r.height();
  std::vector<float> full(size_t{w} * h);
  const auto t0 = std::chrono::steady_clock::now();
  Status st = r.render_radiance(*prepared, full.data(), true);
  const double render_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!st.ok()) return report(st);
  auto parts = component_truth(r, *prepared, proj);
  if (!parts.ok()) return report(parts.status());

  const std::string out = a.get("out");
  std::error_code ec;
  fs::create_directories(out, ec);
  const std::map<std::string, std::string> attrs = {{"scene", scene->name}, {"pattern", a.get("pattern", "white")},
                                                    {"unit", "ru"}};
  Image frame = expose(full.data(), w, h, cam.sensor, cam.sensor.exposure_us, cam.sensor.gain_db,
                       frame_noise_seed(rig->seed, 0, 0), threads);
  for (const auto& [name, img] : std::vector<std::pair<std::string, Image>>{
           {"image.png", std::move(frame)},
           {"radiance.exr", f32_image(full, w, h)},
           {"direct.exr", std::move(parts->direct)},
           {"global.exr", std::move(parts->global)},
           {"ratio.exr", std::move(parts->global_direct_ratio_white)}}) {
    Status ws = write_image(out + "/" + name, img, attrs);
    if (!ws.ok()) return report(ws);
  }
  if (a.get("components", "0") == "1") {  // one image per transport path (ground truth of single paths)
    std::vector<float> part(size_t{w} * h);
    for (const auto& c : r.components()) {
      Status cs = r.render_component(*prepared, part.data(), c->name());
      if (cs.ok()) cs = write_image(out + "/component-" + c->name() + ".exr", f32_image(part, w, h), attrs);
      if (!cs.ok()) return report(cs);
    }
  }
  if (a.has("frames")) {  // the dynamic medium over time (docs/legendre.md)
    const int frames = std::atoi(a.get("frames").c_str());
    if (frames < 1 || frames > 1000) return usage_error("sim --frames: give 1..1000 frames");
    if (!scene->legendre_medium)
      return report(Error(Code::invalid_argument, "sim --frames: scene '" + scene->name + "' has no legendre_medium",
                          "use a scene with a \"legendre_medium\" (e.g. legendre-fog), see hw/sim/SCENES.md"));
    const double period = scene->legendre_medium->frame_period_s;
    AnimatedGif gif;
    Status gs = gif.open(out + "/animation.gif", std::clamp(1.0 / period, 0.01, 100.0));
    if (!gs.ok()) return report(gs);
    for (int k = 0; k < frames; ++k) {
      set_legendre_time(r, k * period);
      Status fs_st = r.render_radiance(*prepared, full.data(), true);
      if (!fs_st.ok()) return report(fs_st);
      char name[32];
      std::snprintf(name, sizeof name, "/frame_%03d.png", k);
      const Image im = expose(full.data(), w, h, cam.sensor, cam.sensor.exposure_us, cam.sensor.gain_db,
                              frame_noise_seed(rig->seed, 0, static_cast<uint64_t>(k)), threads);
      Status ws = write_image(out + name, im, attrs);
      if (ws.ok()) ws = gif.add(im);
      if (!ws.ok()) return report(ws);
    }
    gs = gif.close();
    if (!gs.ok()) return report(gs);
    set_legendre_time(r, 0.0);
  }
  Status gs = write_ground_truth(ground_truth_from_view(r.view()), out, {{"scene", scene->name}});
  if (!gs.ok()) return report(gs);
  nlohmann::json info = {
      {"scene", scene->name},
      {"scene_file", scene->source},
      {"pattern", a.get("pattern", "white")},
      {"components", nlohmann::json::array()},
      {"prep_ms", {{"view", prep.view_ms}, {"radiosity", prep.radiosity_ms}, {"glossy", prep.glossy_ms},
                   {"diffusion", prep.diffusion_ms}}},
      {"patches", prep.patches},
      {"glossy_entries", prep.glossy_entries},
      {"diffusion_objects", prep.diffusion_objects},
      {"render_ms", render_ms}};
  for (const auto& c : r.components()) info["components"].push_back(c->name());
  std::ofstream(out + "/info.json") << info.dump(2) << "\n";
  if (a.json) std::printf("%s\n", info.dump(2).c_str());
  else
    std::printf("scene %s, pattern %s: prepared in %.0f ms (%zu patches, %zu glossy entries), rendered in %.1f ms; wrote %s/\n",
                scene->name.c_str(), a.get("pattern", "white").c_str(),
                prep.view_ms + prep.radiosity_ms + prep.glossy_ms + prep.diffusion_ms, prep.patches,
                prep.glossy_entries, render_ms, out.c_str());
  return 0;
}

}  // namespace procam::cli
