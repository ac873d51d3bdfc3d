// SPDX-License-Identifier: MIT
// The one time base of every device timestamp: CLOCK_MONOTONIC in nanoseconds (header-only).
//
// Projector presentation stamps, camera frame stamps and the sync engine's
// deadlines all use it, so they compare directly. Thread-safe; never fails
// on Linux (clock_gettime(CLOCK_MONOTONIC) cannot fail with a valid pointer).
#pragma once

#include <time.h>

#include <cstdint>

namespace procam {

// Now on CLOCK_MONOTONIC, nanoseconds since an unspecified start (boot).
inline int64_t mono_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * 1000000000 + ts.tv_nsec;
}

}  // namespace procam
