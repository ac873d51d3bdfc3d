// SPDX-License-Identifier: MIT
// Speed of method "checker" (S1) at 1920x1200 8-bit: the work per added frame
// (one running max/min pass) and what happens after the last frame
// (end_round: the direct/global maps; outputs: handing them over), for 1 and
// 2 threads. Issue 12's goals at 2 threads: <= 0.5 ms per frame, <= 3 ms after
// the last of 25 frames. Also multi-focal's end_round (6 settings).
// Run: build/plugins/separation/procam_separation_bench
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "separation_session.hpp"

namespace procam::separation {
namespace {

constexpr uint32_t kW = 1920, kH = 1200;

nlohmann::json rig(uint32_t threads) {
  return {{"projector", {{"width", kW}, {"height", kH}}},
          {"cameras", {{{"width", kW}, {"height", kH}, {"bit_depth", 8}}}},
          {"threads", threads}};
}

// 26 camera frames: a checker-like pattern with noise (values 10..240).
const std::vector<std::vector<uint8_t>>& frames() {
  static const std::vector<std::vector<uint8_t>> f = [] {
    std::vector<std::vector<uint8_t>> v(26, std::vector<uint8_t>(size_t{kW} * kH));
    std::mt19937 rng(5);
    for (size_t k = 0; k < v.size(); ++k)
      for (uint32_t y = 0; y < kH; ++y)
        for (uint32_t x = 0; x < kW; ++x) {
          const bool on = (((x + 3 * k) / 8) + ((y + k) / 8)) % 2 == 0;
          v[k][size_t{y} * kW + x] = static_cast<uint8_t>((on ? 200 : 40) + rng() % 40);
        }
    return v;
  }();
  return f;
}

std::unique_ptr<sdk::Session> session(const char* method, uint32_t threads, nlohmann::json params = {}) {
  std::unique_ptr<sdk::Session> s;
  if (!create_session({method, params.is_null() ? nlohmann::json::object() : params, rig(threads)}, s).ok())
    std::abort();
  sdk::Plan plan;
  bool has = false;
  if (!s->next_plan(plan, has).ok()) std::abort();
  return s;
}

void BM_CheckerAddFrame(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  auto s = session("checker", threads);
  const auto& f = frames();
  uint32_t i = 0;
  for (auto _ : state) {
    // The session folds any frame into its max/min; indices cycle over the checkers.
    if (!s->add_frame(i % 25, sdk::gray_view(f[i % 25].data(), kW, kH)).ok()) std::abort();
    ++i;
  }
}
BENCHMARK(BM_CheckerAddFrame)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_CheckerAfterLastFrame(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  const auto& f = frames();
  for (auto _ : state) {
    state.PauseTiming();
    auto s = session("checker", threads);
    for (uint32_t i = 0; i < 26; ++i)
      if (!s->add_frame(i, sdk::gray_view(f[i].data(), kW, kH)).ok()) std::abort();
    state.ResumeTiming();
    if (!s->end_round().ok()) std::abort();
    sdk::Outputs out;
    if (!s->outputs(out).ok()) std::abort();
    benchmark::DoNotOptimize(out.view());
    state.PauseTiming();
    s.reset();  // session_destroy: the maps go back to the map cache (not timed)
    state.ResumeTiming();
  }
}
// Fixed iterations: each one plans a fresh session (26 projector frames), untimed but slow.
BENCHMARK(BM_CheckerAfterLastFrame)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(6);

// end_round alone, repeated on one session (its maps are reused): the
// arithmetic of the direct/global maps without allocation or hand-over.
void BM_CheckerEndRound(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  const auto& f = frames();
  auto s = session("checker", threads);
  for (uint32_t i = 0; i < 26; ++i)
    if (!s->add_frame(i, sdk::gray_view(f[i].data(), kW, kH)).ok()) std::abort();
  for (auto _ : state)
    if (!s->end_round().ok()) std::abort();
}
BENCHMARK(BM_CheckerEndRound)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_MultiFocalAfterLastFrame(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  const auto& f = frames();
  for (auto _ : state) {
    state.PauseTiming();
    auto s = session("multi-focal", threads);
    for (uint32_t i = 0; i < 151; ++i)
      if (!s->add_frame(i, sdk::gray_view(f[(i * 7) % 26].data(), kW, kH)).ok()) std::abort();
    state.ResumeTiming();
    if (!s->end_round().ok()) std::abort();
    state.PauseTiming();
    s.reset();
    state.ResumeTiming();
  }
}
BENCHMARK(BM_MultiFocalAfterLastFrame)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(5);

}  // namespace
}  // namespace procam::separation

BENCHMARK_MAIN();
