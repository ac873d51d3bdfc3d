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
          // Sensor noise: a uniform +-3 DN hash (sigma ~1.7 DN), so the noise
          // rule has a variance to measure, as on a real or simulated camera.
          const uint32_t h = (x * 73856093u) ^ (y * 19349663u) ^ (static_cast<uint32_t>(pixels.size()) * 83492791u);
          const int n = static_cast<int>((h >> 7) % 7u) - 3;
          px[size_t{y} * kW + x] = static_cast<uint8_t>((lit ? 220 : 15) + n);
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

// noise_k > 0: the session's defaults (noise rule k = 3, uncertainty output,
// stripe averaging "auto": pairs kept, gate counted; it stays shut on this
// crisp capture, as on the sim). stripe: that mode instead.
RoundResult decode_round(uint32_t threads, double noise_k = 0,
                         StripeAverageMode stripe = StripeAverageMode::automatic) {
  Data& d = data();
  BinaryRoundDecoder dec(d.layout, d.cols, nullptr, kW, kH, threads);
  if (noise_k > 0) {
    dec.set_uncertain_output(true);
    StripeAverageParams p;
    p.mode = stripe;
    dec.set_stripe_average(p);
  }
  for (uint32_t i = 0; i < d.views.size(); ++i)
    if (!dec.add_frame(i, d.views[i]).ok()) std::abort();
  return dec.finish(0.03, 0.1, noise_k);
}

void BM_GrayDecode(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  for (auto _ : state) {
    RoundResult r = decode_round(threads);
    benchmark::DoNotOptimize(r);
    recycle_maps(std::move(r));  // as the session does: the next decode reuses mapped pages
  }
}
BENCHMARK(BM_GrayDecode)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// What method "gray" runs with its default parameters: the noise rule
// (noise_k = 3, the capture's noise fitted from pattern/inverse pairs) and
// the proj_col_uncertainty_px output.
void BM_GrayDecodeDefaults(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  for (auto _ : state) {
    RoundResult r = decode_round(threads, 3.0);
    benchmark::DoNotOptimize(r);
    recycle_maps(std::move(r));
  }
}
BENCHMARK(BM_GrayDecodeDefaults)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The defaults with stripe_average=off (no pairs kept, no gate): the cost of
// "auto" on a capture whose gate stays shut is Defaults minus this.
void BM_GrayDecodeStripeOff(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  for (auto _ : state) {
    RoundResult r = decode_round(threads, 3.0, StripeAverageMode::off);
    benchmark::DoNotOptimize(r);
    recycle_maps(std::move(r));
  }
}
BENCHMARK(BM_GrayDecodeStripeOff)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// stripe_average=on: rule A forced (what a capture whose gate opens pays:
// structure tensor over the whole image, averaged noise fit, the rejected pixels).
void BM_GrayDecodeStripeOn(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  for (auto _ : state) {
    RoundResult r = decode_round(threads, 3.0, StripeAverageMode::on);
    benchmark::DoNotOptimize(r);
    recycle_maps(std::move(r));
  }
}
BENCHMARK(BM_GrayDecodeStripeOn)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

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
