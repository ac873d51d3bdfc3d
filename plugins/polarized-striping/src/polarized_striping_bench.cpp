// SPDX-License-Identifier: MIT
// Speed of method "polarized-striping" with K = 64 stripes x 2 analyser
// angles (128 frames) at 1920x1200 8-bit: the work per added frame (one fold
// into the top-2/sum state) and what happens after the last frame
// (end_round: stripe map, DOP, S/A/B, quality sums; outputs: handing the
// maps over), for 1 and 2 threads, without and with triangulation (a
// calibrated rig adds depth_mm), with the default core maps and with all
// maps (param maps = "all"). Issue 13's goals at 2 threads: <= 0.5 ms per frame,
// <= 5 ms after the last frame.
// Run: build/plugins/polarized-striping/procam_polarized_striping_bench
//
// Setup cost: the benchmarks of the end of a scan need a fresh session with
// all 128 frames folded in per iteration, untimed: next_plan (128 projector
// patterns, ~265 MB written and faulted in) plus 128 folds, ~0.1-0.2 s of
// CPU. Left to Google Benchmark's own count (iterations until 0.5 s of
// *timed* work) that setup ran ~1000 times per repetition for
// LastTwoFrames (~0.5 ms timed) and ~50 for each AfterLastFrame row: ~13 min
// for a 5-repetition run. They run a fixed kSetupIterations instead; the
// spread between repetitions (--benchmark_repetitions=5) says how stable the
// mean is. The frames are made once per process (frames(), ~2 s).
// Most of the remaining setup was the kernel zeroing and faulting in the
// plan's fresh pattern pages (perf: memset + page faults ~60 % of the run):
// main() serves every block from the heap (M_MMAP_THRESHOLD) and keeps
// freed heap memory (M_TRIM_THRESHOLD), so that the next iteration's plan
// reuses those pages. Nothing timed allocates at that size
// except the depth row's intensity and triangulation buffers (note in
// docs/polarized-striping.md).
#include <benchmark/benchmark.h>
#include <malloc.h>

#include <atomic>
#include <chrono>
#include <random>
#include <vector>

#include "estimate.hpp"
#include "polarized_striping_session.hpp"
#include "procam/sdk/parallel.hpp"
#include "striping_pass.hpp"

namespace procam::polarized_striping {
namespace {

// Iterations of the benchmarks whose iterations each need a full scan of setup.
constexpr benchmark::IterationCount kSetupIterations = 16;

constexpr uint32_t kW = 1920, kH = 1200, kPW = 1920, kPH = 1080, kK = 64;

nlohmann::json rig(uint32_t threads, bool calibrated) {
  nlohmann::json cam = {{"width", kW}, {"height", kH}, {"bit_depth", 8}};
  nlohmann::json proj = {{"width", kPW}, {"height", kPH}};
  if (calibrated) {
    proj["intrinsics"] = {{"width", kPW}, {"height", kPH}, {"fx", 1800.0}, {"fy", 1800.0}, {"cx", 959.5}, {"cy", 539.5}};
    cam["calibration"] = {
        {"intrinsics", {{"width", kW}, {"height", kH}, {"fx", 1800.0}, {"fy", 1800.0}, {"cx", 959.5}, {"cy", 599.5}}},
        {"cam_from_proj", {{"rotation", {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}}, {"translation_mm", {150.0, 0.0, 0.0}}}}};
  }
  return {{"projector", proj}, {"cameras", {cam}}, {"threads", threads}};
}

// 128 camera frames: stripe k (every 30 columns, 10 wide, shifted by 300 px
// of disparity) over a backscatter haze of ~60 DN, best/worst analyser, noise.
const std::vector<std::vector<uint8_t>>& frames() {
  static const std::vector<std::vector<uint8_t>> f = [] {
    std::vector<std::vector<uint8_t>> v(2 * kK, std::vector<uint8_t>(size_t{kW} * kH));
    std::mt19937 rng(5);
    for (uint32_t k = 0; k < kK; ++k)
      for (uint32_t a = 0; a < 2; ++a)
        for (uint32_t y = 0; y < kH; ++y)
          for (uint32_t x = 0; x < kW; ++x) {
            const uint32_t c = (x + kPW - 300) % kPW;
            const bool lit = c / 30 == k && c % 30 >= 10 && c % 30 < 20;
            const uint32_t haze = a == 0 ? 12 : 60;
            v[2 * k + a][size_t{y} * kW + x] = static_cast<uint8_t>((lit ? 90 : 0) + haze + rng() % 6);
          }
    return v;
  }();
  return f;
}

// maps: the `maps` param ("core" by default; "all" adds cqm, snr_weight,
// gqm and stripe_col_px: the output contract before issue 13's end-of-scan goal).
std::unique_ptr<sdk::Session> session(uint32_t threads, bool calibrated = false, bool all_maps = false) {
  std::unique_ptr<sdk::Session> s;
  const nlohmann::json params = {{"maps", all_maps ? "all" : "core"}};
  if (!create_session({"polarized-striping", params, rig(threads, calibrated)}, s).ok())
    std::abort();
  sdk::Plan plan;
  bool has = false;
  if (!s->next_plan(plan, has).ok()) std::abort();
  return s;
}

void BM_PolarizedStripingAddFrame(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  auto s = session(threads);
  const auto& f = frames();
  uint32_t i = 0;
  for (auto _ : state) {
    // The session folds any frame into its state; indices cycle over the plan.
    if (!s->add_frame(i % (2 * kK), sdk::gray_view(f[i % (2 * kK)].data(), kW, kH)).ok()) std::abort();
    ++i;
  }
}
BENCHMARK(BM_PolarizedStripingAddFrame)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The last frame of each analyser (frames 126 and 127, after the 126 others
// untimed): a stack's final fold also copies the DOP sample's pixels
// (stripe_stack.hpp), so these two cost a little more than two folds; that
// is latency after the last frame too.
void BM_PolarizedStripingLastTwoFrames(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  const auto& f = frames();
  for (auto _ : state) {
    state.PauseTiming();
    auto s = session(threads);
    for (uint32_t i = 0; i + 2 < 2 * kK; ++i)
      if (!s->add_frame(i, sdk::gray_view(f[i].data(), kW, kH)).ok()) std::abort();
    state.ResumeTiming();
    for (uint32_t i = 2 * kK - 2; i < 2 * kK; ++i)
      if (!s->add_frame(i, sdk::gray_view(f[i].data(), kW, kH)).ok()) std::abort();
    state.PauseTiming();
    s.reset();
    state.ResumeTiming();
  }
}
BENCHMARK(BM_PolarizedStripingLastTwoFrames)
    ->Arg(2)
    ->Iterations(kSetupIterations)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// end_round + outputs after all 128 frames (the frames are added untimed).
void BM_PolarizedStripingAfterLastFrame(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  const bool calibrated = state.range(1) != 0, all_maps = state.range(2) != 0;
  const auto& f = frames();
  double end_ms = 0, out_ms = 0;  // wall time of end_round and of outputs (counters, per iteration)
  for (auto _ : state) {
    state.PauseTiming();
    auto s = session(threads, calibrated, all_maps);
    for (uint32_t i = 0; i < 2 * kK; ++i)
      if (!s->add_frame(i, sdk::gray_view(f[i].data(), kW, kH)).ok()) std::abort();
    sdk::Outputs out;
    state.ResumeTiming();
    const auto t0 = std::chrono::steady_clock::now();
    if (!s->end_round().ok()) std::abort();
    const auto t1 = std::chrono::steady_clock::now();
    if (!s->outputs(out).ok()) std::abort();
    const auto t2 = std::chrono::steady_clock::now();
    end_ms += std::chrono::duration<double, std::milli>(t1 - t0).count();
    out_ms += std::chrono::duration<double, std::milli>(t2 - t1).count();
    benchmark::DoNotOptimize(out.size());
    state.PauseTiming();
    s.reset();
    state.ResumeTiming();
  }
  state.counters["end_round_ms"] = benchmark::Counter(end_ms, benchmark::Counter::kAvgIterations);
  state.counters["outputs_ms"] = benchmark::Counter(out_ms, benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_PolarizedStripingAfterLastFrame)
    ->Args({1, 0, 0})->Args({2, 0, 0})->Args({2, 1, 0})->Args({2, 0, 1})
    ->ArgNames({"threads", "depth", "all_maps"})
    ->Iterations(kSetupIterations)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The parts of end_round on the same scan, without the session: both
// stacks built once; the DOP (packed_dop on the stacks' compact samples,
// 2 threads) and the one pass over the pixels (striping_pass, core maps,
// 2 threads) each alone, with and without the report's quality sums
// (PassMaps::quality).
struct Parts {
  Config cfg;
  Levels lv;
  StripeStack best, worst;
};
const Parts& parts() {
  static const Parts p = [] {
    Parts r;
    if (!parse_config("polarized-striping", nlohmann::json::object(), kPW, r.cfg).ok()) std::abort();
    r.cfg.threads = 2;
    r.lv = levels_for(r.cfg, 255.0);
    r.best = StripeStack(kW, kH, true, kK);
    r.worst = StripeStack(kW, kH, true, kK);
    const auto& f = frames();
    for (uint32_t i = 0; i < 2 * kK; ++i)
      (i % 2 ? r.worst : r.best).add(sdk::gray_view(f[i].data(), kW, kH), static_cast<uint16_t>(i / 2), 2);
    return r;
  }();
  return p;
}

void BM_PolarizedStripingEndDop(benchmark::State& state) {
  const Parts& p = parts();
  for (auto _ : state) {
    const double dop = packed_dop({p.best.sample_key1(), p.best.sample_key2(), p.best.sample_sum16(), p.best.frames()},
                                  {p.worst.sample_key1(), p.worst.sample_key2(), p.worst.sample_sum16(), p.worst.frames()},
                                  p.best.sample_size(), 1, p.lv.saturation, p.lv.dop_min_sum, p.cfg.dop_percentile, 2);
    benchmark::DoNotOptimize(dop);
  }
}
BENCHMARK(BM_PolarizedStripingEndDop)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PolarizedStripingEndPass(benchmark::State& state) {
  const Parts& p = parts();
  const size_t n = size_t{kW} * kH;
  std::vector<float> enh(n), bsc(n), stripe(n);
  std::vector<uint8_t> img(n);
  std::vector<float> centre(257, 0.0f);
  const auto ds = StripeDecodeSettings::make(p.lv.sigma, p.cfg.margin_sigma, p.lv.saturation, kK);
  const PassSettings ps{ds.margin_dn, ds.saturation_dn, p.lv.mu, p.lv.z, 0.5, true, centre.data()};
  const PackedView vb{p.best.key1(), p.best.key2(), p.best.sum16(), p.best.frames()};
  const PackedView vw{p.worst.key1(), p.worst.key2(), p.worst.sum16(), p.worst.frames()};
  PassMaps pm;
  pm.image_u8 = img.data(), pm.enhanced = enh.data(), pm.backscatter = bsc.data(), pm.stripe = stripe.data();
  pm.quality = state.range(0) != 0;
  for (auto _ : state) {
    std::atomic<size_t> valid{0};
    sdk::parallel_rows(kH, 2, [&](uint32_t y0, uint32_t y1) {
      QualitySums q;
      valid += striping_pass(vb, &vw, ps, pm, size_t{y0} * kW, size_t{y1} * kW, q);
      benchmark::DoNotOptimize(q);
    });
    benchmark::DoNotOptimize(valid.load());
  }
}
BENCHMARK(BM_PolarizedStripingEndPass)->Arg(1)->Arg(0)->ArgName("quality")->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace procam::polarized_striping

int main(int argc, char** argv) {
  // Heap, not mmap, for every block, and freed memory kept: the next
  // iteration's plan reuses the pattern pages (see the top).
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
