// SPDX-License-Identifier: MIT
// What a scan input costs (plugin ABI 2 "scan inputs"), at 1920x1200:
//   BM_ReadInputMap   the daemon reading a stored depth_mm.exr at submit time
//                     (engine::read_input_map: OpenImageIO, size check)
//   BM_InputsCopy     the plugin's copy in its factory (sdk::Inputs::image_f32:
//                     row copy + non-finite -> NaN)
// Run: build/bin/procam_inputs_bench --benchmark_repetitions=10
//      --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "procam/core/image_io.hpp"
#include "procam/engine/inputs.hpp"
#include "procam/sdk/inputs.hpp"

namespace {
namespace fs = std::filesystem;
constexpr uint32_t kW = 1920, kH = 1200;

// A plane-like depth map with 10 % invalid pixels.
procam::Image depth_map() {
  procam::Image m(kW, kH, procam::PixelType::f32);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  float* p = m.ptr<float>();
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x) p[size_t{y} * kW + x] = u(rng) < 0.1f ? NAN : 800.f + 0.05f * float(x) - 0.03f * float(y);
  return m;
}

void BM_ReadInputMap(benchmark::State& state) {
  const fs::path file = fs::temp_directory_path() / "procam_inputs_bench_depth_mm.exr";
  if (!procam::write_image(file.string(), depth_map()).ok()) {
    state.SkipWithError("cannot write the EXR");
    return;
  }
  for (auto _ : state) {
    auto img = procam::engine::read_input_map("depth_mm", file.string(), "bench file", kW, kH);
    if (!img) state.SkipWithError(img.status().message().c_str());
    benchmark::DoNotOptimize(img->ptr<float>());
  }
  std::error_code ec;
  fs::remove(file, ec);
}
BENCHMARK(BM_ReadInputMap)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_InputsCopy(benchmark::State& state) {
  const procam::Image m = depth_map();
  procam_output o{};
  o.name = "depth_mm";
  o.kind = PROCAM_OUTPUT_IMAGE;
  o.image = m.view();
  const procam::sdk::Inputs in = procam::sdk::Inputs::from_abi(&o, 1);
  std::vector<float> out;
  for (auto _ : state) {
    if (!in.image_f32("depth_mm", kW, kH, out).ok()) state.SkipWithError("copy failed");
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_InputsCopy)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
