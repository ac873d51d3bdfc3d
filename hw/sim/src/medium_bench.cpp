// SPDX-License-Identifier: MIT
// Speed of a frame in a participating medium (medium.hpp) on the default rig:
// 1280×800 camera and projector, the milk-tank chart scenes. The view (ray
// casting, shadow map, backscatter taps) is prepared once outside the timing;
// a frame is the direct component plus the backscatter gather, with the
// projector polariser and camera analyser set (the Stokes-weighted path),
// and the multiple-scattering term where the scene turns it on (the chart
// scenes do; BM_MediumFrameHeavySingleOnly turns it off).
// Counters: chunks per camera pixel with taps, tap memory (MB), prep time (s).
#include <benchmark/benchmark.h>

#include <chrono>
#include <fstream>
#include <map>
#include <sstream>

#include "medium.hpp"
#include "procam/hw/sim/sim_rig.hpp"

namespace procam::sim {
namespace {

struct Prepared {
  SimRigConfig rig;
  std::unique_ptr<Renderer> renderer;
  double prep_s = 0;
};

// One prepared view per scene for the whole run (preparing is the slow part).
Prepared& prepared(const std::string& scene_name) {
  static std::map<std::string, Prepared> cache;
  auto it = cache.find(scene_name);
  if (it != cache.end()) return it->second;
  Prepared& p = cache[scene_name];
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/sim.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto cfg = parse_sim_rig_config(nlohmann::json::parse(ss.str()));
  // "<scene>:single": the scene with its multiple-scattering term off (the cost of the term).
  const size_t colon = scene_name.find(':');
  auto scene = load_scene(scene_name.substr(0, colon), {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"});
  if (!cfg.ok() || !scene.ok()) return p;
  if (colon != std::string::npos && scene->medium) scene->medium->multiple_scattering = Medium::MultipleScattering::none;
  p.rig = *cfg;
  const auto t0 = std::chrono::steady_clock::now();
  auto v = prepare_view(*scene, p.rig.projector, p.rig.cameras[0].calibration, 2);
  p.prep_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (v.ok()) p.renderer = std::make_unique<Renderer>(std::move(v).value(), p.rig.projector, 2);
  return p;
}

Image stripes(uint32_t w, uint32_t h) {
  Image im(w, h, PixelType::u8);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) im.at<uint8_t>(x, y) = (x / 8) % 2 ? 255 : 0;
  return im;
}

void run(benchmark::State& state, const std::string& scene, Renderer::Parts parts) {
  Prepared& p = prepared(scene);
  if (!p.renderer || !p.renderer->view().medium) {
    state.SkipWithError("scene preparation failed");
    return;
  }
  Renderer& r = *p.renderer;
  r.set_threads(static_cast<int>(state.range(0)));
  r.set_polarization(0.0, 90.0);
  const Image pat = stripes(1280, 800);
  PreparedPattern pp = *PreparedPattern::from_pattern(pat.view(), p.rig.projector);
  std::vector<float> radiance(r.view().pixel_count());
  for (auto _ : state) {
    (void)r.render_radiance_parts(pp, radiance.data(), true, parts);
    benchmark::DoNotOptimize(radiance.data());
  }
  const MediumTaps& t = *r.view().medium;
  size_t with = 0;
  for (size_t i = 0; i < t.pixel_count(); ++i) with += t.offset[i + 1] > t.offset[i];
  state.counters["chunks_per_px"] = with ? static_cast<double>(t.chunks.size()) / static_cast<double>(with) : 0.0;
  state.counters["taps_MB"] =
      static_cast<double>(t.chunks.size() * sizeof(MediumChunk) + t.offset.size() * 4 + t.pol_proj.size() * 8 + t.m12.size() * 8) / 1e6;
  state.counters["prep_s"] = p.prep_s;
}

// A whole frame: direct light (attenuated) + backscatter through the analyser.
void BM_MediumFrameModerate(benchmark::State& s) { run(s, "media-chart-moderate", Renderer::Parts::all); }
void BM_MediumFrameHeavy(benchmark::State& s) { run(s, "media-chart-heavy", Renderer::Parts::all); }
// The same without the multiple-scattering term (docs/media.md "Multiple scattering").
void BM_MediumFrameHeavySingleOnly(benchmark::State& s) { run(s, "media-chart-heavy:single", Renderer::Parts::all); }
// The backscatter alone (row prefix sums + gather).
void BM_MediumBackscatterHeavy(benchmark::State& s) { run(s, "media-chart-heavy", Renderer::Parts::volume_only); }
BENCHMARK(BM_MediumFrameModerate)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MediumFrameHeavy)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MediumFrameHeavySingleOnly)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MediumBackscatterHeavy)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace procam::sim

BENCHMARK_MAIN();
