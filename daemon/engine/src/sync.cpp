// SPDX-License-Identifier: MIT
// Synchronization engine: show → presented → (latency) → capture → verify → retry; latency calibration.
#include "procam/engine/sync.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <thread>

#include "procam/base/clock.hpp"
#include "procam/core/image.hpp"
#include "procam/core/log.hpp"

namespace procam::engine {
namespace {

using Clock = std::chrono::steady_clock;

void sleep_until_ns(int64_t t) {
  const int64_t now = mono_ns();
  if (t > now) std::this_thread::sleep_for(std::chrono::nanoseconds(t - now));
}

double ms(int64_t ns) { return static_cast<double>(ns) / 1e6; }
int64_t ns_of_ms(double m) { return static_cast<int64_t>(m * 1e6); }

const char* verdict_name(int v) {
  static const char* names[] = {"ok", "dropped", "late", "corrupt", "mismatched"};
  return names[v];
}

double mean_level(const Image& im) {
  if (im.empty()) return 0;
  double s = 0;
  const size_t n = im.pixel_count();
  const size_t step = std::max<size_t>(1, n / 65536);
  size_t cnt = 0;
  for (size_t i = 0; i < n; i += step, ++cnt) {
    if (im.type() == PixelType::u8) s += im.ptr<uint8_t>()[i];
    else if (im.type() == PixelType::u16) s += im.ptr<uint16_t>()[i];
    else s += static_cast<double>(im.ptr<float>()[i]);
  }
  return cnt ? s / static_cast<double>(cnt) : 0;
}

}  // namespace

Result<SyncSettings> parse_sync_settings(const nlohmann::json& j, hw::TriggerMode camera_mode) {
  SyncSettings s;
  s.mode = camera_mode;
  if (j.is_null()) return s;
  if (!j.is_object()) return Error(Code::invalid_argument, "rig config: sync: must be an object");
  std::string key;
  try {
    for (auto it = j.begin(); it != j.end(); ++it) {
      key = it.key();
      if (key == "mode") {
        const std::string m = it->get<std::string>();
        if (m == "software") s.mode = hw::TriggerMode::software;
        else if (m == "hardware") s.mode = hw::TriggerMode::hardware;
        else if (m == "free_run") s.mode = hw::TriggerMode::free_run;
        else
          return Error(Code::invalid_argument, "rig config: sync.mode: unknown mode '" + m + "'",
                       "one of: software, hardware, free_run");
        s.mode_from_config = true;
      } else if (key == "display_latency_ms") {
        s.display_latency_ms = it->get<double>();
      } else if (key == "camera_latency_ms") {
        s.camera_latency_ms = it->get<double>();
      } else if (key == "retries") {
        s.retries = it->get<int>();
        if (s.retries < 0 || s.retries > 100)
          return Error(Code::invalid_argument, "rig config: sync.retries: must be in [0, 100]");
      } else if (key == "late_ms") {
        s.late_ms = it->get<double>();
      } else if (key == "period_ms") {
        s.period_ms = it->get<double>();
      } else if (key == "period_tolerance") {
        s.period_tolerance = it->get<double>();
      } else if (key == "frame_timeout_ms") {
        s.frame_timeout = std::chrono::milliseconds(it->get<int64_t>());
      } else if (key == "latency_source" || key == "calibrated_utc" || key == "calibration") {
        if (key == "latency_source") s.latency_source = it->get<std::string>();
      } else {
        return Error(Code::invalid_argument, "rig config: sync." + key + ": unknown key",
                     "known: mode, display_latency_ms, camera_latency_ms, retries, late_ms, period_ms, "
                     "period_tolerance, frame_timeout_ms");
      }
    }
  } catch (const nlohmann::json::exception& e) {
    return Error(Code::invalid_argument, "rig config: sync." + key + ": " + e.what());
  }
  if (s.display_latency_ms < 0 || s.camera_latency_ms < 0 || s.late_ms <= 0)
    return Error(Code::invalid_argument, "rig config: sync: latencies must be >= 0 and late_ms > 0");
  return s;
}

nlohmann::json SyncReport::to_json() const {
  return {{"mode", mode},
          {"display_latency_ms", display_latency_ms},
          {"camera_latency_ms", camera_latency_ms},
          {"latency_source", latency_source},
          {"retry_limit", retry_limit},
          {"frames", frames},
          {"frames_retried", retried},
          {"dropped", dropped},
          {"late", late},
          {"corrupt", corrupt},
          {"mismatched", mismatched},
          {"discarded", discarded},
          {"overhead_ms_mean", overhead_ms_mean},
          {"overhead_ms_max", overhead_ms_max},
          {"events", events}};
}

SyncEngine::SyncEngine(hw::Rig& rig, SyncSettings settings)
    : rig_(rig), settings_(std::move(settings)),
      last_id_(rig.camera_count(), 0), last_ts_(rig.camera_count(), 0) {
  report_.mode = hw::to_string(settings_.mode);
  report_.display_latency_ms = settings_.display_latency_ms;
  report_.camera_latency_ms = settings_.camera_latency_ms;
  report_.latency_source = settings_.latency_source;
  report_.retry_limit = settings_.retries;
  if (settings_.period_ms <= 0) {
    const double hz = rig.projector().info().refresh_hz;
    settings_.period_ms = hz > 0 ? 1000.0 / hz : 0;
  }
}

void SyncEngine::note(uint64_t pattern_id, const std::string& label, Verdict v, const std::string& detail) {
  switch (v) {
    case Verdict::dropped: ++report_.dropped; break;
    case Verdict::late: ++report_.late; break;
    case Verdict::corrupt: ++report_.corrupt; break;
    case Verdict::mismatched: ++report_.mismatched; break;
    case Verdict::ok: break;
  }
  if (report_.events.size() < 50)
    report_.events.push_back({{"pattern", pattern_id}, {"label", label},
                              {"kind", verdict_name(static_cast<int>(v))}, {"detail", detail}});
  PROCAM_LOG(engine, warn) << "sync: pattern " << pattern_id << " '" << label << "': "
                           << verdict_name(static_cast<int>(v)) << ": " << detail;
}

Result<hw::Frame> SyncEngine::attempt(const procam_image& pattern, uint64_t pattern_id, size_t ci, Verdict& verdict,
                                      std::string& detail) {
  verdict = Verdict::ok;
  hw::Projector& proj = rig_.projector();
  hw::Camera& cam = rig_.camera(ci);
  const auto t_begin = Clock::now();
  double device_ms = 0;  // time spent inside device calls and deliberate waits
  auto timed = [&](auto&& fn) {
    const auto t = Clock::now();
    auto r = fn();
    device_ms += std::chrono::duration<double, std::milli>(Clock::now() - t).count();
    return r;
  };
  Status shown = timed([&] { return proj.show(pattern, pattern_id); });
  if (!shown) return shown;
  auto pres = timed([&] { return proj.wait_presented(pattern_id, settings_.frame_timeout); });
  if (!pres) {
    if (pres.status().code() == Code::timeout) {
      verdict = Verdict::dropped;
      detail = "projector: " + pres.status().message();
      return pres.status();
    }
    return pres.status();
  }
  const int64_t on_screen = pres->shown_ns + ns_of_ms(settings_.display_latency_ms);
  const int64_t now0 = mono_ns();
  if (on_screen - now0 > ns_of_ms(static_cast<double>(settings_.frame_timeout.count()))) {
    verdict = Verdict::late;
    detail = "projector reports the pattern on screen " + std::to_string(ms(on_screen - now0)) + " ms from now";
    return Error(Code::timeout, detail);
  }
  // Exposure must start once the pattern is lit: trigger (or start looking
  // for free-run frames) no earlier than that.
  if (settings_.mode != hw::TriggerMode::hardware) {
    const auto t = Clock::now();
    sleep_until_ns(on_screen);
    device_ms += std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  }
  const int64_t t_trigger = mono_ns();
  Result<hw::Frame> frame = Error(Code::internal, "no frame");
  for (;;) {
    frame = timed([&] { return cam.capture(settings_.frame_timeout); });
    if (!frame) break;
    // free-run: frames that started during the pattern change are discarded.
    if (settings_.mode == hw::TriggerMode::free_run && frame->timestamp_ns < on_screen) {
      ++report_.discarded;
      continue;
    }
    break;
  }
  if (!frame) {
    const Code c = frame.status().code();
    if (c == Code::timeout || c == Code::unavailable) {
      verdict = Verdict::dropped;
    } else if (c == Code::corrupt_data) {
      verdict = Verdict::corrupt;
    } else {
      return frame.status();  // configuration or internal errors are not retried
    }
    detail = frame.status().message();
    return frame.status();
  }
  const hw::CameraInfo& info = cam.info();
  if (frame->image.empty() || frame->image.width() != info.width || frame->image.height() != info.height) {
    verdict = Verdict::corrupt;
    detail = "frame is " + std::to_string(frame->image.width()) + "x" + std::to_string(frame->image.height()) +
             ", camera is " + std::to_string(info.width) + "x" + std::to_string(info.height);
    return Error(Code::corrupt_data, detail);
  }
  const int64_t ts = frame->timestamp_ns;
  const uint64_t prev_id = last_id_[ci];
  if (prev_id != 0 && frame->frame_id <= prev_id) {
    verdict = Verdict::mismatched;
    detail = "frame id " + std::to_string(frame->frame_id) + " is not after the previous frame " + std::to_string(prev_id);
    return Error(Code::corrupt_data, detail);
  }
  if (ts < on_screen - ns_of_ms(0.001)) {
    verdict = Verdict::mismatched;
    detail = "exposure started " + std::to_string(ms(on_screen - ts)) + " ms before the pattern was on screen";
    return Error(Code::corrupt_data, detail);
  }
  // Late: a stamp after the frame was received cannot be an exposure time
  // (the camera reported it late, or its clock mapping is off); and where the
  // projector moves on by itself (hardware / free-run), a frame exposed more
  // than late_ms after its pattern's window opened may show the next one. In
  // software mode the pattern stays up until the frame arrives, so a slow
  // camera is not late.
  const int64_t received = mono_ns();
  if (ts > received + ns_of_ms(1.0)) {
    verdict = Verdict::late;
    detail = "frame stamped " + std::to_string(ms(ts - received)) + " ms after it was received";
    return Error(Code::timeout, detail);
  }
  const int64_t window_start = settings_.mode == hw::TriggerMode::hardware ? on_screen : std::max(on_screen, t_trigger);
  if (settings_.mode != hw::TriggerMode::software &&
      ts - window_start > ns_of_ms(settings_.late_ms + settings_.camera_latency_ms)) {
    verdict = Verdict::late;
    detail = "frame stamped " + std::to_string(ms(ts - window_start)) + " ms after the pattern's window opened (late_ms " +
             std::to_string(settings_.late_ms) + ")";
    return Error(Code::timeout, detail);
  }
  if (settings_.mode == hw::TriggerMode::hardware && prev_id != 0) {
    // Matched by order: the next frame of the camera must be the next id ...
    if (frame->frame_id != prev_id + 1) {
      verdict = Verdict::mismatched;
      detail = "frame id " + std::to_string(frame->frame_id) + " follows " + std::to_string(prev_id) + ": " +
               std::to_string(frame->frame_id - prev_id - 1) + " frame(s) lost, so this frame belongs to a later pattern";
      last_id_[ci] = frame->frame_id;  // resynchronise on the next attempt
      return Error(Code::corrupt_data, detail);
    }
    // ... and spaced by one projector period (only between back-to-back patterns).
    if (settings_.period_ms > 0 && last_ts_[ci] != 0) {
      const double gap = ms(ts - last_ts_[ci]);
      if (gap < settings_.period_ms * (1 - settings_.period_tolerance)) {
        verdict = Verdict::mismatched;
        detail = "frame spacing " + std::to_string(gap) + " ms is shorter than the projector period " +
                 std::to_string(settings_.period_ms) + " ms";
        last_id_[ci] = frame->frame_id;
        return Error(Code::corrupt_data, detail);
      }
    }
  }
  if (prev_id != 0 && frame->frame_id > prev_id + 1 && settings_.mode != hw::TriggerMode::hardware) {
    // Software / free-run: the frame is inside this pattern's window, so it is
    // right; the gap only says that the camera lost some other frame.
    ++report_.dropped;
  }
  last_id_[ci] = frame->frame_id;
  last_ts_[ci] = ts;
  const double total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t_begin).count();
  const double overhead = std::max(0.0, total_ms - device_ms);
  overhead_sum_ms_ += overhead;
  report_.overhead_ms_max = std::max(report_.overhead_ms_max, overhead);
  return frame;
}

Result<hw::Frame> SyncEngine::capture(const procam_image& pattern, uint64_t pattern_id, size_t camera,
                                      const std::string& label) {
  if (camera >= rig_.camera_count())
    return Error(Code::invalid_argument, "plan asks for camera " + std::to_string(camera) + " but the rig has " +
                                             std::to_string(rig_.camera_count()));
  Status last;
  std::string problems;
  for (int a = 0; a <= settings_.retries; ++a) {
    if (a > 0) ++report_.retried;
    Verdict v = Verdict::ok;
    std::string detail;
    auto f = attempt(pattern, pattern_id, camera, v, detail);
    if (f.ok()) {
      ++report_.frames;
      report_.overhead_ms_mean = overhead_sum_ms_ / static_cast<double>(report_.frames);
      return f;
    }
    if (v == Verdict::ok) return f.status();  // not a synchronization problem: no retry
    note(pattern_id, label, v, detail);
    problems += (problems.empty() ? "" : "; ") + std::string(verdict_name(static_cast<int>(v))) + ": " + detail;
    last = f.status();
  }
  return Error(last.code() == Code::ok ? Code::internal : last.code(),
               "pattern " + std::to_string(pattern_id) + " '" + label + "' failed " +
                   std::to_string(settings_.retries + 1) + " capture attempts (" + problems + ")",
               "check the camera connection and trigger wiring, or raise sync.retries / calibrate the latency");
}

Result<nlohmann::json> calibrate_latency(hw::Rig& rig, int cycles, std::chrono::milliseconds timeout) {
  if (rig.camera_count() == 0) return Error(Code::failed_precondition, "latency calibration: the rig has no camera");
  hw::Projector& proj = rig.projector();
  hw::Camera& cam = rig.camera(0);
  const auto& pi = proj.info();
  Image black(pi.width, pi.height, PixelType::u8), white(pi.width, pi.height, PixelType::u8);
  std::fill(white.data(), white.data() + white.size_bytes(), uint8_t{255});
  uint64_t id = 1u << 30;  // outside scan pattern ids
  auto show = [&](const Image& im) -> Result<hw::Presentation> {
    PROCAM_TRY(proj.show(im.view(), ++id));
    return proj.wait_presented(id, timeout);
  };
  std::vector<double> display, camera_lat;
  double dark = 0, bright = 0;
  for (int c = 0; c < std::max(1, cycles); ++c) {
    auto pb = show(black);
    if (!pb) return pb.status().with_context("latency calibration: showing black");
    const int64_t t0 = mono_ns();
    auto fb = cam.capture(timeout);
    if (!fb) return fb.status().with_context("latency calibration: capturing black");
    camera_lat.push_back(std::max(0.0, ms(fb->timestamp_ns - t0)));
    dark = mean_level(fb->image);
    auto pw = show(white);
    if (!pw) return pw.status().with_context("latency calibration: showing white");
    // Capture until white appears; its stamp minus the presentation report is the display latency.
    bool seen = false;
    for (int k = 0; k < 200 && !seen; ++k) {
      auto fw = cam.capture(timeout);
      if (!fw) return fw.status().with_context("latency calibration: capturing white");
      const double lvl = mean_level(fw->image);
      if (k == 0) bright = lvl;
      bright = std::max(bright, lvl);
      if (lvl > dark + 0.5 * (fw->image.max_value() * 0.05) && lvl > dark * 1.5 + 1) {
        display.push_back(std::max(0.0, ms(fw->timestamp_ns - pw->shown_ns)));
        seen = true;
      }
    }
    if (!seen)
      return Error(Code::failed_precondition,
                   "latency calibration: the camera never saw the white pattern (dark " + std::to_string(dark) +
                       ", bright " + std::to_string(bright) + ")",
                   "point the camera at the projected area and check exposure");
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
  };
  // A software-triggered camera stamps frames after the trigger: the part of
  // the white delay not explained by the camera is the display's.
  const double cam_ms = median(camera_lat);
  const double disp_ms = std::max(0.0, median(display) - cam_ms);
  nlohmann::json out = {{"display_latency_ms", disp_ms},
                        {"camera_latency_ms", cam_ms},
                        {"cycles", cycles},
                        {"samples", {{"display_ms", display}, {"camera_ms", camera_lat}}},
                        {"contrast", {{"dark", dark}, {"bright", bright}}}};
  rig.set_sync_state({{"display_latency_ms", disp_ms}, {"camera_latency_ms", cam_ms}, {"latency_source", "calibrated"}});
  return out;
}

}  // namespace procam::engine
