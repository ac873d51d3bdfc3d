// SPDX-License-Identifier: MIT
// Internal: split a row range over a few threads, through the calling thread's
// persistent procam::WorkPool (procam::parallel_bands, procam/base/work_pool.hpp)
// so a frame's dozen row loops do not each start and join threads.
// fn(begin, end) must be safe to run concurrently on disjoint row ranges.
// Bands: n = min(threads, rows / 16) (at least 1) bands of ceil(rows / n)
// rows, [i * chunk, min(rows, (i + 1) * chunk)) — the same bands as the
// earlier fork-join version, so per-band partial sums are unchanged.
// Errors: the first exception a band throws is rethrown on the calling thread
// after every band finished. If the pool's threads cannot be started, or the
// call is nested inside another band, the bands run on the calling thread.
#pragma once

#include <algorithm>
#include <cstdint>
#include <thread>

#include "procam/base/work_pool.hpp"

namespace procam::sim::detail {

template <typename F>
void parallel_rows(uint32_t rows, int threads, F&& fn) {
  const uint32_t min_rows_per_thread = 16;
  const uint32_t wanted = threads < 1 ? 1u : static_cast<uint32_t>(threads);
  const uint32_t n = std::min(wanted, std::max(1u, rows / min_rows_per_thread));
  if (n <= 1) {
    fn(0u, rows);
    return;
  }
  const uint32_t chunk = (rows + n - 1) / n;
  // The pool has `wanted` threads whatever n is, so row counts that give
  // different n share one pool per calling thread.
  procam::parallel_bands(n, wanted, [&](uint32_t i) {
    const uint32_t b = std::min(rows, i * chunk), e = std::min(rows, (i + 1) * chunk);
    if (b < e) fn(b, e);
  });
}

inline int default_threads() {
  const unsigned hc = std::thread::hardware_concurrency();
  return static_cast<int>(std::clamp(hc, 1u, 8u));
}

}  // namespace procam::sim::detail
