// SPDX-License-Identifier: MIT
// ScopedMs: adds the wall time of a scope, in milliseconds (steady clock), to
// a running total, e.g. a session's decode_ms (add_frame work, end_round,
// triangulation), which sdk::add_standard_outputs then reports.
// Thread-safety: the total is a plain double owned by the caller; use one
// ScopedMs per thread-bound (docs/threading.md) total.
#pragma once

#include <chrono>

namespace procam::sdk {

class ScopedMs {
 public:
  explicit ScopedMs(double& total_ms) : total_(total_ms), t0_(std::chrono::steady_clock::now()) {}
  ~ScopedMs() {
    total_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count();
  }
  ScopedMs(const ScopedMs&) = delete;
  ScopedMs& operator=(const ScopedMs&) = delete;

 private:
  double& total_;
  std::chrono::steady_clock::time_point t0_;
};

}  // namespace procam::sdk
