// SPDX-License-Identifier: MIT
// ScanService metrics: the counters of daemon_status()["metrics"].
#include "service_internal.hpp"

namespace procam::engine {
using service_detail::is_final;

// Called with mu_ held.
nlohmann::json ScanService::metrics_locked() const {
  size_t stored = 0;
  for (const auto& [id, r] : scans_) stored += is_final(r->state);
  return {{"scans_done", done_},
           {"scans_failed", failed_},
           {"scans_cancelled", cancelled_},
           {"scans_rejected_busy", rejected_busy_},
           {"queue_depth", queue_.size()},
           {"queue_limit", cfg_.max_queue},
           {"frames_captured", frames_captured_},
           {"frames_dropped", frames_dropped_},
           {"decode_ms", {{"last", decode_ms_last_},
                          {"mean", decode_count_ ? decode_ms_sum_ / static_cast<double>(decode_count_) : 0.0},
                          {"max", decode_ms_max_}}},
           {"results_bytes", results_bytes_},
           {"scans_stored", stored}};
}

}  // namespace procam::engine
