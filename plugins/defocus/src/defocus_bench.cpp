// SPDX-License-Identifier: MIT
// Speed of multi-focal (issue 12 goal): 1920x1200 8-bit frames, 2 threads,
// 6 focus settings x 24 shifts = 144 frames: work per added frame (the
// streaming accumulation, the fold of each finished setting included) and the
// work after the last frame (fbar by Gaussian interpolation + table lookup).
// Goals: <= 1 ms per frame, <= 10 ms after the last.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "calibration.hpp"
#include "defocus_session.hpp"
#include "e3_accumulator.hpp"
#include "fbar_kernel.hpp"
#include "focus_measures.hpp"
#include "sweep_plan.hpp"
#include "procam/sdk/simd.hpp"

namespace procam::defocus {
namespace {

constexpr uint32_t kW = 1920, kH = 1200, kF = 6, kThreads = 2;

// Frame (focus f, shift t): a blurred stripe profile whose contrast peaks at a
// focus index that varies across the image (a tilted plane).
std::vector<uint8_t> make_frame(uint32_t f, uint32_t t) {
  // The profile depends on x only (exp and cos once per column, not per pixel:
  // the set-up of 144 frames would otherwise take minutes).
  std::vector<double> profile(kW);
  for (uint32_t x = 0; x < kW; ++x) {
    const double peak = 0.5 + 4.0 * x / kW;
    const double c = std::exp(-0.5 * (f - peak) * (f - peak));
    const double s = std::cos(2 * M_PI * 3 * ((double(x) - t) / 24.0));
    profile[x] = 110 + 90 * c * s;
  }
  std::vector<uint8_t> v(size_t{kW} * kH);
  for (uint32_t y = 0; y < kH; ++y)
    for (uint32_t x = 0; x < kW; ++x)
      v[size_t{y} * kW + x] = static_cast<uint8_t>(std::lround(profile[x] + (x * 7 + y * 13) % 3));
  return v;
}

void BM_MultiFocalAddFrame(benchmark::State& state) {
  std::vector<std::vector<uint8_t>> frames;
  for (uint32_t t = 0; t < 24; ++t) frames.push_back(make_frame(2, t));
  const auto threads = static_cast<uint32_t>(state.range(0));
  auto acc = std::make_unique<E3Accumulator>(kW, kH, kF, PROCAM_PIXEL_U8, 255, threads);
  uint32_t k = 0;
  for (auto _ : state) {
    if (k == kF * 24) {
      state.PauseTiming();
      acc = std::make_unique<E3Accumulator>(kW, kH, kF, PROCAM_PIXEL_U8, 255, threads);
      k = 0;
      state.ResumeTiming();
    }
    const procam_image img = sdk::gray_view(frames[k % 24].data(), kW, kH, 8);
    benchmark::DoNotOptimize(acc->add(k / 24, k % 24, img));
    ++k;
  }
  state.counters["frames"] = static_cast<double>(state.iterations());
}
BENCHMARK(BM_MultiFocalAddFrame)->Arg(2)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(288)->Repetitions(3)->UseRealTime();

void BM_MultiFocalAfterLastFrame(benchmark::State& state) {
  E3Accumulator acc(kW, kH, kF, PROCAM_PIXEL_U8, 255, kThreads);
  for (uint32_t f = 0; f < kF; ++f)
    for (uint32_t t = 0; t < 24; ++t) {
      auto fr = make_frame(f, t);
      (void)acc.add(f, t, sdk::gray_view(fr.data(), kW, kH, 8));
    }
  sdk::CalibrationTable table;
  table.name = "defocus.multi-focal";
  for (int k = 0; k <= 50; ++k) table.samples.emplace_back(0.1 * k, 600 + 10.0 * k);
  std::vector<float> fbar, depth;
  Validity rule;
  const auto threads = static_cast<uint32_t>(state.range(0));
  const bool lookup = state.range(1) != 0;  // 0: fbar alone (to see what the table lookup costs)
  for (auto _ : state)
    benchmark::DoNotOptimize(fbar_depth_map(acc, rule, lookup ? &table : nullptr, threads, fbar, lookup ? &depth : nullptr));
}
BENCHMARK(BM_MultiFocalAfterLastFrame)->Args({2, 1})->Args({1, 1})->Args({2, 0})->Unit(benchmark::kMillisecond)->Repetitions(5)->UseRealTime();

// The fused row kernel on one 1920-pixel row whose E rows stay in cache
// (~50 KB): its arithmetic and the table lookup without the memory traffic
// of a whole image, so the lookup's cost shows as the difference between
// lookup:1 and lookup:0, and a shared machine's memory contention matters
// less. Per row; the AVX2 kernel where the CPU has it.
void BM_FbarRowInCache(benchmark::State& state) {
  const bool lookup = state.range(0) != 0;
  std::vector<std::vector<float>> e(kF, std::vector<float>(kW));
  std::vector<float> mean(kW), fbar(kW), depth(kW), peak(kW);
  std::vector<uint8_t> sat(kW / 8, 0), valid(kW);
  for (uint32_t x = 0; x < kW; ++x) {  // the bench image's tilted plane: the peak moves from 0.5 to 4.5
    const double centre = 0.5 + 4.0 * x / kW;
    mean[x] = 110;
    for (uint32_t f = 0; f < kF; ++f)
      e[f][x] = static_cast<float>(60 * std::exp(-0.5 * (f - centre) * (f - centre)) + (x % 3));
  }
  sdk::CalibrationTable table;
  for (int k = 0; k <= 50; ++k) table.samples.emplace_back(0.1 * k, 600 + 10.0 * k);
  const detail::FloatTable ft(&table);
  std::vector<const float*> ptr;
  for (const auto& m : e) ptr.push_back(m.data());
  size_t valid_count = 0;
  const detail::RowArgs a{ptr.data(), kF, mean.data(), sat.data(), 5.f, 0.02f, lookup ? &ft : nullptr,
                          fbar.data(), lookup ? depth.data() : nullptr, peak.data(), valid.data(), &valid_count,
                          nullptr, 0, 0};
  const bool avx2 = sdk::cpu_has_avx2();
  for (auto _ : state) {
    benchmark::DoNotOptimize(avx2 ? detail::fbar_row_avx2(a, 0, kW) : detail::fbar_row_scalar(a, 0, kW));
    benchmark::ClobberMemory();
  }
  state.counters["valid"] = static_cast<double>(valid_count) / static_cast<double>(state.iterations() * kW);
}
BENCHMARK(BM_FbarRowInCache)->ArgName("lookup")->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond)->Repetitions(5);

// What a scan waits for after the last frame, through the session: the last
// frame's add (with the fold of the last focus setting), end_round (fbar +
// depth) and outputs (the maps handed over). Each iteration replays the first
// 143 frames into a fresh session, untimed.
void BM_MultiFocalSessionLastFrame(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  std::vector<std::vector<uint8_t>> frames;
  for (uint32_t f = 0; f < kF; ++f)
    for (uint32_t t = 0; t < 24; ++t) frames.push_back(make_frame(f, t));
  const std::vector<double> focus = focus_sweep_mm(600, 1200, kF);
  sdk::CalibrationTable table;
  table.name = kMultiFocal.table_name;
  table.x_name = kMultiFocal.x_name;
  table.x_unit = kMultiFocal.x_unit;
  table.extra = {{"focus_mm", focus}};
  const double a = 1 / focus.front(), step = (1 / focus.front() - 1 / focus.back()) / double(kF - 1);
  for (int k = 0; k <= 40; ++k) table.samples.emplace_back(0.5 + 0.1 * k, 1 / (a - (0.5 + 0.1 * k) * step));
  const nlohmann::json rig = {{"projector", {{"width", kW}, {"height", kH}}},
                              {"cameras", {{{"width", kW}, {"height", kH}, {"bit_depth", 8}}}},
                              {"threads", threads},
                              {"calibration_tables", {{kMultiFocal.table_name, sdk::to_json(table)}}}};
  const uint32_t last = kF * 24 - 1;
  for (auto _ : state) {
    state.PauseTiming();
    std::unique_ptr<sdk::Session> s;
    if (!create_session({"multi-focal", nlohmann::json::object(), rig}, s).ok()) std::abort();
    sdk::Plan plan;
    bool has = false;
    if (!s->next_plan(plan, has).ok()) std::abort();
    for (uint32_t i = 0; i < last; ++i)
      if (!s->add_frame(i, sdk::gray_view(frames[i].data(), kW, kH, 8)).ok()) std::abort();
    state.ResumeTiming();
    if (!s->add_frame(last, sdk::gray_view(frames[last].data(), kW, kH, 8)).ok()) std::abort();
    if (!s->end_round().ok()) std::abort();
    sdk::Outputs out;
    if (!s->outputs(out).ok()) std::abort();
    benchmark::DoNotOptimize(out.view());
    state.PauseTiming();
    s.reset();
    state.ResumeTiming();
  }
}
BENCHMARK(BM_MultiFocalSessionLastFrame)->Arg(2)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(5)->Repetitions(3);

}  // namespace
}  // namespace procam::defocus

BENCHMARK_MAIN();
