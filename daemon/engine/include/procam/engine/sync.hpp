// SPDX-License-Identifier: MIT
// Projector–camera synchronization engine (one per rig) and latency calibration.
//
// Modes (SyncSettings::mode; default: the camera's own trigger_mode()):
//   software  show → wait for presentation → wait display latency → trigger
//             (capture()) → receive; the frame must have started after the
//             pattern was on screen.
//   hardware  the projector's sync output triggers the camera: frames are
//             matched to patterns by order and checked by frame-id count
//             (no gaps) and timestamp spacing (period ± tolerance).
//   free_run  the camera streams; after presentation + display latency the
//             next frame whose exposure started inside the pattern's window is
//             taken; frames caught during the pattern change are discarded.
// Every frame is checked; a dropped (timeout / projector never presented /
// frame-id gap in hardware mode), late (stamped after its receipt, or, in
// hardware / free-run mode, past the pattern's window), corrupt (camera status,
// wrong size) or mismatched (exposure before the pattern was on screen,
// non-increasing id, spacing off) frame re-captures only that pattern, up to
// `retries` times; then the scan fails with a clear error naming the pattern
// and what went wrong. Nothing is silently accepted.
//
// Threads: a SyncEngine is used on the rig's worker thread only.
// Errors: Status with context; nothing thrown. Units: ms (settings), ns (stamps).
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"
#include "procam/hw/rig.hpp"

namespace procam::engine {

struct SyncSettings {
  hw::TriggerMode mode = hw::TriggerMode::software;
  bool mode_from_config = false;        // false: taken from the camera
  double display_latency_ms = 0;        // presentation report → light on the scene
  double camera_latency_ms = 0;         // trigger → exposure start (reported timestamps)
  int retries = 2;                      // re-captures of one pattern
  double late_ms = 250;                 // hardware/free-run: frame stamped later than this after its window opened: late
                                        // (every mode: a stamp after the frame's receipt is late)
  double period_ms = 0;                 // hardware mode: expected frame spacing (0: 1000/refresh_hz)
  double period_tolerance = 0.5;        // fraction of period_ms
  std::chrono::milliseconds frame_timeout{2000};
  std::string latency_source = "config";  // "config" or "calibrated"
};

// Parses a rig's sync_settings() ({} → defaults); `camera_mode` is used when
// the object has no "mode". Errors name "sync.<key>".
Result<SyncSettings> parse_sync_settings(const nlohmann::json& j, hw::TriggerMode camera_mode);

// What happened during one scan (manifest "sync").
struct SyncReport {
  std::string mode;
  double display_latency_ms = 0, camera_latency_ms = 0;
  std::string latency_source;
  int retry_limit = 0;
  size_t frames = 0;          // frames accepted
  size_t retried = 0;         // re-captures
  size_t dropped = 0, late = 0, corrupt = 0, mismatched = 0, discarded = 0;
  double overhead_ms_mean = 0, overhead_ms_max = 0;  // engine work per accepted frame
  std::vector<nlohmann::json> events;                // first 50 problems: {pattern, kind, detail}
  nlohmann::json to_json() const;
};

class SyncEngine {
public:
  SyncEngine(hw::Rig& rig, SyncSettings settings);

  // Shows `pattern` as `pattern_id` and returns the frame of camera `camera`
  // that saw it, re-capturing within the retry limit. `label` names the
  // pattern in errors and events.
  Result<hw::Frame> capture(const procam_image& pattern, uint64_t pattern_id, size_t camera, const std::string& label);

  const SyncReport& report() const { return report_; }
  const SyncSettings& settings() const { return settings_; }

private:
  enum class Verdict { ok, dropped, late, corrupt, mismatched };
  Result<hw::Frame> attempt(const procam_image& pattern, uint64_t pattern_id, size_t camera, Verdict& verdict,
                            std::string& detail);
  void note(uint64_t pattern_id, const std::string& label, Verdict v, const std::string& detail);

  hw::Rig& rig_;
  SyncSettings settings_;
  SyncReport report_;
  std::vector<uint64_t> last_id_;      // per camera: last accepted frame id (0: none)
  std::vector<int64_t> last_ts_;       // per camera: last accepted timestamp
  double overhead_sum_ms_ = 0;
};

// Latency calibration: alternates black and white full-screen patterns,
// `cycles` times, and measures per camera-0 frame (a) when a white pattern
// first appears in a frame relative to its presentation report (display
// latency) and (b) how long after the capture call the frame is stamped
// (camera latency). Stores the medians in the rig (set_sync_state) and
// returns {"display_latency_ms", "camera_latency_ms", "cycles", "samples",
// "contrast"}. failed_precondition if the camera cannot tell black from white.
Result<nlohmann::json> calibrate_latency(hw::Rig& rig, int cycles = 5,
                                         std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));

}  // namespace procam::engine
