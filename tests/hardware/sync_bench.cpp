// SPDX-License-Identifier: MIT
// Benchmark (issue 5 "Speed"): sync-engine overhead per frame between
// receiving a frame and being ready for the next (goal <= 0.5 ms), and
// frames/s with Aravis's in-process Fake camera at a 1000 Hz trigger rate.
#include <benchmark/benchmark.h>

#include <cstring>

#include "procam/core/image.hpp"
#include "procam/engine/sync.hpp"
#include "rig_helpers.hpp"

namespace procam::testing {
namespace {

void BM_SyncCaptureFake1000Hz(benchmark::State& state) {
  // A small sim projector (so show() is cheap) and the in-process Fake camera
  // triggered at up to 1000 Hz with a constant fill.
  auto sim = make_rig("sim.json", {{"projector", {{"intrinsics", {{"width", 128}, {"height", 80}, {"fx", 160.0},
                                                                  {"fy", 160.0}, {"cx", 63.5}, {"cy", 39.5}}}}}});
  aravis::AravisCameraConfig c;
  c.device = "Fake";
  c.roi_width = 640;
  c.roi_height = 480;
  c.fake_trigger_hz = 1000;
  auto cam = aravis::AravisCamera::open(c, [](uint32_t w, uint32_t h, uint32_t bpp, uint8_t* dst) {
    std::memset(dst, 100, size_t{w} * h * bpp);
    return Status::Ok();
  });
  if (!sim || !cam.ok()) {
    state.SkipWithError("cannot open the sim projector or the Aravis Fake camera");
    return;
  }
  SimProjectorGvCameraRig rig(std::move(sim), std::move(*cam));
  engine::SyncSettings s;
  engine::SyncEngine sync(rig, s);
  Image p(128, 80, PixelType::u8);
  uint64_t k = 0;
  for (auto _ : state) {
    auto f = sync.capture(p.view(), ++k, 0, "b");
    if (!f.ok()) {
      state.SkipWithError(f.status().to_string().c_str());
      return;
    }
    benchmark::DoNotOptimize(f->image.data());
  }
  const auto& r = sync.report();
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(k), benchmark::Counter::kIsRate);
  state.counters["overhead_ms_mean"] = r.overhead_ms_mean;
  state.counters["overhead_ms_max"] = r.overhead_ms_max;
  state.counters["retried"] = static_cast<double>(r.retried);
}
BENCHMARK(BM_SyncCaptureFake1000Hz)->Iterations(500)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace procam::testing

BENCHMARK_MAIN();
