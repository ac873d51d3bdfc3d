// SPDX-License-Identifier: MIT
// Aravis (GenICam) camera: device open, configuration, stream, capture, stats, reconnect.
#include "procam/hw/aravis/aravis_camera.hpp"

#include <arv.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <ctime>
#include <mutex>
#include <set>

#include "procam/core/json_fields.hpp"
#include "procam/core/log.hpp"

namespace procam::aravis {
namespace {

int64_t clock_ns(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return int64_t{ts.tv_sec} * 1000000000 + ts.tv_nsec;
}

// GError → Status (frees the error). `what` says what was being done.
Status gerror_status(GError* err, const std::string& what, Code code = Code::io_error) {
  std::string msg = what + ": " + (err && err->message ? err->message : "unknown Aravis error");
  if (err) g_error_free(err);
  return Error(code, msg);
}

const char* buffer_status_name(ArvBufferStatus s) {
  switch (s) {
    case ARV_BUFFER_STATUS_SUCCESS: return "success";
    case ARV_BUFFER_STATUS_CLEARED: return "cleared";
    case ARV_BUFFER_STATUS_TIMEOUT: return "timeout (packets did not all arrive)";
    case ARV_BUFFER_STATUS_MISSING_PACKETS: return "missing packets";
    case ARV_BUFFER_STATUS_WRONG_PACKET_ID: return "wrong packet id";
    case ARV_BUFFER_STATUS_SIZE_MISMATCH: return "size mismatch";
    case ARV_BUFFER_STATUS_FILLING: return "still filling";
    case ARV_BUFFER_STATUS_ABORTED: return "aborted";
    default: return "unknown";
  }
}

bool is_fake_name(const std::string& d) { return d == "Fake" || d.rfind("Fake_", 0) == 0; }

uint32_t bytes_per_pixel(const std::string& fmt) { return fmt == "Mono16" ? 2 : 1; }
bool is_bayer(const std::string& fmt) { return fmt.rfind("Bayer", 0) == 0; }

}  // namespace

// Fill-callback context, shared with Aravis's stream thread.
struct FillContext {
  FillFn fn;
  ArvFakeCamera* fake = nullptr;
  size_t payload = 0;
  std::atomic<uint64_t> failures{0};
};

struct AravisCamera::Impl {
  ArvCamera* camera = nullptr;
  ArvStream* stream = nullptr;
  ArvFakeCamera* fake = nullptr;  // in-process Fake device only (owned by the device)
  std::unique_ptr<FillContext> fill;
  std::atomic<bool> control_lost{false};
  gulong lost_handler = 0;
  size_t payload = 0;
  std::string pixel_format;
  uint32_t width = 0, height = 0;
  // statistics
  uint64_t frames = 0, stale = 0, corrupt = 0, timeouts = 0, lost_frames = 0, reconnects = 0;
  uint64_t last_raw_id = 0, last_id = 0;
  uint64_t id_epoch = 0;  // unwrapped id = epoch * 65535 + raw (GigE ids wrap 65535 → 1)
  bool have_last = false;
  // stats saved across reconnects
  uint64_t prev_completed = 0, prev_failures = 0, prev_underruns = 0, prev_resent = 0, prev_missing = 0;
};

namespace {

void fill_trampoline(ArvBuffer* buffer, void* data, guint32 /*exposure_us*/, guint32 /*gain*/,
                     ArvPixelFormat pixel_format) {
  auto* ctx = static_cast<FillContext*>(data);
  guint32 w = 0, h = 0;
  arv_fake_camera_read_register(ctx->fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, &w);
  arv_fake_camera_read_register(ctx->fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, &h);
  const uint32_t bpp = pixel_format == ARV_PIXEL_FORMAT_MONO_16 ? 2 : 1;
  size_t size = 0;
  auto* dst = static_cast<uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, &size)));
  const size_t need = size_t{w} * h * bpp;
  if (dst == nullptr || need == 0 || need > ctx->payload) {
    ctx->failures++;
    return;
  }
  std::memset(dst, 0, need);
  if (!ctx->fn) return;
  Status s = ctx->fn(w, h, bpp, dst);
  if (!s.ok()) {
    ctx->failures++;
    PROCAM_LOG(hw, warn) << "aravis fake fill: " << s.to_string();
  }
}

// Unwraps a 16-bit GigE block id and counts gaps as lost frames.
uint64_t track_id(AravisCamera::Impl& d, uint64_t raw) {
  if (d.have_last && raw < d.last_raw_id && d.last_raw_id - raw > 32768) d.id_epoch++;
  const uint64_t id = d.id_epoch * 65535 + raw;
  if (d.have_last && id > d.last_id + 1) d.lost_frames += id - d.last_id - 1;
  d.last_raw_id = raw;
  d.last_id = id;
  d.have_last = true;
  return id;
}

void on_control_lost(ArvDevice* /*device*/, gpointer data) {
  static_cast<AravisCamera::Impl*>(data)->control_lost.store(true);
}

}  // namespace

// ---------------------------------------------------------------- config

Result<AravisCameraConfig> parse_aravis_camera_config(const nlohmann::json& j, const std::string& field,
                                                      const std::vector<std::string>& extra_keys) {
  AravisCameraConfig c;
  ParseErrors errors{"rig config", {}};
  FieldReader r(j, field, errors);
  if (!errors.ok()) return errors.first;
  std::vector<std::string> known = {"backend", "device", "id", "pixel_format", "roi", "exposure_us",
                                    "gain_db", "trigger", "trigger_line", "frame_rate",
                                    "fake_trigger_hz", "buffers", "packet_size", "reconnect",
                                    "bit_depth"};
  known.insert(known.end(), extra_keys.begin(), extra_keys.end());
  r.only(known, "aravis camera keys: device, id, pixel_format, roi {x,y,width,height}, exposure_us, "
                "gain_db, trigger (software|hardware|free_run), trigger_line, frame_rate, buffers, "
                "packet_size, reconnect, bit_depth, fake_trigger_hz");
  c.device = r.string("device", std::string());
  c.id = r.string("id", std::string());
  c.pixel_format = r.string("pixel_format", std::string("Mono8"));
  static const std::set<std::string> fmts = {"Mono8", "Mono16", "BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8"};
  if (errors.ok() && fmts.count(c.pixel_format) == 0)
    r.fail("pixel_format", "unsupported '" + c.pixel_format + "'",
           "supported: Mono8, Mono16, BayerRG8, BayerGB8, BayerGR8, BayerBG8");
  if (const nlohmann::json* rj = r.object("roi", false)) {
    FieldReader roi(*rj, r.field("roi"), errors);
    roi.only({"x", "y", "width", "height"});
    constexpr uint64_t kMax = INT32_MAX;
    c.roi_x = static_cast<int32_t>(roi.integer("x", 0, 0, kMax));  // values must be >= 0
    c.roi_y = static_cast<int32_t>(roi.integer("y", 0, 0, kMax));
    c.roi_width = static_cast<int32_t>(roi.integer("width", 0, 0, kMax));
    c.roi_height = static_cast<int32_t>(roi.integer("height", 0, 0, kMax));
  }
  c.exposure_us = r.number("exposure_us", 0.0, "µs; <= 0 keeps the camera's value");
  c.gain_db = r.number("gain_db", -1.0, "dB; < 0 keeps the camera's value");
  const std::string t = r.string("trigger", std::string("software"));
  if (t == "software") c.trigger = hw::TriggerMode::software;
  else if (t == "hardware") c.trigger = hw::TriggerMode::hardware;
  else if (t == "free_run") c.trigger = hw::TriggerMode::free_run;
  else if (errors.ok()) r.fail("trigger", "unknown mode '" + t + "'", "one of: software, hardware, free_run");
  c.trigger_line = r.string("trigger_line", std::string("Line0"));
  c.frame_rate = r.number("frame_rate", 0.0, "Hz; <= 0 keeps the camera's value");
  c.fake_trigger_hz = r.number("fake_trigger_hz", 1000.0, "Hz");
  c.buffers = static_cast<int>(r.integer("buffers", 8, 2, 256));
  c.packet_size = static_cast<int>(r.integer("packet_size", 0, 0, 65535));
  c.reconnect = r.boolean("reconnect", true);
  c.bit_depth = static_cast<int>(r.integer("bit_depth", 0, 0, 16));
  if (!errors.ok()) return errors.first;
  return c;
}

nlohmann::json list_aravis_devices() {
  nlohmann::json out = nlohmann::json::array();
  arv_update_device_list();
  const unsigned n = arv_get_n_devices();
  for (unsigned i = 0; i < n; ++i) {
    auto s = [](const char* p) { return std::string(p ? p : ""); };
    out.push_back({{"id", s(arv_get_device_id(i))},
                   {"serial", s(arv_get_device_serial_nbr(i))},
                   {"address", s(arv_get_device_address(i))},
                   {"model", s(arv_get_device_model(i))},
                   {"vendor", s(arv_get_device_vendor(i))},
                   {"protocol", s(arv_get_device_protocol(i))}});
  }
  return out;
}

// ---------------------------------------------------------------- camera

AravisCamera::AravisCamera(AravisCameraConfig config) : config_(std::move(config)), impl_(std::make_unique<Impl>()) {
  exposure_us_ = config_.exposure_us;
  gain_db_ = config_.gain_db;
}

AravisCamera::~AravisCamera() { disconnect(); }

Result<std::unique_ptr<AravisCamera>> AravisCamera::open(const AravisCameraConfig& config, FillFn fill) {
  if (fill && !is_fake_name(config.device))
    return Error(Code::invalid_argument,
                 "aravis: a fill source needs the in-process Fake device, not '" + config.device + "'",
                 "set \"device\": \"Fake\"");
  std::unique_ptr<AravisCamera> cam(new AravisCamera(config));
  cam->fill_ = std::move(fill);
  PROCAM_TRY(cam->connect());
  return cam;
}

void AravisCamera::disconnect() {
  Impl& d = *impl_;
  if (d.stream) {
    guint64 completed = 0, failures = 0, underruns = 0;
    arv_stream_get_statistics(d.stream, &completed, &failures, &underruns);
    d.prev_completed += completed;
    d.prev_failures += failures;
    d.prev_underruns += underruns;
    if (ARV_IS_GV_STREAM(d.stream)) {
      guint64 resent = 0, missing = 0;
      arv_gv_stream_get_statistics(ARV_GV_STREAM(d.stream), &resent, &missing);
      d.prev_resent += resent;
      d.prev_missing += missing;
    }
  }
  if (d.camera) {
    GError* err = nullptr;
    arv_camera_stop_acquisition(d.camera, &err);
    if (err) g_error_free(err);
  }
  if (d.stream) {
    g_object_unref(d.stream);
    d.stream = nullptr;
  }
  if (d.camera) {
    ArvDevice* dev = arv_camera_get_device(d.camera);
    if (dev && d.lost_handler) g_signal_handler_disconnect(dev, d.lost_handler);
    d.lost_handler = 0;
    if (d.fake) arv_fake_camera_set_fill_pattern(d.fake, nullptr, nullptr);
    g_object_unref(d.camera);
    d.camera = nullptr;
  }
  d.fake = nullptr;
  d.fill.reset();
}

Status AravisCamera::connect() {
  Impl& d = *impl_;
  GError* err = nullptr;
  if (is_fake_name(config_.device)) arv_enable_interface("Fake");
  std::string name = config_.device;
  if (is_fake_name(name)) name = "Fake_1";
  // A serial number that is not a device id: look it up.
  if (!name.empty() && !is_fake_name(name)) {
    arv_update_device_list();
    const unsigned n = arv_get_n_devices();
    for (unsigned i = 0; i < n; ++i) {
      const char* serial = arv_get_device_serial_nbr(i);
      const char* id = arv_get_device_id(i);
      if (serial && id && name == serial) {
        name = id;
        break;
      }
    }
  }
  d.camera = arv_camera_new(name.empty() ? nullptr : name.c_str(), &err);
  if (!d.camera) {
    std::string seen;
    for (const auto& dev : list_aravis_devices())
      seen += (seen.empty() ? "" : ", ") + dev["id"].get<std::string>() + " (" + dev["address"].get<std::string>() + ")";
    std::string msg = "aravis: no camera '" + (config_.device.empty() ? std::string("<first>") : config_.device) + "'";
    if (err) {
      msg += ": " + std::string(err->message ? err->message : "");
      g_error_free(err);
    }
    return Error(Code::not_found, msg,
                 seen.empty() ? "no GenICam devices found (is the camera powered and on this subnet?)"
                              : "devices found: " + seen);
  }
  ArvDevice* dev = arv_camera_get_device(d.camera);
  d.lost_handler = g_signal_connect_data(dev, "control-lost", reinterpret_cast<GCallback>(&on_control_lost),
                                         impl_.get(), nullptr, G_CONNECT_AFTER);
  d.control_lost = false;
  if (ARV_IS_FAKE_DEVICE(dev)) {
    d.fake = arv_fake_device_get_fake_camera(ARV_FAKE_DEVICE(dev));
    if (d.fake) arv_fake_camera_set_trigger_frequency(d.fake, config_.fake_trigger_hz);
  }
  if (fill_ && !d.fake) return Error(Code::internal, "aravis: fill source given but the device is not a Fake device");
  Status s = apply_config();
  if (!s) return s;
  const char* serial = arv_camera_get_device_serial_number(d.camera, nullptr);
  const char* model = arv_camera_get_model_name(d.camera, nullptr);
  info_.backend = "aravis";
  info_.id = !config_.id.empty() ? config_.id : (serial ? serial : name);
  info_.width = d.width;
  info_.height = d.height;
  info_.bit_depth = config_.bit_depth > 0 ? static_cast<uint32_t>(config_.bit_depth)
                                          : (bytes_per_pixel(d.pixel_format) == 2 ? 16u : 8u);
  PROCAM_LOG(hw, info) << "aravis: opened " << info_.id << " (" << (model ? model : "?") << ") " << d.width << "x"
                       << d.height << " " << d.pixel_format << ", trigger " << hw::to_string(config_.trigger);
  return start_stream();
}

Status AravisCamera::apply_config() {
  Impl& d = *impl_;
  GError* err = nullptr;
  arv_camera_set_pixel_format_from_string(d.camera, config_.pixel_format.c_str(), &err);
  if (err) return gerror_status(err, "aravis: setting pixel format " + config_.pixel_format, Code::invalid_argument);
  if (config_.roi_width > 0 && config_.roi_height > 0) {
    arv_camera_set_region(d.camera, config_.roi_x, config_.roi_y, config_.roi_width, config_.roi_height, &err);
    if (err) return gerror_status(err, "aravis: setting ROI", Code::invalid_argument);
  }
  gint x = 0, y = 0, w = 0, h = 0;
  arv_camera_get_region(d.camera, &x, &y, &w, &h, &err);
  if (err) return gerror_status(err, "aravis: reading ROI");
  if (config_.roi_width > 0 && (w != config_.roi_width || h != config_.roi_height || x != config_.roi_x ||
                                y != config_.roi_y))
    return Error(Code::invalid_argument,
                 "aravis: camera accepted ROI " + std::to_string(x) + "," + std::to_string(y) + " " + std::to_string(w) +
                     "x" + std::to_string(h) + " instead of the configured one",
                 "use offsets/sizes that are multiples of the camera's increments");
  d.width = static_cast<uint32_t>(w);
  d.height = static_cast<uint32_t>(h);
  d.pixel_format = config_.pixel_format;
  if (exposure_us_ > 0) {
    arv_camera_set_exposure_time(d.camera, exposure_us_, &err);
    if (err) return gerror_status(err, "aravis: setting exposure", Code::invalid_argument);
  }
  if (gain_db_ >= 0) {
    arv_camera_set_gain(d.camera, gain_db_, &err);
    if (err) return gerror_status(err, "aravis: setting gain", Code::invalid_argument);
  }
  // Frame rate first: on some cameras (and the fake) it turns TriggerMode Off.
  if (config_.frame_rate > 0) {
    arv_camera_set_frame_rate(d.camera, config_.frame_rate, &err);
    if (err) return gerror_status(err, "aravis: setting frame rate", Code::invalid_argument);
  }
  arv_camera_set_acquisition_mode(d.camera, ARV_ACQUISITION_MODE_CONTINUOUS, &err);
  if (err) return gerror_status(err, "aravis: setting acquisition mode");
  switch (config_.trigger) {
    case hw::TriggerMode::free_run:
      arv_camera_set_string(d.camera, "TriggerMode", "Off", &err);
      break;
    case hw::TriggerMode::software:
      arv_camera_set_string(d.camera, "TriggerMode", "On", &err);
      if (!err) arv_camera_set_string(d.camera, "TriggerSource", "Software", &err);
      break;
    case hw::TriggerMode::hardware:
      arv_camera_set_string(d.camera, "TriggerMode", "On", &err);
      if (!err) arv_camera_set_string(d.camera, "TriggerSource", config_.trigger_line.c_str(), &err);
      break;
  }
  if (err) return gerror_status(err, std::string("aravis: setting trigger mode ") + hw::to_string(config_.trigger));
  if (config_.packet_size > 0 && arv_camera_is_gv_device(d.camera)) {
    arv_camera_gv_set_packet_size(d.camera, config_.packet_size, &err);
    if (err) return gerror_status(err, "aravis: setting packet size", Code::invalid_argument);
  }
  return Status::Ok();
}

Status AravisCamera::start_stream() {
  Impl& d = *impl_;
  GError* err = nullptr;
  d.payload = arv_camera_get_payload(d.camera, &err);
  if (err) return gerror_status(err, "aravis: reading payload size");
  if (d.fake && fill_) {
    d.fill = std::make_unique<FillContext>();
    d.fill->fn = fill_;
    d.fill->fake = d.fake;
    d.fill->payload = d.payload;
    arv_fake_camera_set_fill_pattern(d.fake, &fill_trampoline, d.fill.get());
  }
  d.stream = arv_camera_create_stream(d.camera, nullptr, nullptr, &err);
  if (!d.stream) return gerror_status(err, "aravis: creating the stream", Code::unavailable);
  if (ARV_IS_GV_STREAM(d.stream))
    g_object_set(d.stream, "packet-resend", ARV_GV_STREAM_PACKET_RESEND_NEVER, nullptr);
  for (int i = 0; i < config_.buffers; ++i) arv_stream_push_buffer(d.stream, arv_buffer_new(d.payload, nullptr));
  arv_camera_start_acquisition(d.camera, &err);
  if (err) return gerror_status(err, "aravis: starting acquisition", Code::unavailable);
  d.have_last = false;
  return Status::Ok();
}

Status AravisCamera::configure(const hw::CameraSettings& settings) {
  if (!std::isnan(settings.polarizer_deg))
    return Error(Code::failed_precondition, "aravis camera '" + info_.id + "' has no polarizer",
                 "remove polarizer_deg from the plan or use a rig with a motorised analyser");
  const double exp = settings.exposure_us > 0 ? settings.exposure_us : config_.exposure_us;
  const double gain = settings.gain_db >= 0 ? settings.gain_db : config_.gain_db;
  Impl& d = *impl_;
  if (!d.camera) {
    exposure_us_ = exp;
    gain_db_ = gain;
    return Status::Ok();  // applied on reconnect
  }
  GError* err = nullptr;
  if (exp > 0 && exp != exposure_us_) {
    arv_camera_set_exposure_time(d.camera, exp, &err);
    if (err) return gerror_status(err, "aravis: setting exposure " + std::to_string(exp) + " us", Code::invalid_argument);
    exposure_us_ = exp;
  }
  if (gain >= 0 && gain != gain_db_) {
    arv_camera_set_gain(d.camera, gain, &err);
    if (err) return gerror_status(err, "aravis: setting gain " + std::to_string(gain) + " dB", Code::invalid_argument);
    gain_db_ = gain;
  }
  return Status::Ok();
}

Status AravisCamera::set_trigger_mode(hw::TriggerMode mode) {
  config_.trigger = mode;
  disconnect();
  return connect();
}

void AravisCamera::drop_connection_for_test() {
  disconnect();
  impl_->control_lost = true;
}

Result<AravisCamera::Readback> AravisCamera::readback() {
  Impl& d = *impl_;
  if (!d.camera) return Error(Code::unavailable, "aravis: camera not connected");
  Readback r;
  GError* err = nullptr;
  arv_camera_get_region(d.camera, &r.x, &r.y, &r.width, &r.height, &err);
  if (err) return gerror_status(err, "aravis: reading ROI");
  const char* pf = arv_camera_get_pixel_format_as_string(d.camera, &err);
  if (err) return gerror_status(err, "aravis: reading pixel format");
  r.pixel_format = pf ? pf : "";
  r.exposure_us = arv_camera_get_exposure_time(d.camera, &err);
  if (err) return gerror_status(err, "aravis: reading exposure");
  r.gain_db = arv_camera_get_gain(d.camera, &err);
  if (err) return gerror_status(err, "aravis: reading gain");
  r.frame_rate = arv_camera_get_frame_rate(d.camera, &err);
  if (err) return gerror_status(err, "aravis: reading frame rate");
  const char* tm = arv_camera_get_string(d.camera, "TriggerMode", &err);
  if (err) return gerror_status(err, "aravis: reading TriggerMode");
  r.trigger_mode = tm ? tm : "";
  const char* ts = arv_camera_get_string(d.camera, "TriggerSource", &err);
  if (err) return gerror_status(err, "aravis: reading TriggerSource");
  r.trigger_source = ts ? ts : "";
  return r;
}

Result<hw::Frame> AravisCamera::capture(std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  if (d.control_lost.load() || !d.camera) {
    if (!config_.reconnect)
      return Error(Code::unavailable, "aravis camera '" + info_.id + "' disappeared (reconnect is off)");
    PROCAM_LOG(hw, warn) << "aravis: camera " << info_.id << " lost; reconnecting";
    disconnect();
    Status s = connect();
    if (!s) return s.with_context("aravis camera '" + info_.id + "' disappeared; reconnect failed");
    d.reconnects++;
  }
  const int64_t call_ns = clock_ns(CLOCK_MONOTONIC);
  // Stale frames queued before this call belong to earlier patterns: recycle them.
  if (config_.trigger != hw::TriggerMode::hardware) {
    while (ArvBuffer* b = arv_stream_try_pop_buffer(d.stream)) {
      track_id(d, arv_buffer_get_frame_id(b));
      arv_stream_push_buffer(d.stream, b);
    }
  }
  GError* err = nullptr;
  if (config_.trigger == hw::TriggerMode::software) {
    arv_camera_software_trigger(d.camera, &err);
    if (err) {
      d.control_lost = true;
      return gerror_status(err, "aravis: software trigger", Code::unavailable);
    }
  }
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::microseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0 || d.control_lost.load()) break;
    ArvBuffer* b = arv_stream_timeout_pop_buffer(d.stream, static_cast<guint64>(left.count()));
    if (!b) continue;
    const int64_t now_mono = clock_ns(CLOCK_MONOTONIC);
    const int64_t now_real = clock_ns(CLOCK_REALTIME);
    const uint64_t sys_ts = arv_buffer_get_system_timestamp(b);
    const int64_t ts = sys_ts ? now_mono - (now_real - static_cast<int64_t>(sys_ts)) : now_mono;
    const uint64_t raw_id = arv_buffer_get_frame_id(b);
    const uint64_t id = track_id(d, raw_id);
    const ArvBufferStatus st = arv_buffer_get_status(b);
    if (st != ARV_BUFFER_STATUS_SUCCESS) {
      arv_stream_push_buffer(d.stream, b);
      d.corrupt++;
      return Error(Code::corrupt_data, "aravis camera '" + info_.id + "': frame " + std::to_string(raw_id) + " " +
                                           buffer_status_name(st));
    }
    // Software trigger and free-run: the frame must have started after this
    // call; an earlier one (in flight while stale frames were recycled, or
    // an untriggered frame) shows an earlier pattern.
    if (config_.trigger != hw::TriggerMode::hardware && ts < call_ns) {
      arv_stream_push_buffer(d.stream, b);
      d.stale++;
      continue;
    }
    size_t size = 0;
    const auto* src = static_cast<const uint8_t*>(arv_buffer_get_image_data(b, &size));
    uint32_t w = static_cast<uint32_t>(arv_buffer_get_image_width(b));
    uint32_t h = static_cast<uint32_t>(arv_buffer_get_image_height(b));
    if (w == 0 || h == 0) {
      w = d.width;
      h = d.height;
    }
    const uint32_t bpp = bytes_per_pixel(d.pixel_format);
    const size_t need = size_t{w} * h * bpp;
    if (size == 0) size = std::min(need, d.payload);  // custom fake fill reports size 0
    if (src == nullptr || size < need || w != d.width || h != d.height) {
      arv_stream_push_buffer(d.stream, b);
      d.corrupt++;
      return Error(Code::corrupt_data, "aravis camera '" + info_.id + "': frame " + std::to_string(raw_id) + " is " +
                                           std::to_string(w) + "x" + std::to_string(h) + " with " +
                                           std::to_string(size) + " bytes, expected " + std::to_string(d.width) +
                                           "x" + std::to_string(d.height));
    }
    hw::Frame f;
    if (bpp == 2) {
      f.image = Image(w, h, PixelType::u16, 1, info_.bit_depth);
      std::memcpy(f.image.data(), src, need);
    } else if (is_bayer(d.pixel_format)) {
      // Bayer → grey: mean of the 2x2 block at each pixel (R + 2G + B) / 4.
      f.image = Image(w, h, PixelType::u8, 1, 8);
      for (uint32_t y = 0; y < h; ++y) {
        const uint32_t y1 = y + 1 < h ? y + 1 : y - 1;
        uint8_t* out = f.image.row<uint8_t>(y);
        for (uint32_t x = 0; x < w; ++x) {
          const uint32_t x1 = x + 1 < w ? x + 1 : x - 1;
          const unsigned sum = unsigned{src[size_t{y} * w + x]} + src[size_t{y} * w + x1] + src[size_t{y1} * w + x] +
                               src[size_t{y1} * w + x1];
          out[x] = static_cast<uint8_t>((sum + 2) / 4);
        }
      }
    } else {
      f.image = Image(w, h, PixelType::u8, 1, info_.bit_depth);
      std::memcpy(f.image.data(), src, need);
    }
    f.frame_id = id;
    f.timestamp_ns = ts;
    arv_stream_push_buffer(d.stream, b);
    d.frames++;
    return f;
  }
  if (d.control_lost.load())
    return Error(Code::unavailable, "aravis camera '" + info_.id + "' disappeared during capture",
                 "the next capture reconnects");
  d.timeouts++;
  return Error(Code::timeout, "aravis camera '" + info_.id + "': no frame within " + std::to_string(timeout.count()) +
                                  " ms (trigger " + hw::to_string(config_.trigger) + ")");
}

nlohmann::json AravisCamera::stats() const {
  const Impl& d = *impl_;
  guint64 completed = 0, failures = 0, underruns = 0, resent = 0, missing = 0;
  if (d.stream) {
    arv_stream_get_statistics(d.stream, &completed, &failures, &underruns);
    if (ARV_IS_GV_STREAM(d.stream)) arv_gv_stream_get_statistics(ARV_GV_STREAM(d.stream), &resent, &missing);
  }
  return {{"frames", d.frames},
          {"stale_discarded", d.stale},
          {"corrupt", d.corrupt},
          {"timeouts", d.timeouts},
          {"completed_buffers", d.prev_completed + completed},
          {"failures", d.prev_failures + failures},
          {"underruns", d.prev_underruns + underruns},
          {"resent_packets", d.prev_resent + resent},
          {"missing_packets", d.prev_missing + missing},
          {"lost_frames", d.lost_frames},
          {"reconnects", d.reconnects},
          {"fill_failures", d.fill ? d.fill->failures.load() : 0},
          {"pixel_format", d.pixel_format},
          {"trigger", hw::to_string(config_.trigger)}};
}

}  // namespace procam::aravis
