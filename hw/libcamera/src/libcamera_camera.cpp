// SPDX-License-Identifier: MIT
// libcamera camera: manager, configuration, buffers, request-based capture.
#include "procam/hw/libcamera/libcamera_camera.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <ctime>
#include <mutex>
#include <set>

#include <libcamera/libcamera.h>

#include "procam/base/clock.hpp"
#include "procam/core/json_fields.hpp"

namespace procam::libcam {
namespace {

std::string errno_text(int ret) { return std::string(std::strerror(-ret)) + " (" + std::to_string(ret) + ")"; }

const char* kNoCameraHint =
    "libcamera lists no camera: connect a supported camera (the user needs access to /dev/video* and /dev/media*), "
    "or use another camera backend; `cam -l` (libcamera-tools) lists what libcamera sees";

}  // namespace

Result<LibcameraCameraConfig> parse_libcamera_camera_config(const nlohmann::json& j, const std::string& field,
                                                            const std::vector<std::string>& extra_keys) {
  LibcameraCameraConfig c;
  ParseErrors errors{"rig config", {}};
  FieldReader r(j, field, errors);
  std::vector<std::string> known = {"backend", "camera", "id", "width", "height", "pixel_format",
                                    "exposure_us", "gain", "buffers"};
  known.insert(known.end(), extra_keys.begin(), extra_keys.end());
  r.only(known, "libcamera camera keys: camera (id or index), id, width, height, pixel_format (R8|R16|YUV420), "
                "exposure_us, gain, buffers");
  c.camera = r.name_or_index("camera", "");
  c.id = r.string("id", std::string());
  c.width = static_cast<uint32_t>(r.integer("width", 0, 0, 65536));
  c.height = static_cast<uint32_t>(r.integer("height", 0, 0, 65536));
  c.pixel_format = r.string("pixel_format", std::string("R8"));
  if (errors.ok() && c.pixel_format != "R8" && c.pixel_format != "R16" && c.pixel_format != "YUV420")
    r.fail("pixel_format", "unsupported '" + c.pixel_format + "'", "one of: R8, R16, YUV420");
  c.exposure_us = r.number("exposure_us", 0.0, "µs; <= 0: auto/default");
  c.gain = r.number("gain", 0.0, "analogue gain factor; <= 0: default");
  c.buffers = static_cast<int>(r.integer("buffers", 4, 1, 64));
  if (!errors.ok()) return errors.first;
  return c;
}

Result<nlohmann::json> list_libcamera_cameras() {
  auto cm = std::make_unique<libcamera::CameraManager>();
  const int ret = cm->start();
  if (ret) return Error(Code::unavailable, "libcamera: CameraManager::start failed: " + errno_text(ret));
  nlohmann::json out = nlohmann::json::array();
  int i = 0;
  for (const auto& cam : cm->cameras()) out.push_back({{"index", i++}, {"id", cam->id()}});
  cm->stop();
  return out;
}

struct LibcameraCamera::Impl {
  LibcameraCameraConfig config;
  std::unique_ptr<libcamera::CameraManager> cm;
  std::shared_ptr<libcamera::Camera> camera;
  std::unique_ptr<libcamera::CameraConfiguration> cfg;
  std::unique_ptr<libcamera::FrameBufferAllocator> alloc;
  libcamera::Stream* stream = nullptr;
  std::vector<std::unique_ptr<libcamera::Request>> requests;
  size_t next_request = 0;
  bool acquired = false, started = false;
  uint32_t width = 0, height = 0, stride = 0;
  bool sixteen = false;
  // completion handover
  std::mutex mu;
  std::condition_variable cv;
  libcamera::Request* done = nullptr;
  uint64_t frames = 0, failed = 0, timeouts = 0;
  uint64_t last_sequence = 0;
  bool have_sequence = false;
  uint64_t lost = 0;

  void on_complete(libcamera::Request* r) {
    std::lock_guard lock(mu);
    done = r;
    cv.notify_all();
  }
  void close() {
    if (camera) {
      if (started) camera->stop();
      started = false;
      camera->requestCompleted.disconnect(this);
      requests.clear();
      alloc.reset();
      if (acquired) camera->release();
      acquired = false;
      camera.reset();
    }
    if (cm) {
      cm->stop();
      cm.reset();
    }
  }
};

Result<std::unique_ptr<LibcameraCamera>> LibcameraCamera::open(const LibcameraCameraConfig& config) {
  std::unique_ptr<LibcameraCamera> c(new LibcameraCamera());
  c->impl_ = std::make_unique<Impl>();
  Impl& d = *c->impl_;
  d.config = config;
  d.cm = std::make_unique<libcamera::CameraManager>();
  int ret = d.cm->start();
  if (ret) return Error(Code::unavailable, "libcamera: CameraManager::start failed: " + errno_text(ret));
  const auto cams = d.cm->cameras();
  if (cams.empty())
    return Error(Code::not_found,
                 "no libcamera camera: libcamera " + d.cm->version() + " enumerated 0 cameras" +
                     (config.camera.empty() ? std::string() : " (asked for '" + config.camera + "')"),
                 kNoCameraHint);
  if (config.camera.empty()) {
    d.camera = cams.front();
  } else {
    d.camera = d.cm->get(config.camera);
    if (!d.camera && std::all_of(config.camera.begin(), config.camera.end(), ::isdigit)) {
      const size_t i = std::stoul(config.camera);
      if (i < cams.size()) d.camera = cams[i];
    }
    if (!d.camera) {
      std::string seen;
      for (size_t i = 0; i < cams.size(); ++i) seen += (i ? ", " : "") + std::to_string(i) + ": " + cams[i]->id();
      return Error(Code::not_found, "no libcamera camera '" + config.camera + "'", "cameras: " + seen);
    }
  }
  ret = d.camera->acquire();
  if (ret) return Error(Code::unavailable, "libcamera: camera '" + d.camera->id() + "' is busy: " + errno_text(ret));
  d.acquired = true;
  d.cfg = d.camera->generateConfiguration({libcamera::StreamRole::Raw});
  if (!d.cfg || d.cfg->empty()) d.cfg = d.camera->generateConfiguration({libcamera::StreamRole::Viewfinder});
  if (!d.cfg || d.cfg->empty()) return Error(Code::unavailable, "libcamera: camera '" + d.camera->id() + "' offers no stream");
  libcamera::StreamConfiguration& sc = d.cfg->at(0);
  if (config.width) sc.size.width = config.width;
  if (config.height) sc.size.height = config.height;
  sc.pixelFormat = config.pixel_format == "R8"    ? libcamera::formats::R8
                   : config.pixel_format == "R16" ? libcamera::PixelFormat::fromString("R16")
                                                  : libcamera::formats::YUV420;
  sc.bufferCount = static_cast<unsigned>(std::max(2, config.buffers));
  if (d.cfg->validate() == libcamera::CameraConfiguration::Invalid)
    return Error(Code::invalid_argument, "libcamera: configuration " + sc.toString() + " is invalid for '" + d.camera->id() + "'");
  ret = d.camera->configure(d.cfg.get());
  if (ret) return Error(Code::invalid_argument, "libcamera: configure " + sc.toString() + " failed: " + errno_text(ret));
  d.stream = sc.stream();
  d.width = sc.size.width;
  d.height = sc.size.height;
  d.stride = sc.stride;
  d.sixteen = config.pixel_format == "R16";
  d.alloc = std::make_unique<libcamera::FrameBufferAllocator>(d.camera);
  if (d.alloc->allocate(d.stream) < 0) return Error(Code::unavailable, "libcamera: cannot allocate buffers");
  for (const auto& buf : d.alloc->buffers(d.stream)) {
    auto req = d.camera->createRequest();
    if (!req) return Error(Code::unavailable, "libcamera: cannot create a request");
    if (req->addBuffer(d.stream, buf.get()) < 0) return Error(Code::unavailable, "libcamera: cannot add a buffer to a request");
    d.requests.push_back(std::move(req));
  }
  d.camera->requestCompleted.connect(&d, &Impl::on_complete);
  libcamera::ControlList controls;
  if (config.exposure_us > 0) controls.set(libcamera::controls::ExposureTime, static_cast<int32_t>(config.exposure_us));
  if (config.gain > 0) controls.set(libcamera::controls::AnalogueGain, static_cast<float>(config.gain));
  ret = d.camera->start(&controls);
  if (ret) return Error(Code::unavailable, "libcamera: start failed: " + errno_text(ret));
  d.started = true;
  c->info_.backend = "libcamera";
  c->info_.id = config.id.empty() ? d.camera->id() : config.id;
  c->info_.width = d.width;
  c->info_.height = d.height;
  c->info_.bit_depth = d.sixteen ? 16 : 8;
  return c;
}

LibcameraCamera::~LibcameraCamera() {
  if (impl_) impl_->close();
}

Status LibcameraCamera::configure(const hw::CameraSettings& settings) {
  if (!std::isnan(settings.polarizer_deg)) return Error(Code::failed_precondition, "libcamera camera: no polarizer");
  if (settings.exposure_us > 0) impl_->config.exposure_us = settings.exposure_us;
  if (settings.gain_db >= 0) impl_->config.gain = std::pow(10.0, settings.gain_db / 20.0);
  return Status::Ok();
}

Result<hw::Frame> LibcameraCamera::capture(std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  libcamera::Request* req = d.requests[d.next_request].get();
  d.next_request = (d.next_request + 1) % d.requests.size();
  req->reuse(libcamera::Request::ReuseBuffers);
  if (d.config.exposure_us > 0) req->controls().set(libcamera::controls::ExposureTime, static_cast<int32_t>(d.config.exposure_us));
  if (d.config.gain > 0) req->controls().set(libcamera::controls::AnalogueGain, static_cast<float>(d.config.gain));
  {
    std::lock_guard lock(d.mu);
    d.done = nullptr;
  }
  const int ret = d.camera->queueRequest(req);
  if (ret < 0) return Error(Code::unavailable, "libcamera: queueRequest failed: " + errno_text(ret));
  std::unique_lock lock(d.mu);
  if (!d.cv.wait_for(lock, timeout, [&] { return d.done == req; })) {
    d.timeouts++;
    return Error(Code::timeout, "libcamera camera '" + info_.id + "': no frame within " + std::to_string(timeout.count()) + " ms");
  }
  lock.unlock();
  if (req->status() != libcamera::Request::RequestComplete) {
    d.failed++;
    return Error(Code::corrupt_data, "libcamera camera '" + info_.id + "': request cancelled");
  }
  libcamera::FrameBuffer* fb = req->buffers().at(d.stream);
  const libcamera::FrameMetadata& md = fb->metadata();
  if (md.status != libcamera::FrameMetadata::FrameSuccess) {
    d.failed++;
    return Error(Code::corrupt_data, "libcamera camera '" + info_.id + "': frame " + std::to_string(md.sequence) + " failed");
  }
  const auto& plane = fb->planes().at(0);
  const size_t map_len = plane.offset + plane.length;
  void* mem = mmap(nullptr, map_len, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
  if (mem == MAP_FAILED) return Error(Code::io_error, "libcamera: cannot map the frame buffer");
  const auto* src = static_cast<const uint8_t*>(mem) + plane.offset;
  hw::Frame f;
  const uint32_t bpp = d.sixteen ? 2 : 1;
  f.image = Image(d.width, d.height, d.sixteen ? PixelType::u16 : PixelType::u8, 1, info_.bit_depth);
  const size_t stride = d.stride ? d.stride : d.width * bpp;
  for (uint32_t y = 0; y < d.height; ++y)
    std::memcpy(f.image.data() + size_t{y} * d.width * bpp, src + y * stride, size_t{d.width} * bpp);
  munmap(mem, map_len);
  if (d.have_sequence && md.sequence > d.last_sequence + 1) d.lost += md.sequence - d.last_sequence - 1;
  d.last_sequence = md.sequence;
  d.have_sequence = true;
  f.frame_id = md.sequence + 1;  // libcamera sequences start at 0
  f.timestamp_ns = md.timestamp ? static_cast<int64_t>(md.timestamp) : mono_ns();  // sensor stamp, CLOCK_BOOTTIME-like
  d.frames++;
  return f;
}

nlohmann::json LibcameraCamera::stats() const {
  return {{"frames", impl_->frames}, {"failed", impl_->failed}, {"timeouts", impl_->timeouts}, {"lost_frames", impl_->lost}};
}

}  // namespace procam::libcam
