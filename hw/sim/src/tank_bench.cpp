// SPDX-License-Identifier: MIT
// Speed of the dilution tank rig (tank.hpp): configs/rigs/sim-tank.json (a
// 1280×800 12-bit camera 5 m from the tank) with the tank-* scenes.
//  - BM_TankPrepare: prepare_view (ray casting + the bulb's radial tables and
//    per-pixel gains), once per scene load.
//  - BM_TankFrame: one camera frame: render (direct + bulb scatter + bulb
//    source) and the sensor (exposure, shot/read noise, 12-bit DN) — what the
//    sim camera does per captured frame.
//  - BM_TankMonteCarlo: 1000 paths of the Monte Carlo reference at one face
//    point (tank-chocolate-milk-8ml, 60 mm off the bulb's axis), plain
//    (arg 0) and with the variance reductions {4, forced, exact_single}
//    (arg 1), {2, forced, exact_single} (2), exact_single alone (3), forced
//    alone (4): the cost side of docs/media.md's standard-error gains; the
//    Fig. 4.11 comparison's setting {2, unforced, exact_single} (5) and the
//    same with common random numbers and a sampling medium 0.3 % off (6):
//    the cost of per-path seeds and of the weights.
#include <benchmark/benchmark.h>

#include <fstream>
#include <sstream>

#include "procam/hw/sim/sensor.hpp"
#include "procam/hw/sim/sim_rig.hpp"
#include "tank.hpp"

namespace procam::sim {
namespace {

SimRigConfig tank_rig_config() {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/sim-tank.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto cfg = parse_sim_rig_config(nlohmann::json::parse(ss.str()));
  return cfg.ok() ? *cfg : SimRigConfig{};
}

Result<Scene> tank_scene(const std::string& name) {
  return load_scene(name, {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"});
}

void BM_TankPrepare(benchmark::State& state, const std::string& scene_name) {
  const SimRigConfig rig = tank_rig_config();
  const Result<Scene> scene = tank_scene(scene_name);
  if (rig.cameras.empty() || !scene.ok()) {
    state.SkipWithError("rig or scene failed to load");
    return;
  }
  for (auto _ : state) {
    auto v = prepare_view(*scene, rig.projector, rig.cameras[0].calibration, static_cast<int>(state.range(0)));
    if (!v.ok() || !v->tank) state.SkipWithError("prepare_view failed");
    benchmark::DoNotOptimize(v);
  }
}

void BM_TankFrame(benchmark::State& state, const std::string& scene_name) {
  const SimRigConfig rig = tank_rig_config();
  const Result<Scene> scene = tank_scene(scene_name);
  if (rig.cameras.empty() || !scene.ok()) {
    state.SkipWithError("rig or scene failed to load");
    return;
  }
  const int threads = static_cast<int>(state.range(0));
  auto v = prepare_view(*scene, rig.projector, rig.cameras[0].calibration, threads);
  if (!v.ok()) {
    state.SkipWithError("prepare_view failed");
    return;
  }
  Renderer r(std::move(v).value(), rig.projector, threads);
  Image white(rig.projector.intrinsics.width, rig.projector.intrinsics.height, PixelType::u8);
  std::fill(white.ptr<uint8_t>(), white.ptr<uint8_t>() + white.pixel_count(), uint8_t{255});
  PreparedPattern pp = *PreparedPattern::from_pattern(white.view(), rig.projector);
  std::vector<float> radiance(r.view().pixel_count());
  const SensorModel& sensor = rig.cameras[0].sensor;
  uint64_t seed = 1;
  for (auto _ : state) {
    (void)r.render_radiance(pp, radiance.data());
    Image frame = expose(radiance.data(), r.width(), r.height(), sensor, 100000.0, 0.0, ++seed, threads);
    benchmark::DoNotOptimize(frame.data());
  }
}

void BM_TankMonteCarlo(benchmark::State& state) {
  const Result<Scene> scene = tank_scene("tank-chocolate-milk-8ml");
  if (!scene.ok() || !scene->medium || !scene->medium->bulb) {
    state.SkipWithError("scene failed to load");
    return;
  }
  const Medium& m = *scene->medium;
  const TankMcOptions options[] = {{},
                                   {4, true, true},
                                   {2, true, true},
                                   {1, false, true},
                                   {1, true, false},
                                   {2, false, true},
                                   {2, false, true, true, 0.997 * m.sigma_t_per_mm, m.g}};
  const TankMcOptions opt = options[state.range(0)];
  uint64_t seed = 1;
  for (auto _ : state) {
    const TankMonteCarlo mc = tank_monte_carlo(m, m.bulb->center_mm.x + 60, m.bulb->center_mm.y, 1000, ++seed, 1 << 20, opt);
    benchmark::DoNotOptimize(mc.total);
  }
}

BENCHMARK(BM_TankMonteCarlo)->DenseRange(0, 6)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_TankPrepare, lowfat_milk, std::string("tank-lowfat-milk"))
    ->Arg(2)->Iterations(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_TankFrame, lowfat_milk, std::string("tank-lowfat-milk"))
    ->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace procam::sim

BENCHMARK_MAIN();
