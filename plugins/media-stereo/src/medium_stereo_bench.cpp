// SPDX-License-Identifier: MIT
// Speed of the media-stereo core on the test scenes: binocular matching
// (128 x 96, 161 hypotheses, 7 x 7 window, tables included) and Helmholtz
// (64 x 48, 4 pairs, 221 hypotheses), normal integration (64 x 48).
// Single-threaded.
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>

#include "binocular.hpp"
#include "helmholtz.hpp"
#include "normal_integration.hpp"
#include "test_rig.hpp"

namespace procam::media_stereo {
namespace {

void BM_Binocular(benchmark::State& state) {
  const test::BinocularRig rig;
  const auto m = test::tank_medium();
  const auto scene = test::scene_of(SceneKind::inclined_plane);
  const auto l = render(scene, rig.left, rig.light, test::kLightIntensity, m);
  const auto r = render(scene, rig.right, rig.light, test::kLightIntensity, m);
  BinocularInput in{rig.left, rig.right, l.image, r.image, rig.light, test::kLightIntensity, m, std::nullopt};
  if (state.range(0) == 2) {  // media, the light a projector (emission cone), as the ABI session runs it
    LightCone cone;
    cone.light_from_world = Rigid3{Mat3::identity(), -rig.light};
    cone.width = 320;
    cone.height = 240;
    cone.fx = cone.fy = 160;
    cone.cx = 159.5 - 160 * 160.0 / 520;
    cone.cy = 119.5 - 160 * 120.0 / 520;
    in.light_cone = cone;
  }
  DepthSearch d;
  d.min_signal = 1e-4;
  const auto c = state.range(0) ? Constraint::media : Constraint::clear_air;
  for (auto _ : state) benchmark::DoNotOptimize(binocular_depth(in, d, c));
}
// 0: clear air, 1: media, 2: media with the projector's emission cone.
BENCHMARK(BM_Binocular)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_IntegrateNormals(benchmark::State& state) {
  SyntheticScene scene = test::scene_of(SceneKind::half_sphere);
  scene.textured = false;
  const PinholeCamera cam = look_at_camera(64, 48, 87, {0, 0, 0}, {0, 0, 520});
  const RenderedView t = render(scene, cam, {0, 0, 0}, test::kLightIntensity, {});
  std::vector<float> seed = t.depth_mm;
  for (float& z : seed) z += 10.0f;
  for (auto _ : state) benchmark::DoNotOptimize(integrate_normals(cam, t.normal, seed));
}
BENCHMARK(BM_IntegrateNormals)->Unit(benchmark::kMillisecond);

void BM_Helmholtz(benchmark::State& state) {
  SyntheticScene scene = test::scene_of(SceneKind::half_sphere);
  scene.textured = false;
  const auto m = test::tank_medium();
  HelmholtzInput in;
  in.reference = look_at_camera(64, 48, 87, {0, 0, 0}, {0, 0, 520});
  in.light_intensity = test::kLightIntensity;
  in.medium = m;
  for (int j = 0; j < 4; ++j) {
    const double a = j * std::numbers::pi / 4;
    const Vec3 pa{100 * std::cos(a), 100 * std::sin(a), 0};
    ReciprocalPair pr;
    pr.cam_a = look_at_camera(64, 48, 87, pa, {0, 0, 520});
    pr.cam_b = look_at_camera(64, 48, 87, -pa, {0, 0, 520});
    pr.image_a = render(scene, pr.cam_a, pr.cam_b.centre(), test::kLightIntensity, m).image;
    pr.image_b = render(scene, pr.cam_b, pr.cam_a.centre(), test::kLightIntensity, m).image;
    in.pairs.push_back(std::move(pr));
  }
  DepthSearch d;
  d.window = 5;
  d.z_min_mm = 420;
  d.z_max_mm = 640;
  d.z_step_mm = 1;
  for (auto _ : state) benchmark::DoNotOptimize(helmholtz_stereo(in, d, state.range(0) != 0));
}
BENCHMARK(BM_Helmholtz)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace procam::media_stereo

BENCHMARK_MAIN();
