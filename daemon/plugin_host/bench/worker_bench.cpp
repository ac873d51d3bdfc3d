// SPDX-License-Identifier: MIT
// What isolation costs (README.md "Process model"):
//  - BM_AddFrame/<backend>: one add_frame of a 1920x1200 8-bit frame on the
//    "faults" fixture's "stream" method, whose add_frame does nothing; the
//    isolated minus the in-process time is the per-frame overhead (the copy
//    into the shared ring + one request/reply). Goal: <= 0.3 ms.
//  - BM_WorkerStart/0: create_session + destroy of an isolated session (spawn,
//    exec, sandbox, load + check the plugin, session_create, teardown);
//    /1 the same with IsolationOptions::prestart (procamd's default: the
//    next worker starts while the current session runs; here, while the
//    loop destroys and recreates, so this is the worst case of back-to-back
//    sessions); /2 prestart with 60 ms (a short scan, not timed) between
//    sessions, as in procamd. Goal: <= 20 ms. BM_InProcessSessionStart for comparison.
// Run: <build>/bin/procam_worker_bench --benchmark_repetitions=5
//      --benchmark_report_aggregates_only=true   (report the medians)
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdlib>
#include <thread>
#include <string>

#include "procam/core/image.hpp"
#include "bench_host.hpp"
#include "procam/host/plugin_host.hpp"

namespace {
using namespace procam;
using namespace procam::host;

PluginHost& host_with(Isolation mode) {
  return bench::host_with(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so", mode);
}

void BM_AddFrame(benchmark::State& state) {
  const auto mode = state.range(0) == 0 ? Isolation::in_process : Isolation::process;
  auto s = host_with(mode).create_session("faults", "stream", "{}", "{}");
  if (!s) {
    state.SkipWithError(s.status().to_string().c_str());
    return;
  }
  auto plan = s->next_plan();
  if (!plan || !plan->has_value()) {
    state.SkipWithError("no plan");
    return;
  }
  const uint32_t frames = static_cast<uint32_t>((*plan)->frames.size());
  Image frame(1920, 1200, PixelType::u8);
  for (size_t i = 0; i < frame.pixel_count(); ++i) frame.ptr<uint8_t>()[i] = static_cast<uint8_t>(i * 7);
  uint32_t i = 0;
  for (auto _ : state) {
    if (i == frames) {
      state.SkipWithError("plan exhausted: lower the iteration count");
      break;
    }
    Status st = s->add_frame(i++, frame.view());
    if (!st) {
      state.SkipWithError(st.to_string().c_str());
      break;
    }
  }
  state.SetLabel(mode == Isolation::process ? "isolated" : "in_process");
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * 1920 * 1200);
}
BENCHMARK(BM_AddFrame)->Arg(0)->Arg(1)->Iterations(1000)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_WorkerStart(benchmark::State& state) {
  PluginHost& h = host_with(Isolation::process);
  IsolationOptions iso;
  iso.prestart = state.range(0) != 0;
  h.set_isolation(iso);
  for (auto _ : state) {
    if (state.range(0) == 2) {  // a scan's worth of time between sessions (not timed)
      state.PauseTiming();
      std::this_thread::sleep_for(std::chrono::milliseconds(60));
      state.ResumeTiming();
    }
    auto s = h.create_session("faults", "ok", "{}", "{}");
    if (!s) {
      state.SkipWithError(s.status().to_string().c_str());
      break;
    }
  }
  state.SetLabel(!iso.prestart ? "cold" : state.range(0) == 2 ? "prestart, 60 ms between" : "prestart, back to back");
  h.set_isolation(IsolationOptions{});
}
BENCHMARK(BM_WorkerStart)->Arg(0)->Arg(1)->Arg(2)->Iterations(50)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_InProcessSessionStart(benchmark::State& state) {
  PluginHost& h = host_with(Isolation::in_process);
  for (auto _ : state) {
    auto s = h.create_session("faults", "ok", "{}", "{}");
    benchmark::DoNotOptimize(s);
  }
}
BENCHMARK(BM_InProcessSessionStart)->Unit(benchmark::kMicrosecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
