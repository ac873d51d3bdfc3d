// SPDX-License-Identifier: MIT
// parallel_rows(): split per-pixel work over row bands on std::threads.
//
// Contract: fn(y0, y1) is called for disjoint bands [y0, y1) covering [0, rows)
// exactly once each, at most `threads` at a time (the calling thread runs the
// first band). fn must only write state owned by its band. Returns after
// every band finished; if any band threw, the first exception is rethrown on
// the calling thread (so exceptions never escape a worker thread), which the
// SDK's ABI wrapper then turns into an error code.
#pragma once

#include <algorithm>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace procam::sdk {

template <class Fn>
void parallel_rows(uint32_t rows, uint32_t threads, Fn&& fn) {
  if (rows == 0) return;
  const uint32_t n = std::clamp<uint32_t>(threads, 1u, rows);
  if (n == 1) {
    fn(uint32_t{0}, rows);
    return;
  }
  std::exception_ptr first;
  std::mutex mutex;
  auto band = [&](uint32_t i) {
    const uint32_t y0 = static_cast<uint32_t>(uint64_t{rows} * i / n);
    const uint32_t y1 = static_cast<uint32_t>(uint64_t{rows} * (i + 1) / n);
    try {
      fn(y0, y1);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      if (!first) first = std::current_exception();
    }
  };
  {
    std::vector<std::jthread> workers;  // jthread joins on destruction, even on throw
    workers.reserve(n - 1);
    for (uint32_t i = 1; i < n; ++i) workers.emplace_back(band, i);
    band(0);
  }
  if (first) std::rethrow_exception(first);
}

}  // namespace procam::sdk
