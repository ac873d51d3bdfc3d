// SPDX-License-Identifier: MIT
// Speed of global light transport on the default rig (1280×800 camera and
// projector), per scene of the library: scene preparation (ray casting, form
// factors, radiosity solve, glossy tracing, blur masks) and the per-frame render
// with growing sets of components (0: direct only, 1: + diffuse radiosity,
// 2: + glossy, 3: + sub-surface / sheet diffusion = everything). 2 threads.
#include <benchmark/benchmark.h>

#include <fstream>
#include <sstream>

#include "procam/hw/sim/global.hpp"
#include "procam/hw/sim/sensor.hpp"
#include "procam/hw/sim/sim_rig.hpp"

namespace procam::sim {
namespace {

const char* const kScenes[] = {"plane",          "v-groove",   "marble-slab", "bowl-on-marble",
                               "shower-curtain", "metal-lamp", "wax-candle",  "deep-scene"};

SimRigConfig bench_config() {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/sim.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto cfg = parse_sim_rig_config(nlohmann::json::parse(ss.str()));
  return cfg.ok() ? *cfg : SimRigConfig{};
}

GlobalOptions options_for(int64_t set) {
  GlobalOptions o;
  o.interreflection = set >= 1;
  o.glossy = set >= 2;
  o.diffusion = set >= 3;
  return o;
}

std::unique_ptr<Renderer> make(const SimRigConfig& cfg, int64_t scene, int64_t set, PrepStats* stats = nullptr) {
  auto s = load_scene(kScenes[scene], {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"});
  if (!s.ok()) return nullptr;
  const CameraCalibration& cam = cfg.cameras[0].calibration;
  auto r = make_scene_renderer(*s, cfg.projector, cam, cam.cam_from_proj, options_for(set), 2, stats);
  return r.ok() ? std::move(r).value() : nullptr;
}

void BM_PrepareScene(benchmark::State& state) {
  const SimRigConfig cfg = bench_config();
  PrepStats st;
  for (auto _ : state) {
    auto r = make(cfg, state.range(0), 3, &st);
    if (!r) { state.SkipWithError("scene failed"); return; }
    benchmark::DoNotOptimize(r.get());
  }
  state.SetLabel(kScenes[state.range(0)]);
  state.counters["view_ms"] = st.view_ms;
  state.counters["radiosity_ms"] = st.radiosity_ms;
  state.counters["glossy_ms"] = st.glossy_ms;
  state.counters["diffusion_ms"] = st.diffusion_ms;
  state.counters["patches"] = static_cast<double>(st.patches);
}
BENCHMARK(BM_PrepareScene)->DenseRange(0, 7)->Unit(benchmark::kMillisecond)->Iterations(2);

// Per frame, pattern already prepared (8-px stripes): render_radiance with
// component set state.range(1).
void BM_Render(benchmark::State& state) {
  const SimRigConfig cfg = bench_config();
  auto r = make(cfg, state.range(0), state.range(1));
  if (!r) { state.SkipWithError("scene failed"); return; }
  Image pat(cfg.projector.intrinsics.width, cfg.projector.intrinsics.height, PixelType::u8);
  for (uint32_t y = 0; y < pat.height(); ++y)
    for (uint32_t x = 0; x < pat.width(); ++x) pat.at<uint8_t>(x, y) = (x / 8) % 2 ? 255 : 0;
  PreparedPattern p = *PreparedPattern::from_pattern(pat.view(), cfg.projector);
  p.build_levels(r->defocus().levels_needed, 2);
  std::vector<float> radiance(r->view().pixel_count());
  for (auto _ : state) {
    (void)r->render_radiance(p, radiance.data());
    benchmark::DoNotOptimize(radiance.data());
  }
  state.SetLabel(kScenes[state.range(0)]);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Render)->ArgsProduct({benchmark::CreateDenseRange(0, 7, 1), {0, 1, 2, 3}})->Unit(benchmark::kMillisecond);

// The whole per-frame cost of the sim camera with every component, as
// SimProjector::show + SimCamera::capture pay it: a new 8-bit pattern each
// frame (alternating 8-px stripes and their inverse) → PreparedPattern (emitted
// light) → defocus levels → radiance → sensor (exposure, shot + read noise,
// 8-bit). This is the number the ≥ 60 frames/s goal is about.
void BM_Frame(benchmark::State& state) {
  const SimRigConfig cfg = bench_config();
  auto r = make(cfg, state.range(0), 3);
  if (!r) { state.SkipWithError("scene failed"); return; }
  Image pat[2] = {Image(cfg.projector.intrinsics.width, cfg.projector.intrinsics.height, PixelType::u8),
                  Image(cfg.projector.intrinsics.width, cfg.projector.intrinsics.height, PixelType::u8)};
  for (uint32_t k = 0; k < 2; ++k)
    for (uint32_t y = 0; y < pat[k].height(); ++y)
      for (uint32_t x = 0; x < pat[k].width(); ++x) pat[k].at<uint8_t>(x, y) = ((x / 8) + k) % 2 ? 255 : 0;
  std::vector<float> radiance(r->view().pixel_count());
  const SensorModel& sensor = cfg.cameras[0].sensor;
  uint64_t frame = 0;
  PreparedPattern p;  // reused frame to frame, as SimProjector does
  for (auto _ : state) {
    if (!p.assign(pat[frame % 2].view(), cfg.projector, 2).ok()) { state.SkipWithError("pattern failed"); return; }
    (void)r->render_radiance(p, radiance.data(), true);
    Image img = expose(radiance.data(), r->width(), r->height(), sensor, sensor.exposure_us, 0.0,
                       ++frame, 2);
    benchmark::DoNotOptimize(img.data());
  }
  state.SetLabel(kScenes[state.range(0)]);
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Frame)->DenseRange(0, 7)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace procam::sim

BENCHMARK_MAIN();
