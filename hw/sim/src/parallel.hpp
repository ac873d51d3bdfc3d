// SPDX-License-Identifier: MIT
// Internal: split a row range over a few std::threads (fork–join per call).
// fn(begin, end) must be safe to run concurrently on disjoint row ranges.
// If a thread cannot be started its rows run on the calling thread.
#pragma once

#include <algorithm>
#include <cstdint>
#include <system_error>
#include <thread>
#include <vector>

namespace procam::sim::detail {

template <typename F>
void parallel_rows(uint32_t rows, int threads, F&& fn) {
  const uint32_t min_rows_per_thread = 16;
  uint32_t n = threads < 1 ? 1u : static_cast<uint32_t>(threads);
  n = std::min(n, std::max(1u, rows / min_rows_per_thread));
  if (n <= 1) {
    fn(0u, rows);
    return;
  }
  std::vector<std::thread> workers;
  workers.reserve(n - 1);
  const uint32_t chunk = (rows + n - 1) / n;
  for (uint32_t i = 1; i < n; ++i) {
    const uint32_t b = std::min(rows, i * chunk), e = std::min(rows, (i + 1) * chunk);
    if (b >= e) continue;
    try {
      workers.emplace_back([&fn, b, e] { fn(b, e); });
    } catch (const std::system_error&) {
      fn(b, e);
    }
  }
  fn(0u, std::min(rows, chunk));
  for (auto& w : workers) w.join();
}

inline int default_threads() {
  const unsigned hc = std::thread::hardware_concurrency();
  return static_cast<int>(std::clamp(hc, 1u, 8u));
}

}  // namespace procam::sim::detail
