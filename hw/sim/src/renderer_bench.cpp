// SPDX-License-Identifier: MIT
// Speed of the sim renderer on the default rig (1280×800 camera and projector,
// plane scene): direct render, pattern preparation + blur level, sensor, and a
// whole capture; and a textured calibration board on the distorted rig.
// Single-threaded unless stated.
#include <benchmark/benchmark.h>

#include <fstream>
#include <sstream>

#include "procam/hw/sim/sensor.hpp"
#include "procam/hw/sim/sim_rig.hpp"

namespace procam::sim {
namespace {

SimRigConfig bench_config(int threads) {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/sim.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto cfg = parse_sim_rig_config(nlohmann::json::parse(ss.str()));
  if (!cfg.ok()) return {};
  cfg->threads = threads;
  return *cfg;
}

std::unique_ptr<SimRig> bench_rig(int threads) {
  auto rig = SimRig::create(bench_config(threads),
                            {std::string(PROCAM_SOURCE_DIR) + "/configs/rigs",
                             {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"}});
  return rig.ok() ? std::move(rig).value() : nullptr;
}

Image stripes(uint32_t w, uint32_t h) {
  Image im(w, h, PixelType::u8);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) im.at<uint8_t>(x, y) = (x / 8) % 2 ? 255 : 0;
  return im;
}

// Direct component only: per-pixel sampling of an already prepared pattern.
void BM_RenderDirect(benchmark::State& state) {
  auto rig = bench_rig(static_cast<int>(state.range(0)));
  if (!rig) { state.SkipWithError("rig creation failed"); return; }
  Renderer& r = rig->renderer(0);
  r.clear_components();  // the rig also installs global components (global_bench.cpp)
  r.add_component(std::make_unique<DirectComponent>());
  const Image pat = stripes(r.view().proj_width, r.view().proj_height);
  PreparedPattern p = *PreparedPattern::from_pattern(pat.view(), rig->config().projector);
  p.build_levels(r.defocus().levels_needed);
  std::vector<float> radiance(r.view().pixel_count());
  for (auto _ : state) {
    (void)r.render_radiance(p, radiance.data());
    benchmark::DoNotOptimize(radiance.data());
  }
}
BENCHMARK(BM_RenderDirect)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// Emission curve + the blur levels the default focus needs.
void BM_PreparePattern(benchmark::State& state) {
  auto rig = bench_rig(1);
  if (!rig) { state.SkipWithError("rig creation failed"); return; }
  const size_t levels = rig->renderer(0).defocus().levels_needed;
  const Image pat = stripes(1280, 800);
  for (auto _ : state) {
    PreparedPattern p = *PreparedPattern::from_pattern(pat.view(), rig->config().projector);
    p.build_levels(levels);
    benchmark::DoNotOptimize(p.level(levels - 1));
  }
  state.counters["levels"] = static_cast<double>(levels);
}
BENCHMARK(BM_PreparePattern)->Unit(benchmark::kMillisecond);

void BM_Expose(benchmark::State& state) {
  std::vector<float> radiance(1280 * 800, 0.3f);
  SensorModel s;
  uint64_t frame = 0;
  for (auto _ : state) {
    Image im = expose(radiance.data(), 1280, 800, s, 12000, 0, frame_noise_seed(1, 0, frame++));
    benchmark::DoNotOptimize(im.data());
  }
}
BENCHMARK(BM_Expose)->Unit(benchmark::kMillisecond);

// show() + capture(): what a scan pays per frame.
void BM_ShowAndCapture(benchmark::State& state) {
  auto rig = bench_rig(static_cast<int>(state.range(0)));
  if (!rig) { state.SkipWithError("rig creation failed"); return; }
  const Image pat = stripes(1280, 800);
  uint64_t id = 0;
  for (auto _ : state) {
    (void)rig->projector().show(pat.view(), ++id);
    auto f = rig->camera(0).capture(std::chrono::milliseconds(100));
    benchmark::DoNotOptimize(f.ok());
  }
}
BENCHMARK(BM_ShowAndCapture)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// Scene preparation (ray casting + shadow rays) per camera.
void BM_PrepareScene(benchmark::State& state) {
  const SimRigConfig cfg = bench_config(1);
  auto scene = load_scene("tilted-box", {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"});
  if (!scene.ok() || cfg.cameras.empty()) { state.SkipWithError("scene/config failed"); return; }
  for (auto _ : state) {
    auto v = prepare_view(*scene, cfg.projector, cfg.cameras[0].calibration, 1);
    benchmark::DoNotOptimize(v.ok());
  }
}
BENCHMARK(BM_PrepareScene)->Unit(benchmark::kMillisecond);

// Scene preparation of a calibration pose on the distorted rig
// (configs/rigs/sim-distorted.json, board-4): Arg 1 with the chessboard
// texture (anti-aliased footprints), Arg 0 the same plate untextured; the
// difference is the texture's cost. Single-threaded.
void BM_PrepareBoard(benchmark::State& state) {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/sim-distorted.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto cfg = parse_sim_rig_config(nlohmann::json::parse(ss.str()));
  auto scene = load_scene(std::string(PROCAM_SOURCE_DIR) + "/configs/scenes/calib/board-4.json", {});
  if (!cfg.ok() || !scene.ok()) { state.SkipWithError("scene/config failed"); return; }
  if (state.range(0) == 0) scene->objects[0].texture.reset();
  for (auto _ : state) {
    auto v = prepare_view(*scene, cfg->projector, cfg->cameras[0].calibration, 1);
    benchmark::DoNotOptimize(v.ok());
  }
}
BENCHMARK(BM_PrepareBoard)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace procam::sim

BENCHMARK_MAIN();
