// SPDX-License-Identifier: MIT
// Speed of method "gray" on a 1280x800 8-bit camera with an 11-bit column
// code and inverses (24 frames): streaming binarization (all add_frame work),
// per-pixel decode, and triangulation, for 1 and 2 threads.
// Run: build-*/plugins/structured-light/procam_sl_bench
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "gray_code.hpp"
#include "plan_layout.hpp"
#include "round_decoder.hpp"
#include "procam/sdk/triangulate.hpp"

namespace procam::sl {
namespace {

constexpr uint32_t kW = 1280, kH = 800;

struct Data {
  StripeCode cols = make_gray_code(kW);
  Layout layout = make_layout(cols, nullptr, true);
  std::vector<std::vector<uint8_t>> pixels;
  std::vector<procam_image> views;
  CameraCalibration cam;
  Intrinsics proj{kW, kH, 1400, 1400, 639.5, 399.5};
  Data() {
    cam.intrinsics = {kW, kH, 1400, 1400, 639.5, 399.5};
    cam.cam_from_proj.rotation = rotation_from_euler_deg(0, -15, 0);
    cam.cam_from_proj.translation_mm = {200, 0, 0};
    // Camera pixel (x, y) sees projector column ~ 0.9 x + 0.05 y + 30 (most pixels lit).
    for (const FrameRole& role : layout.frames) {
      std::vector<uint8_t> px(size_t{kW} * kH);
      for (uint32_t y = 0; y < kH; ++y)
        for (uint32_t x = 0; x < kW; ++x) {
          const auto c = static_cast<uint32_t>(0.9 * x + 0.05 * y + 30);
          bool lit = role.kind == FrameKind::white;
          if (role.kind == FrameKind::plane) lit = cols.bit(role.plane, c);
          if (role.kind == FrameKind::inverse) lit = !cols.bit(role.plane, c);
          px[size_t{y} * kW + x] = static_cast<uint8_t>(lit ? 220 : 15);
        }
      pixels.push_back(std::move(px));
      views.push_back(sdk::gray_view(pixels.back().data(), kW, kH));
    }
  }
};

Data& data() {
  static Data d;
  return d;
}

RoundResult decode_round(uint32_t threads) {
  Data& d = data();
  BinaryRoundDecoder dec(d.layout, d.cols, nullptr, kW, kH, threads);
  for (uint32_t i = 0; i < d.views.size(); ++i)
    if (!dec.add_frame(i, d.views[i]).ok()) std::abort();
  return dec.finish(0.03, 0.1);
}

void BM_GrayDecode(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(decode_round(threads));
}
BENCHMARK(BM_GrayDecode)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_GrayDecodeAndTriangulate(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  Data& d = data();
  for (auto _ : state) {
    RoundResult r = decode_round(threads);
    benchmark::DoNotOptimize(sdk::triangulate_columns(d.cam, d.proj, kW, kH,
                                                      r.cols.coord.data(), r.intensity.data(),
                                                      threads));
  }
}
BENCHMARK(BM_GrayDecodeAndTriangulate)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Triangulate(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  Data& d = data();
  const RoundResult r = decode_round(2);
  for (auto _ : state)
    benchmark::DoNotOptimize(sdk::triangulate_columns(d.cam, d.proj, kW, kH,
                                                      r.cols.coord.data(), r.intensity.data(),
                                                      threads));
}
BENCHMARK(BM_Triangulate)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace procam::sl

BENCHMARK_MAIN();
