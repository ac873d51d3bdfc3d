// SPDX-License-Identifier: MIT
// Scan loop: capture each planned frame in lockstep and stream it to the decoder.
#include "procam/engine/scan_runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "procam/core/image_io.hpp"
#include "procam/core/log.hpp"
#include "procam/engine/frame_layout.hpp"
#include "procam/engine/sync.hpp"

namespace procam::engine {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

std::string frame_context(int round, size_t i, const std::string& label) {
  return "round " + std::to_string(round) + ", frame " + std::to_string(i) + " '" + label + "'";
}

// Capture one planned frame: per-frame settings, then the sync engine shows
// the pattern, waits until it is on screen and captures/verifies/retries.
Result<hw::Frame> capture_one(hw::Rig& rig, SyncEngine& sync, const host::PlannedFrame& f, uint64_t pattern_id) {
  const auto& s = f.settings;
  if (s.camera_index < 0 || static_cast<size_t>(s.camera_index) >= rig.camera_count())
    return Error(Code::invalid_argument,
                 "plan asks for camera " + std::to_string(s.camera_index) + " but the rig has " +
                     std::to_string(rig.camera_count()));
  const auto& pinfo = rig.projector().info();
  if (f.pattern.width != pinfo.width || f.pattern.height != pinfo.height)
    return Error(Code::plugin_error,
                 "pattern is " + std::to_string(f.pattern.width) + "x" + std::to_string(f.pattern.height) +
                     " but the projector is " + std::to_string(pinfo.width) + "x" + std::to_string(pinfo.height));
  // Every field of procam_frame_settings reaches a device or fails the scan:
  // a backend that cannot honour a value refuses it (failed_precondition).
  PROCAM_TRY(rig.projector().set_focus_mm(s.projector_focus_mm));
  PROCAM_TRY(rig.projector().set_polarizer_deg(s.projector_polarizer_deg));
  // ABI 3: the frame's light (0 = the projector; plans of older plugins
  // arrive with 0). A rig without that light refuses it.
  if (s.light_index < 0 || static_cast<size_t>(s.light_index) > rig.lights().size())
    return Error(Code::failed_precondition,
                 "plan asks for light " + std::to_string(s.light_index) + " but the rig has " +
                     std::to_string(rig.lights().size()) + " lights besides the projector",
                 "use a rig with lights (rig config: cameras[i].light)");
  PROCAM_TRY(rig.select_light(static_cast<size_t>(s.light_index)));
  hw::Camera& cam = rig.camera(static_cast<size_t>(s.camera_index));
  hw::CameraSettings cs;
  cs.exposure_us = s.exposure_us;
  cs.gain_db = s.gain_db;
  cs.polarizer_deg = s.polarizer_deg;
  PROCAM_TRY(cam.configure(cs));
  return sync.capture(f.pattern, pattern_id, static_cast<size_t>(s.camera_index), f.label);
}

}  // namespace

std::string recorded_frame_name(int round, size_t index) {
  char b[48];
  std::snprintf(b, sizeof b, "frame-r%d-%03zu.png", round, index);
  return b;
}

Result<ScanOutcome> run_scan(hw::Rig& rig, host::Session& session, const CaptureOptions& opts,
                             const ProgressFn& progress, const std::atomic<bool>& cancel) {
  ScanOutcome out;
  uint64_t pattern_id = 0;
  auto settings = parse_sync_settings(rig.sync_settings(),
                                      rig.camera_count() ? rig.camera(0).trigger_mode() : hw::TriggerMode::software);
  if (!settings) return settings.status();
  if (!rig.sync_settings().contains("retries")) settings->retries = opts.retries;
  if (!rig.sync_settings().contains("frame_timeout_ms")) settings->frame_timeout = opts.frame_timeout;
  SyncEngine sync(rig, *settings);
  for (int round = 1;; ++round) {
    auto plan = session.next_plan();
    if (!plan) return plan.status().with_context("planning round " + std::to_string(round));
    if (!plan->has_value()) break;
    const host::Plan& p = **plan;
    out.rounds.push_back({p.note, p.frames.size()});
    out.patterns += p.frames.size();
    PROCAM_LOG(engine, info) << "round " << round << ": " << p.frames.size() << " frames"
                             << (p.note.empty() ? "" : " — " + p.note);
    auto t0 = Clock::now();
    double add_ms = 0;
    for (size_t i = 0; i < p.frames.size(); ++i) {
      if (cancel.load()) return Error(Code::cancelled, "scan cancelled");
      const auto& f = p.frames[i];
      auto frame = capture_one(rig, sync, f, ++pattern_id);
      out.frames_retried = sync.report().retried;
      out.sync = sync.report().to_json();
      if (!frame) return frame.status().with_context(frame_context(round, i, f.label));
      if (!opts.record_dir.empty()) {
        const std::string path = (fs::path(opts.record_dir) / recorded_frame_name(round, i)).string();
        if (Status w = write_image(path, frame->image); !w)
          return w.with_context("recording " + frame_context(round, i, f.label));
      }
      auto ta = Clock::now();
      Status s = session.add_frame(static_cast<uint32_t>(i), frame->image.view());
      add_ms += ms_since(ta);
      if (!s) return s.with_context(frame_context(round, i, f.label));
      if (progress) progress({"capture", round, i + 1, p.frames.size(), f.label});
    }
    out.capture_ms += ms_since(t0) - add_ms;
    if (progress) progress({"decode", round, 0, 1, ""});
    auto td = Clock::now();
    // The loop asks for the next plan at once: an isolated worker may send
    // it (and the outputs after the last round) ahead.
    Status s = session.end_round(host::Session::AfterRound::next_plan);
    out.decode_ms += ms_since(td) + add_ms;  // streaming work in add_frame is decode time
    if (!s) return s.with_context("decoding round " + std::to_string(round));
    if (progress) progress({"decode", round, 1, 1, ""});
  }
  out.frames_retried = sync.report().retried;
  out.sync = sync.report().to_json();
  return out;
}

std::vector<std::string> list_image_files(const std::string& dir) {
  static const char* exts[] = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr", ".pgm", ".ppm", ".bmp"};
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file()) continue;
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (std::find_if(std::begin(exts), std::end(exts), [&](const char* x) { return ext == x; }) != std::end(exts))
      files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

namespace {
// Per-pixel max (white) / min (black) of the pair frames, in their own format
// (frame_layout.hpp, synthesized white / black).
struct Extremes {
  Image hi, lo;
  void add(const Image& img) {
    if (hi.empty()) {
      hi = img;
      lo = img;
      return;
    }
    const size_t n = img.pixel_count() * img.channels();
    switch (img.type()) {
      case PixelType::u8: fold(img.ptr<uint8_t>(), hi.ptr<uint8_t>(), lo.ptr<uint8_t>(), n); break;
      case PixelType::u16: fold(img.ptr<uint16_t>(), hi.ptr<uint16_t>(), lo.ptr<uint16_t>(), n); break;
      default: fold(img.ptr<float>(), hi.ptr<float>(), lo.ptr<float>(), n); break;
    }
  }
  template <class T>
  static void fold(const T* v, T* h, T* l, size_t n) {
    for (size_t i = 0; i < n; ++i) {
      h[i] = v[i] > h[i] ? v[i] : h[i];  // a NaN sample never replaces a value
      l[i] = v[i] < l[i] ? v[i] : l[i];
    }
  }
};
}  // namespace

Result<ScanOutcome> run_offline(host::Session& session, const std::string& frames_dir,
                                const ProgressFn& progress, const OfflineOptions& options) {
  ScanOutcome out;
  if (!fs::is_directory(frames_dir))
    return Error(Code::not_found, "frames folder '" + frames_dir + "' does not exist");
  std::error_code ec;
  const bool recorded = fs::is_regular_file(fs::path(frames_dir) / recorded_frame_name(1, 0), ec);
  const auto round_dir = [&](int round) {
    return round == 1 ? frames_dir : (fs::path(frames_dir) / ("round" + std::to_string(round))).string();
  };
  // Round 2 and later exist only where the capture has their frames.
  const auto captured = [&](int round) {
    return recorded ? fs::is_regular_file(fs::path(frames_dir) / recorded_frame_name(round, 0), ec)
                    : fs::is_directory(round_dir(round), ec);
  };
  for (int round = 1;; ++round) {
    std::string dir = round_dir(round);
    // A capture with fewer rounds than the method may plan: stop before
    // planning one that has no frames (a planned round cannot be abandoned).
    if (round > 1 && !captured(round)) {
      if (Status s = session.stop(); !s) return s.with_context("stopping after round " + std::to_string(round - 1));
      if (options.multi_round)
        out.rounds_skipped = "round " + std::to_string(round) + " and later not run: the capture has " +
                             (recorded ? "no recorded " + recorded_frame_name(round, 0)
                                       : "no folder '" + dir + "'") +
                             "; decoded the " + std::to_string(round - 1) +
                             " round(s) it has (the method may plan more: capture them there to run them)";
      break;
    }
    auto plan = session.next_plan();
    if (!plan) return plan.status().with_context("planning round " + std::to_string(round));
    if (!plan->has_value()) break;
    const host::Plan& p = **plan;
    std::vector<std::string> files;
    if (recorded) {
      dir = frames_dir;
      for (size_t i = 0;; ++i) {
        const fs::path f = fs::path(frames_dir) / recorded_frame_name(round, i);
        if (!fs::is_regular_file(f, ec)) break;
        files.push_back(f.string());
      }
    } else {
      files = list_image_files(dir);
    }
    FrameAssignment assign;
    if (recorded || options.layout.empty() || options.layout == "procam") {
      if (files.size() != p.frames.size()) {
        std::string labels;
        for (size_t i = 0; i < p.frames.size(); ++i)
          labels += (i ? ", " : "") + std::to_string(i) + ":" + p.frames[i].label;
        return Error(Code::invalid_argument,
                     "round " + std::to_string(round) + " needs " + std::to_string(p.frames.size()) +
                         " frames in '" + dir + "' but found " + std::to_string(files.size()) + " image files",
                     recorded ? "recorded frames are named " + recorded_frame_name(round, 0) + ", ...: the scan that "
                                                                                 "recorded them used another method or parameters"
                              : "name the files so that sorting by name gives the plan order: " + labels +
                                    " (or pass --layout: " + kBuiltinLayouts + ", or a layout file)");
      }
      for (size_t i = 0; i < files.size(); ++i) {
        assign.frame_of_file.push_back(i);
        assign.files.push_back(i);
      }
    } else {
      std::vector<std::string> labels;
      for (const auto& f : p.frames) labels.push_back(f.label);
      auto a = assign_frames(options.layout, labels, files);
      if (!a) return a.status().with_context("round " + std::to_string(round) + " in '" + dir + "'");
      assign = std::move(*a);
    }
    const bool synthesize = assign.white >= 0 || assign.black >= 0;
    std::vector<bool> is_pair(p.frames.size(), false);
    for (size_t f : assign.pair_frames) is_pair[f] = true;
    Extremes extremes;
    out.rounds.push_back({p.note, p.frames.size()});
    if (synthesize)
      out.rounds.back().note += std::string(" [") + (assign.white >= 0 ? "white" : "") +
                                (assign.white >= 0 && assign.black >= 0 ? " and " : "") +
                                (assign.black >= 0 ? "black" : "") +
                                " synthesized: per-pixel max/min of the pattern/inverse frames]";
    out.patterns += p.frames.size();
    auto t0 = Clock::now();
    for (size_t j = 0; j < assign.files.size(); ++j) {
      const std::string& file = files[assign.files[j]];
      const size_t i = assign.frame_of_file[j];
      const std::string ctx = frame_context(round, i, p.frames[i].label) + " from " + fs::path(file).filename().string();
      auto img = read_image(file);
      if (!img) return img.status().with_context(ctx);
      if (synthesize && is_pair[i]) {
        if (!extremes.hi.empty() && (img->width() != extremes.hi.width() || img->height() != extremes.hi.height() ||
                                     img->type() != extremes.hi.type() || img->channels() != extremes.hi.channels()))
          return Error(Code::invalid_argument, ctx + ": size or format differs from the earlier frames of the round");
        extremes.add(*img);
      }
      Status s = session.add_frame(static_cast<uint32_t>(i), img->view());
      if (!s) return s.with_context(ctx);
      if (progress) progress({"decode", round, j + 1, assign.files.size(), p.frames[i].label});
    }
    for (long f : {assign.white, assign.black}) {
      if (f < 0) continue;
      const Image& img = f == assign.white ? extremes.hi : extremes.lo;
      Status s = session.add_frame(static_cast<uint32_t>(f), img.view());
      if (!s) return s.with_context(frame_context(round, static_cast<size_t>(f), p.frames[static_cast<size_t>(f)].label) +
                                    " (synthesized)");
    }
    // Where the capture has the next round, the loop asks for its plan at
    // once (an isolated worker may send it ahead); else it may stop.
    Status s = session.end_round(captured(round + 1) ? host::Session::AfterRound::next_plan
                                                     : host::Session::AfterRound::next_plan_or_stop);
    if (!s) return s.with_context("decoding round " + std::to_string(round));
    out.decode_ms += ms_since(t0);
  }
  return out;
}

}  // namespace procam::engine
