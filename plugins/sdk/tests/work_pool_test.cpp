// SPDX-License-Identifier: MIT
// Tests of the shared work pool (procam/base/work_pool.hpp) and the thread
// split built on it: every band exactly once, the first exception on the
// caller, nested and concurrent callers, persistent threads, and the exact
// bands of sdk::parallel_rows (rows*i/n) and the simulator's split.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <set>
#include <string>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "procam/base/work_pool.hpp"
#include "procam/sdk/parallel.hpp"

namespace {

TEST(WorkPool, RunsEveryBandOnceWithAnyThreadCount) {
  for (uint32_t threads : {1u, 2u, 3u, 8u}) {
    procam::WorkPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (uint32_t bands : {0u, 1u, 2u, 7u, 64u, 1000u}) {
      std::vector<std::atomic<int>> hits(bands);
      pool.for_each_band(bands, [&](uint32_t i) { hits[i]++; });
      for (uint32_t i = 0; i < bands; ++i) ASSERT_EQ(hits[i].load(), 1) << threads << "/" << bands;
    }
  }
}

TEST(WorkPool, RunCoversRowsWithDisjointBands) {
  procam::WorkPool pool(3);
  for (uint32_t rows : {1u, 2u, 5u, 23u, 24u, 25u, 1000u}) {
    std::vector<std::atomic<int>> hits(rows);
    pool.run(rows, [&](uint32_t y0, uint32_t y1) {
      ASSERT_LT(y0, y1);
      for (uint32_t y = y0; y < y1; ++y) hits[y]++;
    });
    for (uint32_t y = 0; y < rows; ++y) ASSERT_EQ(hits[y].load(), 1) << rows;
  }
}

TEST(WorkPool, RethrowsTheFirstExceptionAfterAllBandsAndStaysUsable) {
  procam::WorkPool pool(4);
  std::atomic<int> ran{0};
  EXPECT_THROW(pool.for_each_band(40,
                                  [&](uint32_t i) {
                                    ran++;
                                    if (i % 10 == 3) throw std::runtime_error("band failed");
                                  }),
               std::runtime_error);
  EXPECT_EQ(ran.load(), 40);  // later bands still ran
  std::atomic<int> again{0};
  pool.for_each_band(10, [&](uint32_t) { again++; });
  EXPECT_EQ(again.load(), 10);
}

TEST(WorkPool, KeepsItsThreadsBetweenJobs) {
  procam::WorkPool pool(3);
  std::mutex m;
  std::set<std::thread::id> first, second;
  pool.for_each_band(300, [&](uint32_t) {
    std::this_thread::sleep_for(std::chrono::microseconds(50));
    std::lock_guard<std::mutex> lock(m);
    first.insert(std::this_thread::get_id());
  });
  pool.for_each_band(300, [&](uint32_t) {
    std::this_thread::sleep_for(std::chrono::microseconds(50));
    std::lock_guard<std::mutex> lock(m);
    second.insert(std::this_thread::get_id());
  });
  EXPECT_LE(first.size(), 3u);
  for (const std::thread::id& id : second) EXPECT_TRUE(first.count(id) || id == std::this_thread::get_id());
}

// Between jobs a worker spins, then yields its CPU for a bounded time (the
// header's "Why the yield phase"), then sleeps: an idle pool must not keep
// burning a CPU. Reads each thread's state from /proc/self/task: after a
// job and 200 ms (kYieldSpin is 2 ms), every thread of the pool sleeps
// ('S'); a yield loop without its deadline leaves them runnable ('R').
TEST(WorkPool, IdleWorkersSleepAfterTheYieldPhase) {
  const auto states_of_others = [] {
    std::string states;
    const std::string self = std::to_string(::gettid());
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator("/proc/self/task", ec)) {
      if (e.path().filename() == self) continue;
      std::ifstream f(e.path() / "stat");
      std::string stat((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
      const size_t paren = stat.rfind(')');
      if (paren != std::string::npos && paren + 2 < stat.size()) states += stat[paren + 2];
    }
    return states;
  };
  if (!states_of_others().empty()) GTEST_SKIP() << "the test process already runs other threads";
  procam::WorkPool pool(3);
  std::atomic<int> ran{0};
  pool.for_each_band(64, [&](uint32_t) { ran++; });
  ASSERT_EQ(ran.load(), 64);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const std::string states = states_of_others();
  ASSERT_EQ(states.size(), 2u) << "the pool's two workers";
  EXPECT_EQ(states, "SS") << "thread states (R: still spinning or yielding 200 ms after the last job)";
  // And they still take the next job.
  pool.for_each_band(64, [&](uint32_t) { ran++; });
  EXPECT_EQ(ran.load(), 128);
}

TEST(ParallelBands, NestedCallsRunInlineAndCoverEverything) {
  std::vector<std::atomic<int>> hits(12 * 9);
  procam::parallel_bands(12, 3, [&](uint32_t i) {
    const std::thread::id outer = std::this_thread::get_id();
    procam::parallel_bands(9, 3, [&](uint32_t j) {
      EXPECT_EQ(std::this_thread::get_id(), outer);  // no pool inside a band
      hits[i * 9 + j]++;
    });
  });
  for (auto& h : hits) ASSERT_EQ(h.load(), 1);
}

TEST(ParallelBands, ConcurrentCallersEachGetEveryBand) {
  std::vector<std::thread> callers;
  std::atomic<int> failures{0};
  for (int c = 0; c < 4; ++c)
    callers.emplace_back([&] {
      for (int rep = 0; rep < 50; ++rep) {
        std::vector<std::atomic<int>> hits(37);
        procam::parallel_bands(37, 3, [&](uint32_t i) { hits[i]++; });
        for (auto& h : hits) failures += h.load() == 1 ? 0 : 1;
      }
    });
  for (std::thread& t : callers) t.join();
  EXPECT_EQ(failures.load(), 0);
}

TEST(ParallelBands, RethrowsOnTheCaller) {
  EXPECT_THROW(procam::parallel_bands(8, 2,
                                      [](uint32_t i) {
                                        if (i == 5) throw std::logic_error("x");
                                      }),
               std::logic_error);
  EXPECT_THROW(procam::parallel_bands(8, 1,
                                      [](uint32_t i) {
                                        if (i == 5) throw std::logic_error("x");
                                      }),
               std::logic_error);
}

// sdk::parallel_rows keeps its documented bands: n = min(threads, rows) bands
// [rows*i/n, rows*(i+1)/n) — the same as the fork-join version it replaced.
TEST(ParallelBands, SdkParallelRowsKeepsItsBands) {
  for (uint32_t rows : {1u, 7u, 10u, 480u})
    for (uint32_t threads : {1u, 2u, 3u, 64u}) {
      std::mutex m;
      std::set<std::pair<uint32_t, uint32_t>> got;
      procam::sdk::parallel_rows(rows, threads, [&](uint32_t y0, uint32_t y1) {
        std::lock_guard<std::mutex> lock(m);
        got.insert({y0, y1});
      });
      const uint32_t n = std::min(std::max(threads, 1u), rows);
      std::set<std::pair<uint32_t, uint32_t>> want;
      uint32_t y = 0;
      for (uint32_t i = 0; i < n; ++i) {  // band ends by integer division, accumulated
        const uint32_t end = static_cast<uint32_t>((uint64_t{rows} * (i + 1)) / n);
        want.insert({y, end});
        y = end;
      }
      EXPECT_EQ(got, want) << rows << "/" << threads;
    }
}

}  // namespace
