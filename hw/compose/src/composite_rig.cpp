// SPDX-License-Identifier: MIT
// Composite rig: per-device backends, and the sim → Aravis Fake feed bridge.
#include "procam/hw/compose/composite_rig.hpp"

#include <cstring>
#include <mutex>
#include <vector>

#include "procam/core/json_fields.hpp"
#include "procam/hw/sim/sim_rig.hpp"
// Device backends are optional (hw/CMakeLists.txt may leave one out); each
// one compiled in defines PROCAM_HAVE_<NAME> here (hw/compose/CMakeLists.txt).
#if PROCAM_HAVE_ARAVIS
#include "procam/hw/aravis/aravis_camera.hpp"
#endif
#if PROCAM_HAVE_GLFW
#include "procam/hw/glfw/glfw_projector.hpp"
#endif
#if PROCAM_HAVE_LIBCAMERA
#include "procam/hw/libcamera/libcamera_camera.hpp"
#endif
#if PROCAM_HAVE_SCREENCAM
#include "procam/hw/screencam/screen_camera.hpp"
#endif

namespace procam::compose {
namespace {

// Serialises the sim projector (worker thread) against the Aravis stream
// thread that renders the sim camera's view in the Fake device's fill callback.
class LockedProjector final : public hw::Projector {
public:
  LockedProjector(hw::Projector& inner, std::mutex& mu) : inner_(inner), mu_(mu) {}
  const hw::ProjectorInfo& info() const override { return inner_.info(); }
  Status show(const procam_image& pattern, uint64_t pattern_id) override {
    std::lock_guard lock(mu_);
    return inner_.show(pattern, pattern_id);
  }
  Result<hw::Presentation> wait_presented(uint64_t pattern_id, std::chrono::milliseconds timeout) override {
    std::lock_guard lock(mu_);
    return inner_.wait_presented(pattern_id, timeout);
  }
  Status set_focus_mm(double focus_mm) override {
    std::lock_guard lock(mu_);
    return inner_.set_focus_mm(focus_mm);
  }
  Status set_polarizer_deg(double deg) override {
    std::lock_guard lock(mu_);
    return inner_.set_polarizer_deg(deg);
  }

private:
  hw::Projector& inner_;
  std::mutex& mu_;
};

class CompositeRig final : public hw::Rig {
public:
  hw::Projector& projector() override { return *projector_; }
  size_t camera_count() const override { return cameras_.size(); }
  hw::Camera& camera(size_t index) override { return *cameras_[index < cameras_.size() ? index : 0]; }
  const Intrinsics& projector_intrinsics() const override { return projector_intrinsics_; }
  const std::vector<CameraCalibration>& camera_calibrations() const override { return calibrations_; }

  nlohmann::json describe() const override {
    nlohmann::json j;
    try {
      j["name"] = name_;
      if (!description_.empty()) j["description"] = description_;
      nlohmann::json cam_backends = nlohmann::json::array(), cams = nlohmann::json::array();
      for (size_t i = 0; i < cameras_.size(); ++i) {
        const auto& ci = cameras_[i]->info();
        cam_backends.push_back(ci.backend);
        nlohmann::json c = {{"backend", ci.backend}, {"id", ci.id},           {"width", ci.width},
                            {"height", ci.height},   {"bit_depth", ci.bit_depth},
                            {"calibration", calibrations_[i]},
                            {"trigger", hw::to_string(cameras_[i]->trigger_mode())},
                            {"stats", cameras_[i]->stats()}};
        if (!feeds_[i].empty()) c["fed_by"] = feeds_[i];
        cams.push_back(std::move(c));
      }
      const auto& pi = projector_->info();
      j["backends"] = {{"projector", pi.backend}, {"cameras", cam_backends}};
      j["projector"] = {{"backend", pi.backend}, {"name", pi.name},          {"width", pi.width},
                        {"height", pi.height},   {"refresh_hz", pi.refresh_hz},
                        {"intrinsics", projector_intrinsics_}};
      j["cameras"] = cams;
      nlohmann::json state = nlohmann::json::object();
      if (sim_) {
        std::lock_guard lock(mu_);
        auto sd = sim_->describe();
        if (sd.contains("state")) state = sd["state"];
        if (sd.contains("projector")) j["projector"]["sim"] = sd["projector"];
      }
      state["sync"] = sync_settings();
      j["state"] = state;
    } catch (const std::exception& e) {
      j = {{"name", name_}, {"error", std::string("describe failed: ") + e.what()}};
    }
    return j;
  }

  Status check_scan_options(const nlohmann::json& options) const override {
    if (sim_) return sim_->check_scan_options(options);  // reads config only: no lock needed
    if (options.is_null() || (options.is_object() && options.empty())) return Status::Ok();
    if (!options.is_object())
      return Error(Code::invalid_argument, std::string("rig_options must be a JSON object, got ") + options.type_name());
    return Error(Code::invalid_argument, "rig_options: unknown key '" + options.begin().key() + "' for rig '" + name_ + "'",
                 "this hardware rig takes no rig_options");
  }

  nlohmann::json scan_options() const override {
    return sim_ ? sim_->scan_options() : nlohmann::json::object();  // config only, like check_scan_options
  }

  Status apply_scan_options(const nlohmann::json& options) override {
    if (sim_) {
      std::lock_guard lock(mu_);
      return sim_->apply_scan_options(options);
    }
    if (options.is_null() || (options.is_object() && options.empty())) return Status::Ok();
    if (!options.is_object())
      return Error(Code::invalid_argument, std::string("rig_options must be a JSON object, got ") + options.type_name());
    return Error(Code::invalid_argument, "rig_options: unknown key '" + options.begin().key() + "' for rig '" + name_ + "'",
                 "this hardware rig takes no rig_options");
  }

  Result<hw::GroundTruth> ground_truth(size_t index) override {
    if (sim_ && index < feeds_.size() && !feeds_[index].empty()) {
      std::lock_guard lock(mu_);
      return sim_->ground_truth(sim_index_[index]);
    }
    return Error(Code::unavailable, "rig '" + name_ + "' has no ground truth for camera " + std::to_string(index),
                 "ground truth exists only for cameras fed by the simulated rig");
  }

  nlohmann::json sync_settings() const override {
    nlohmann::json s = sync_config_.is_object() ? sync_config_ : nlohmann::json::object();
    for (auto it = sync_state_.begin(); it != sync_state_.end(); ++it) s[it.key()] = it.value();
    return s;
  }
  void set_sync_state(const nlohmann::json& state) override {
    if (state.is_object())
      for (auto it = state.begin(); it != state.end(); ++it) sync_state_[it.key()] = it.value();
  }

  std::string name_, description_;
  nlohmann::json sync_config_ = nlohmann::json::object();
  nlohmann::json sync_state_ = nlohmann::json::object();
  mutable std::mutex mu_;               // sim state vs Aravis stream threads
  std::unique_ptr<sim::SimRig> sim_;    // when the projector is "sim"
  std::unique_ptr<hw::Projector> projector_;
  Intrinsics projector_intrinsics_;
  std::vector<std::unique_ptr<hw::Camera>> cameras_;
  std::vector<CameraCalibration> calibrations_;
  std::vector<std::string> feeds_;      // "" or "sim" per camera
  std::vector<size_t> sim_index_;       // index of the feeding sim camera
};

// Unused in a sim-only build (no device camera backend compiled in).
[[maybe_unused]] Result<CameraCalibration> parse_calibration(const nlohmann::json& cam, const std::string& field) {
  CameraCalibration c;
  try {
    if (!cam.contains("intrinsics") || !cam.contains("cam_from_proj"))
      return Error(Code::invalid_argument, "rig config: " + field + ": needs \"intrinsics\" and \"cam_from_proj\"",
                   "give the camera's calibration (see configs/rigs/sim.json for the format)");
    cam.at("intrinsics").get_to(c.intrinsics);
    cam.at("cam_from_proj").get_to(c.cam_from_proj);
  } catch (const std::exception& e) {
    return Error(Code::invalid_argument, "rig config: " + field + " calibration: " + e.what());
  }
  return c;
}

#if PROCAM_HAVE_ARAVIS
// Copies a rendered sim frame into an Aravis Fake buffer.
Status copy_sim_frame(const hw::Frame& f, uint32_t w, uint32_t h, uint32_t bpp, uint8_t* dst) {
  const Image& im = f.image;
  if (im.width() != w || im.height() != h)
    return Error(Code::invalid_argument, "sim feed renders " + std::to_string(im.width()) + "x" +
                                             std::to_string(im.height()) + " but the Aravis ROI is " +
                                             std::to_string(w) + "x" + std::to_string(h));
  if (bpp == 1 && im.type() == PixelType::u8) {
    std::memcpy(dst, im.data(), size_t{w} * h);
  } else if (bpp == 2 && im.type() == PixelType::u16) {
    std::memcpy(dst, im.data(), size_t{w} * h * 2);
  } else if (bpp == 2 && im.type() == PixelType::u8) {
    auto* out = reinterpret_cast<uint16_t*>(dst);
    for (size_t i = 0; i < size_t{w} * h; ++i) out[i] = static_cast<uint16_t>(im.data()[i] << 8);
  } else {
    return Error(Code::invalid_argument, "sim feed: cannot convert the sim frame to the Aravis pixel format",
                 "use pixel_format Mono16 for a sim bit_depth > 8");
  }
  return Status::Ok();
}

#endif  // PROCAM_HAVE_ARAVIS

// ---- device factories: one per backend, each opens one device into `rig` ----

// Projector "sim": a SimRig holding the projector and the sim cameras that
// feed Aravis Fake devices ("feed" objects of the camera entries).
Status open_sim_projector(CompositeRig& rig, const nlohmann::json& config, const hw::RigContext& ctx) {
  const nlohmann::json& pj = config.at("projector");
  const nlohmann::json& cams = config.at("cameras");
  nlohmann::json sc = nlohmann::json::object();
  for (const char* k : {"name", "description", "comment", "scene", "seed", "threads"})
    if (config.contains(k)) sc[k] = config[k];
  sc["projector"] = pj;
  sc["cameras"] = nlohmann::json::array();
  for (size_t i = 0; i < cams.size(); ++i) {
    const auto& c = cams[i];
    if (!c.contains("feed")) continue;
    nlohmann::json feed = c["feed"];
    const std::string field = "cameras[" + std::to_string(i) + "].feed";
    if (!feed.is_object() || feed.value("backend", "") != "sim")
      return Error(Code::invalid_argument, "rig config: " + field + ": must be {\"backend\": \"sim\", ...sim sensor fields}");
    if (c.contains("intrinsics")) feed["intrinsics"] = c["intrinsics"];
    if (c.contains("cam_from_proj")) feed["cam_from_proj"] = c["cam_from_proj"];
    feed["id"] = "feed" + std::to_string(i);
    sc["cameras"].push_back(feed);
  }
  if (sc["cameras"].empty())
    return Error(Code::invalid_argument, "rig config: projector.backend 'sim' needs a camera fed by the sim",
                 "add \"feed\": {\"backend\": \"sim\"} to a camera, or use a real projector backend");
  auto parsed = sim::parse_sim_rig_config(sc, "rig config (sim feed)");
  if (!parsed) return parsed.status();
  auto sim = sim::SimRig::create(std::move(*parsed), ctx);
  if (!sim) return sim.status();
  rig.sim_ = std::move(*sim);
  rig.projector_ = std::make_unique<LockedProjector>(rig.sim_->projector(), rig.mu_);
  rig.projector_intrinsics_ = rig.sim_->projector_intrinsics();
  return Status::Ok();
}

#if PROCAM_HAVE_GLFW
Status open_glfw_projector(CompositeRig& rig, const nlohmann::json& config, const hw::RigContext&) {
  const nlohmann::json& pj = config.at("projector");
  auto pc = glfw::parse_glfw_projector_config(pj, {"intrinsics"});
  if (!pc) return pc.status();
  if (!pj.contains("intrinsics"))
    return Error(Code::invalid_argument, "rig config: projector.intrinsics: missing",
                 "give the projector's calibrated intrinsics (width, height, fx, fy, cx, cy)");
  pj.at("intrinsics").get_to(rig.projector_intrinsics_);
  if (pc->width == 0) pc->width = rig.projector_intrinsics_.width;
  if (pc->height == 0) pc->height = rig.projector_intrinsics_.height;
  auto p = glfw::GlfwProjector::open(*pc);
  if (!p) return p.status().with_context("rig config: projector");
  rig.projector_ = std::move(*p);
  return Status::Ok();
}
#endif

#if PROCAM_HAVE_ARAVIS
// `sim_i`: index of the next feeding sim camera (a fed camera uses it).
Status open_aravis_camera(CompositeRig& rig, const nlohmann::json& c, const std::string& field, size_t sim_i) {
  const bool fed = c.contains("feed");
  auto cfg = aravis::parse_aravis_camera_config(c, field, {"intrinsics", "cam_from_proj", "feed"});
  if (!cfg) return cfg.status();
  auto cal = parse_calibration(c, field);
  if (!cal) return cal.status();
  aravis::FillFn fill;
  if (fed && !rig.sim_)
    return Error(Code::invalid_argument, "rig config: " + field + ".feed: needs projector.backend 'sim'",
                 "a camera can be fed by the simulated rig only when the projector is simulated too");
  if (fed) {
    if (cfg->device.empty()) cfg->device = "Fake";
    if (cfg->roi_width == 0) {
      cfg->roi_width = static_cast<int32_t>(cal->intrinsics.width);
      cfg->roi_height = static_cast<int32_t>(cal->intrinsics.height);
    }
    hw::Camera* simcam = &rig.sim_->camera(sim_i);
    std::mutex* mu = &rig.mu_;
    fill = [simcam, mu](uint32_t w, uint32_t h, uint32_t bpp, uint8_t* dst) -> Status {
      std::lock_guard lock(*mu);
      auto f = simcam->capture(std::chrono::milliseconds(1000));
      if (!f) return f.status();
      return copy_sim_frame(*f, w, h, bpp, dst);
    };
  }
  auto cam = aravis::AravisCamera::open(*cfg, fill);
  if (!cam) return cam.status().with_context("rig config: " + field);
  if ((*cam)->info().width != cal->intrinsics.width || (*cam)->info().height != cal->intrinsics.height)
    return Error(Code::invalid_argument,
                 "rig config: " + field + ": camera delivers " + std::to_string((*cam)->info().width) + "x" +
                     std::to_string((*cam)->info().height) + " but intrinsics say " +
                     std::to_string(cal->intrinsics.width) + "x" + std::to_string(cal->intrinsics.height),
                 "set roi.width/height or fix the intrinsics");
  rig.cameras_.push_back(std::move(*cam));
  rig.calibrations_.push_back(fed ? rig.sim_->camera_calibrations()[sim_i] : *cal);
  return Status::Ok();
}
#endif

#if PROCAM_HAVE_SCREENCAM
Status open_screen_camera(CompositeRig& rig, const nlohmann::json& c, const std::string& field, size_t) {
  ParseErrors errors{"rig config", {}};
  FieldReader r(c, field, errors);
  r.only({"backend", "id", "display", "region", "intrinsics", "cam_from_proj"},
         "screencam keys: id, display, region {x, y, width, height}, intrinsics, cam_from_proj");
  if (!errors.ok()) return errors.first;
  auto cal = parse_calibration(c, field);
  if (!cal) return cal.status();
  screencam::ScreenCameraConfig sc;
  const auto& pi = rig.projector_->info();
  sc.id = r.string("id", "screen" + std::to_string(rig.cameras_.size()));
  sc.display = r.string("display", pi.display);
  sc.x = pi.screen_x;  // default: exactly what the projector shows
  sc.y = pi.screen_y;
  sc.width = pi.width;
  sc.height = pi.height;
  if (const nlohmann::json* rj = r.object("region", false)) {
    FieldReader region(*rj, r.field("region"), errors);
    region.only({"x", "y", "width", "height"});
    sc.x = static_cast<int32_t>(region.integer("x", 0, 0, 65536));  // root-window pixels
    sc.y = static_cast<int32_t>(region.integer("y", 0, 0, 65536));
    sc.width = static_cast<uint32_t>(region.integer("width", 0, 0, 65536));
    sc.height = static_cast<uint32_t>(region.integer("height", 0, 0, 65536));
  }
  if (!errors.ok()) return errors.first;
  auto cam = screencam::ScreenCamera::open(sc);
  if (!cam) return cam.status().with_context("rig config: " + field);
  rig.cameras_.push_back(std::move(*cam));
  rig.calibrations_.push_back(*cal);
  return Status::Ok();
}
#endif

#if PROCAM_HAVE_LIBCAMERA
Status open_libcamera_camera(CompositeRig& rig, const nlohmann::json& c, const std::string& field, size_t) {
  auto cfg = libcam::parse_libcamera_camera_config(c, field, {"intrinsics", "cam_from_proj"});
  if (!cfg) return cfg.status();
  auto cal = parse_calibration(c, field);
  if (!cal) return cal.status();
  if (cfg->width == 0) cfg->width = cal->intrinsics.width;
  if (cfg->height == 0) cfg->height = cal->intrinsics.height;
  auto cam = libcam::LibcameraCamera::open(*cfg);
  if (!cam) return cam.status().with_context("rig config: " + field);
  rig.cameras_.push_back(std::move(*cam));
  rig.calibrations_.push_back(*cal);
  return Status::Ok();
}
#endif

// ---- the device backend table ----

// Opens the rig's projector from config["projector"]; sets projector_ and
// projector_intrinsics_ (and sim_ for the sim projector).
using ProjectorFactory = Status (*)(CompositeRig& rig, const nlohmann::json& config, const hw::RigContext& ctx);
// Opens camera `c` (rig config entry `field`, e.g. "cameras[1]"); appends to
// cameras_ and calibrations_. `sim_i`: the sim camera that feeds it, if fed.
using CameraFactory = Status (*)(CompositeRig& rig, const nlohmann::json& c, const std::string& field, size_t sim_i);

struct DeviceBackend {
  const char* name;
  BackendKind kind;                   // projector or camera
  ProjectorFactory open_projector;    // kind == projector, else nullptr
  CameraFactory open_camera;          // kind == camera, else nullptr
  const char* summary;
};

// Every device backend compiled into this build, in listing order. Adding a
// device backend = one folder hw/<name>/ and one row here (see hw/README.md).
constexpr DeviceBackend kDeviceBackends[] = {
    {"sim", BackendKind::projector, &open_sim_projector, nullptr,
     "simulated projector; its sim cameras feed Aravis Fake cameras (\"feed\")"},
#if PROCAM_HAVE_GLFW
    {"glfw", BackendKind::projector, &open_glfw_projector, nullptr,
     "borderless fullscreen GLFW window on a monitor (hw/glfw)"},
#endif
#if PROCAM_HAVE_ARAVIS
    {"aravis", BackendKind::camera, nullptr, &open_aravis_camera, "GenICam camera over Aravis 0.8 (hw/aravis)"},
#endif
#if PROCAM_HAVE_SCREENCAM
    {"screencam", BackendKind::camera, nullptr, &open_screen_camera,
     "X screen grab of the projector's monitor (hw/screencam)"},
#endif
#if PROCAM_HAVE_LIBCAMERA
    {"libcamera", BackendKind::camera, nullptr, &open_libcamera_camera, "libcamera camera (hw/libcamera)"},
#endif
};

const DeviceBackend* find_device_backend(const std::string& name, BackendKind kind) {
  for (const DeviceBackend& b : kDeviceBackends)
    if (b.kind == kind && name == b.name) return &b;
  return nullptr;
}

}  // namespace

std::vector<BackendEntry> device_backends() {
  std::vector<BackendEntry> out;
  for (const DeviceBackend& b : kDeviceBackends) out.push_back({b.name, b.kind, b.summary});
  return out;
}

std::string backend_names(BackendKind kind) {
  std::string s;
  for (const DeviceBackend& b : kDeviceBackends)
    if (b.kind == kind) s += (s.empty() ? "" : ", ") + std::string(b.name);
  return s;
}

bool is_projector_backend(const std::string& name) {
  return find_device_backend(name, BackendKind::projector) != nullptr;
}
bool is_camera_backend(const std::string& name) { return find_device_backend(name, BackendKind::camera) != nullptr; }

Result<std::unique_ptr<hw::Rig>> create_composite_rig(const nlohmann::json& config, const hw::RigContext& ctx) {
  auto rig = std::make_unique<CompositeRig>();
  try {
    rig->name_ = config.value("name", std::string("hardware"));
    rig->description_ = config.value("description", std::string());
    if (config.contains("sync")) {
      if (!config["sync"].is_object())
        return Error(Code::invalid_argument, "rig config: sync: must be an object");
      rig->sync_config_ = config["sync"];
    }
    const nlohmann::json& pj = config.at("projector");
    const std::string pbackend = pj.value("backend", "");
    const nlohmann::json& cams = config.at("cameras");

    // --- projector (and, for "sim", the sim rig behind it)
    const DeviceBackend* pb = find_device_backend(pbackend, BackendKind::projector);
    if (pb == nullptr)
      return Error(Code::invalid_argument, "rig config: projector.backend: '" + pbackend + "' is not built into this composite rig",
                   "projector backends: " + backend_names(BackendKind::projector));
    if (Status st = pb->open_projector(*rig, config, ctx); !st) return st;

    // --- cameras
    size_t sim_i = 0;
    for (size_t i = 0; i < cams.size(); ++i) {
      const auto& c = cams[i];
      const std::string field = "cameras[" + std::to_string(i) + "]";
      const std::string cb = c.value("backend", "");
      const bool fed = c.contains("feed");
      const DeviceBackend* b = find_device_backend(cb, BackendKind::camera);
      if (b == nullptr)
        return Error(Code::invalid_argument, "rig config: " + field + ".backend: '" + cb + "' is not a camera backend here",
                     "camera backends: " + backend_names(BackendKind::camera));
      if (Status st = b->open_camera(*rig, c, field, sim_i); !st) return st;
      rig->feeds_.push_back(fed ? "sim" : "");
      rig->sim_index_.push_back(fed ? sim_i : 0);
      if (fed) ++sim_i;
    }
  } catch (const std::exception& e) {
    return Error(Code::invalid_argument, std::string("rig config: ") + e.what());
  }
  return std::unique_ptr<hw::Rig>(std::move(rig));
}

}  // namespace procam::compose
