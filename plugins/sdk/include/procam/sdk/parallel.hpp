// SPDX-License-Identifier: MIT
// parallel_rows(): split per-pixel work over row bands on persistent threads.
//
// Contract: fn(y0, y1) is called for disjoint bands [y0, y1) covering [0, rows)
// exactly once each, at most `threads` at a time (the calling thread runs
// bands too). fn must only write state owned by its band. Returns after every
// band finished; if any band threw, the first exception is rethrown on the
// calling thread (so exceptions never escape a worker thread), which the SDK's
// ABI wrapper then turns into an error code.
// Bands: min(threads, rows) equal bands, band i = [rows*i/n, rows*(i+1)/n).
// Threads: the calling thread's persistent pool (procam::parallel_bands in
// procam/base/work_pool.hpp): no thread is started per call once the pool
// exists; a nested call runs its bands on the calling thread.
#pragma once

#include <algorithm>
#include <cstdint>

#include "procam/base/work_pool.hpp"

namespace procam::sdk {

template <class Fn>
void parallel_rows(uint32_t rows, uint32_t threads, Fn&& fn) {
  if (rows == 0) return;
  const uint32_t n = std::clamp<uint32_t>(threads, 1u, rows);
  if (n == 1) {
    fn(uint32_t{0}, rows);
    return;
  }
  procam::parallel_bands(n, n, [&](uint32_t i) {
    fn(static_cast<uint32_t>(uint64_t{rows} * i / n), static_cast<uint32_t>(uint64_t{rows} * (i + 1) / n));
  });
}

}  // namespace procam::sdk
