// SPDX-License-Identifier: MIT
// GenICam camera backend over Aravis 0.8 ("aravis"): open by id / serial /
// address, ROI, Mono8 / Mono16 / Bayer*8 (→ grey), exposure, gain, trigger
// modes, buffer pool + stream, frame ids and timestamps, stream statistics,
// reconnect after the camera disappears.
//
// Ownership: AravisCamera owns its ArvCamera, ArvStream and buffers; nothing
// Aravis leaks out of this header (no GLib types here).
// Threads: thread-bound (docs/threading.md) like every hw::Camera (the rig's capture thread);
// Aravis runs its own stream thread internally. A FillFn (in-process Fake
// device only) is called on Aravis's stream thread.
// Errors: every GError becomes a Status carrying the GError message; nothing
// is thrown. Units: exposure µs, gain dB, timestamps ns CLOCK_MONOTONIC.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/hw/camera.hpp"

namespace procam::aravis {

// Fills one frame of the in-process Fake device: `dst` holds width*height
// pixels of `bytes_per_pixel` (1: Mono8, 2: Mono16 little-endian). Called on
// Aravis's stream thread; must not throw. A non-ok Status leaves the buffer
// zeroed (the frame is then delivered dark; use corrupt detection upstream).
using FillFn = std::function<Status(uint32_t width, uint32_t height, uint32_t bytes_per_pixel, uint8_t* dst)>;

struct AravisCameraConfig {
  // Device: "" = first found; else an Aravis device id ("Aravis-Fake-GV01"),
  // a serial number, or an address ("127.0.0.1"). "Fake" (or "Fake_1") opens
  // Aravis's in-process Fake device (no network).
  std::string device;
  std::string id;                 // reported CameraInfo::id; default: device serial
  std::string pixel_format = "Mono8";  // Mono8, Mono16, Bayer{RG,GB,GR,BG}8
  int32_t roi_x = 0, roi_y = 0;   // region of interest; 0 width/height = keep current
  int32_t roi_width = 0, roi_height = 0;
  double exposure_us = 0;         // <= 0: keep the camera's value
  double gain_db = -1;            // < 0: keep the camera's value
  hw::TriggerMode trigger = hw::TriggerMode::software;
  std::string trigger_line = "Line0";  // hardware trigger source
  double frame_rate = 0;          // free-run rate (Hz); <= 0: keep
  double fake_trigger_hz = 1000;  // in-process Fake only: software-trigger pacing
  int buffers = 8;                // stream buffer pool size
  int packet_size = 0;            // GigE packet size (0: keep)
  bool reconnect = true;          // reopen once when the camera disappears
  int bit_depth = 0;              // 0: 8 for Mono8/Bayer, 16 for Mono16
};

// Strict parse of a camera entry ("rig config: cameras[0].pixel_format: ...").
// Unknown keys are errors except those listed in `extra_keys` (handled by the caller).
Result<AravisCameraConfig> parse_aravis_camera_config(const nlohmann::json& j, const std::string& field,
                                                      const std::vector<std::string>& extra_keys = {});

// Aravis devices visible now (id, serial, address, model, vendor, protocol).
nlohmann::json list_aravis_devices();

class AravisCamera final : public hw::Camera {
public:
  // Opens and configures the device and starts acquisition. not_found names
  // the device asked for and lists the devices seen; other failures carry the
  // GError message. `fill` (optional) is installed as the in-process Fake
  // device's pattern source (invalid_argument for any other device).
  static Result<std::unique_ptr<AravisCamera>> open(const AravisCameraConfig& config, FillFn fill = {});
  ~AravisCamera() override;
  AravisCamera(const AravisCamera&) = delete;
  AravisCamera& operator=(const AravisCamera&) = delete;

  const hw::CameraInfo& info() const override { return info_; }
  // exposure_us / gain_db as in CameraSettings; unset values restore the
  // configured ones. polarizer_deg: failed_precondition unless NaN.
  Status configure(const hw::CameraSettings& settings) override;
  // software: discards queued stale frames, triggers, waits. hardware: waits
  // for the next externally triggered frame. free_run: returns the next frame
  // whose exposure started after the call. Buffers with missing packets or a
  // bad status → corrupt_data (naming the status); nothing within `timeout`
  // → timeout; camera gone → unavailable (after one reconnect attempt).
  Result<hw::Frame> capture(std::chrono::milliseconds timeout) override;
  hw::TriggerMode trigger_mode() const override { return config_.trigger; }
  // {"frames", "corrupt", "timeouts", "completed_buffers", "failures",
  //  "underruns", "resent_packets", "missing_packets", "lost_frames",
  //  "reconnects", "pixel_format", "trigger"}
  nlohmann::json stats() const override;

  // Change the trigger mode (stops and restarts acquisition).
  Status set_trigger_mode(hw::TriggerMode mode);
  // Current camera values (read back from the device), for round-trip checks.
  struct Readback {
    int32_t x = 0, y = 0, width = 0, height = 0;
    std::string pixel_format;
    double exposure_us = 0, gain_db = 0, frame_rate = 0;
    std::string trigger_mode, trigger_source;
  };
  Result<Readback> readback();
  // Simulates the camera disappearing (drops the device handles); the next
  // capture() reconnects. For tests of the reconnect path.
  void drop_connection_for_test();

  struct Impl;

private:
  explicit AravisCamera(AravisCameraConfig config);
  Status connect();
  void disconnect();
  Status apply_config();
  Status start_stream();

  AravisCameraConfig config_;
  hw::CameraInfo info_;
  FillFn fill_;
  std::unique_ptr<Impl> impl_;
  double exposure_us_ = 0, gain_db_ = -1;  // currently applied overrides
};

}  // namespace procam::aravis
