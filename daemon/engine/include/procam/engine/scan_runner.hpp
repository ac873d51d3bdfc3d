// SPDX-License-Identifier: MIT
// Runs one scan: plan → projector/camera capture → frames → decoder, round by
// round, and the same loop fed from files for offline decoding.
//
// Threads: run on the rig's worker thread; `progress` is called on that thread.
// Errors: the first failure stops the scan and is returned with context
// ("round 1, frame 7 'col bit 3': camera timed out"); nothing is thrown.
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

namespace procam::engine {

struct Progress {
  std::string stage;   // "capture", "decode"
  int round = 1;
  size_t done = 0, total = 0;
  std::string message;
};
using ProgressFn = std::function<void(const Progress&)>;

struct CaptureOptions {
  std::chrono::milliseconds frame_timeout{2000};
  int retries = 2;     // re-captures of one frame after a dropped/late/corrupt/mismatched frame
                       // (the rig config's sync.retries overrides it)
  // When set, every frame given to the decoder is also written there as
  // "frame-r<round>-<index>.png" (lossless, the camera's bit depth), a
  // layout run_offline() reads back: the raw data of a scan, to decode again
  // later with other methods or parameters.
  std::string record_dir;
};

// The recorded-frame file name (CaptureOptions::record_dir), e.g. frame-r1-007.png.
std::string recorded_frame_name(int round, size_t index);

struct RoundSummary {
  std::string note;
  size_t frames = 0;
};

struct ScanOutcome {
  std::vector<RoundSummary> rounds;
  // Offline only: why the plugin's later rounds were not run (a multi-round
  // method on a capture with fewer rounds); empty when every round ran.
  std::string rounds_skipped;
  size_t patterns = 0;
  double capture_ms = 0, decode_ms = 0;
  size_t frames_retried = 0;
  // Synchronization report (engine/sync.hpp SyncReport::to_json()): mode,
  // latencies used, frames retried, dropped/late/corrupt/mismatched counts.
  nlohmann::json sync = nlohmann::json::object();
};

// Drives `session` against `rig` until the plugin has no more rounds.
Result<ScanOutcome> run_scan(hw::Rig& rig, host::Session& session, const CaptureOptions& opts,
                             const ProgressFn& progress, const std::atomic<bool>& cancel);

// Offline: feeds image files instead of a rig. Two layouts of `frames_dir`:
//  - recorded (CaptureOptions::record_dir): files frame-r<round>-<index>.png,
//    all rounds in one folder (other files, e.g. a scan's previews, ignored);
//  - plain: the round-1 frames in the plan's order (every image file, sorted
//    by file name); a multi-round method reads later rounds from sub-folders
//    "round2", "round3", ...
// A capture with fewer rounds than the method plans (no "roundN" folder, or
// no recorded frame-rN-000.png) decodes the rounds that exist, stops the
// session there (host::Session::stop: the outputs are those of the last
// decoded round) and, with OfflineOptions::multi_round, says so in
// ScanOutcome::rounds_skipped.
// Errors list the files expected (by plan label) versus found.
// `layout` (plain folders only): which file is which plan frame —
// frame_layout.hpp ("procam" = plan order, "opencv-graycode", "gupta-pairs" or
// a JSON layout file); white / black missing from the capture are synthesized
// from the pattern/inverse frames.
struct OfflineOptions {
  std::string layout = "procam";
  // The method may plan more than one round (its describe() "rounds" is not
  // 1): a missing later round is then reported in rounds_skipped.
  bool multi_round = false;
};
Result<ScanOutcome> run_offline(host::Session& session, const std::string& frames_dir,
                                const ProgressFn& progress, const OfflineOptions& options = {});

// Image files in a folder, sorted by name (png, jpg, jpeg, tif, tiff, exr, pgm, ppm, bmp).
std::vector<std::string> list_image_files(const std::string& dir);

}  // namespace procam::engine
