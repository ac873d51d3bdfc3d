// SPDX-License-Identifier: MIT
// Speed of a frame with the dynamic Legendre medium (legendre_medium.hpp) on
// the default rig (1280x800 camera and projector) and the shipped
// legendre-fog scene, 2 render threads. The renderer (ray casting, shadow
// maps) is built once outside the timing. A frame is a full render of an
// 8-px stripe pattern with the projector polariser and the camera analyser
// set (the Stokes path):
//  - BM_LegendreFogFrame/0: the medium at a fixed time (the march only);
//  - BM_LegendreFogFrame/1: the medium advanced by one frame period per
//    frame (fluid step + density grid + projector-depth lattice + march),
//    the cost a scan pays per captured frame.
// Counter: ns per camera pixel.
#include <benchmark/benchmark.h>

#include <fstream>
#include <sstream>

#include "legendre_medium.hpp"
#include "procam/hw/sim/global.hpp"
#include "procam/hw/sim/sim_rig.hpp"

namespace procam::sim {
namespace {

struct Prepared {
  SimRigConfig rig;
  Scene scene;
  std::unique_ptr<Renderer> renderer;
  PreparedPattern pattern;
};

Prepared& prepared() {
  static Prepared p;
  if (p.renderer) return p;
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) + "/configs/rigs/sim.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto cfg = parse_sim_rig_config(nlohmann::json::parse(ss.str()));
  auto scene = load_scene("legendre-fog", {std::string(PROCAM_SOURCE_DIR) + "/configs/scenes"});
  if (!cfg.ok() || !scene.ok()) return p;
  p.rig = *cfg;
  p.scene = *scene;
  const CameraCalibration& cam = p.rig.cameras[0].calibration;
  auto r = make_scene_renderer(p.scene, p.rig.projector, cam, cam.cam_from_proj, GlobalOptions{}, 2);
  if (!r.ok()) return p;
  p.renderer = std::move(r).value();
  const Intrinsics& kp = p.rig.projector.intrinsics;
  Image im(kp.width, kp.height, PixelType::u8);
  for (uint32_t y = 0; y < kp.height; ++y)
    for (uint32_t x = 0; x < kp.width; ++x) im.at<uint8_t>(x, y) = (x / 8) % 2 ? 255 : 0;
  auto pat = PreparedPattern::from_pattern(im.view(), p.rig.projector, 2);
  if (pat.ok()) p.pattern = std::move(pat).value();
  return p;
}

void BM_LegendreFogFrame(benchmark::State& state) {
  Prepared& p = prepared();
  if (!p.renderer || p.pattern.empty()) {
    state.SkipWithError("legendre-fog renderer could not be built");
    return;
  }
  Renderer& r = *p.renderer;
  r.set_polarization(0.0, 90.0);
  std::vector<float> out(r.view().pixel_count());
  const double period = p.scene.legendre_medium->frame_period_s;
  const bool advance = state.range(0) != 0;
  int frame = 0;
  set_legendre_time(r, 0.0);
  for (auto _ : state) {
    if (advance) set_legendre_time(r, ++frame * period);
    if (!r.render_radiance(p.pattern, out.data(), false).ok()) state.SkipWithError("render failed");
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["ns_per_px"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * static_cast<double>(out.size()),
      benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_LegendreFogFrame)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace procam::sim

BENCHMARK_MAIN();
