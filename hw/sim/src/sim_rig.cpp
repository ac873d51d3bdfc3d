// SPDX-License-Identifier: MIT
// Sim backend: rig config parsing and the Projector / Camera / Rig adapters.
#include "procam/hw/sim/sim_rig.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "parallel.hpp"
#include "procam/base/clock.hpp"
#include "procam/core/json_fields.hpp"
#include "procam/core/log.hpp"
#include "procam/hw/sim/global.hpp"
#include "procam/hw/sim/ground_truth.hpp"
#include "procam/hw/sim/sensor.hpp"

namespace procam::sim {
namespace fs = std::filesystem;

namespace {

Intrinsics parse_intrinsics(FieldReader& parent, const char* key) {
  Intrinsics k;
  const nlohmann::json* j = parent.object(key, true);
  if (j == nullptr) return k;
  FieldReader r(*j, parent.field(key), parent.errors());
  r.only({"width", "height", "fx", "fy", "cx", "cy", "distortion"});
  k.width = static_cast<uint32_t>(r.integer("width", std::nullopt, 1, 65536));
  k.height = static_cast<uint32_t>(r.integer("height", std::nullopt, 1, 65536));
  k.fx = r.positive("fx", std::nullopt, "focal length, pixels");
  k.fy = r.positive("fy", std::nullopt, "focal length, pixels");
  k.cx = r.number("cx", std::nullopt, "principal point, pixels");
  k.cy = r.number("cy", std::nullopt, "principal point, pixels");
  // Lens distortion, OpenCV's [k1, k2, p1, p2, k3] (procam/base/calibration.hpp):
  // the renderer casts camera rays through Intrinsics::ray() and finds a
  // point's projector pixel with Intrinsics::project(), both distortion-aware.
  if (r.has("distortion")) {
    const auto d = r.numbers<5>("distortion", std::nullopt, "[k1, k2, p1, p2, k3]");
    for (size_t i = 0; i < 5 && r.errors().ok(); ++i)
      if (!(std::abs(d[i]) <= 10.0)) r.fail("distortion", "coefficients must be finite and within [-10, 10]");
    if (r.errors().ok()) k.distortion = d;
  }
  return k;
}

Rigid3 parse_rigid(FieldReader& parent, const char* key) {
  Rigid3 t;
  const nlohmann::json* j = parent.object(key, true);
  if (j == nullptr) return t;
  FieldReader r(*j, parent.field(key), parent.errors());
  r.only({"rotation", "euler_deg", "translation_mm"});
  if (r.has("rotation") && r.has("euler_deg")) {
    r.fail("rotation", "give either rotation or euler_deg, not both");
    return t;
  }
  if (r.has("rotation")) {
    t.rotation.m = r.numbers<9>("rotation", std::nullopt, "row-major 3x3");
    const Mat3 rtr = t.rotation.transposed() * t.rotation;
    double err = 0;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) err = std::max(err, std::abs(rtr(a, b) - (a == b ? 1.0 : 0.0)));
    const Mat3& m = t.rotation;
    const double det = m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1)) -
                       m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0)) +
                       m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0));
    if (r.errors().ok() && (err > 1e-6 || det < 0))
      r.fail("rotation", "must be a proper rotation matrix (orthonormal, det +1)");
  } else {
    const Vec3 e = r.vec3("euler_deg", Vec3{0, 0, 0}, "[rx, ry, rz] degrees, R = Rz*Ry*Rx");
    t.rotation = rotation_from_euler_deg(e.x, e.y, e.z);
  }
  t.translation_mm = r.vec3("translation_mm", std::nullopt, "mm");
  return t;
}

void check_backend(FieldReader& r) {
  const std::string b = r.string("backend", std::string("sim"));
  if (r.errors().ok() && b != "sim")
    r.fail("backend", "the sim rig needs backend \"sim\", got \"" + b + "\"");
}

}  // namespace

FaultConfig parse_faults(FieldReader& parent, bool camera) {
  FaultConfig f;
  const nlohmann::json* j = parent.object("faults", false);
  if (j == nullptr) return f;
  FieldReader r(*j, parent.field("faults"), parent.errors());
  if (camera) r.only({"drop_every", "late_every", "late_ms", "timeout_every", "seed"});
  else r.only({"drop_every", "late_every", "late_ms", "seed"});
  f.drop_every = r.integer("drop_every", 0, 0, UINT64_MAX);
  f.late_every = r.integer("late_every", 0, 0, UINT64_MAX);
  f.late_ms = r.number("late_ms", 0.0, "ms", 0.0, 1e6);
  if (camera) f.timeout_every = r.integer("timeout_every", 0, 0, UINT64_MAX);
  f.seed = r.integer("seed", 0, 0, UINT64_MAX);
  if (r.errors().ok() && f.late_every > 0 && !(f.late_ms > 0))
    r.fail("late_ms", "must be > 0 when late_every is set");
  return f;
}

// Whether event number `k` (1-based) faults for period `every` (see FaultConfig).
bool fault_fires(uint64_t every, uint64_t seed, uint64_t k, uint64_t& rng_state) {
  if (every == 0) return false;
  if (seed == 0) return k % every == 0;
  if (rng_state == 0) rng_state = seed * 0x9E3779B97F4A7C15ull + 1;
  // xorshift64*
  rng_state ^= rng_state >> 12;
  rng_state ^= rng_state << 25;
  rng_state ^= rng_state >> 27;
  return (rng_state * 0x2545F4914F6CDD1Dull) % every == 0;
}

nlohmann::json counters_json(const FaultCounters& c, bool camera) {
  nlohmann::json j = {{camera ? "captures" : "shows", c.events}, {"dropped", c.dropped}, {"late", c.late}};
  if (camera) j["timeouts"] = c.timeouts;
  return j;
}

Result<SimRigConfig> parse_sim_rig_config(const nlohmann::json& config, const std::string& source) {
  try {
    ParseErrors errors{source, {}};
    FieldReader root(config, "", errors);
    // calibration_tables: rig-level, read by the daemon (copied into the rig
    // description for plugins); the sim itself does not use them.
    root.only({"name", "description", "comment", "scene", "seed", "threads", "projector", "cameras",
               "calibration_tables"});
    SimRigConfig c;
    c.name = root.string("name", std::string("sim"));
    c.description = root.string("description", std::string());
    c.scene = root.string("scene", std::string("plane"));
    c.seed = root.integer("seed", 1, 0, UINT64_MAX);
    c.threads = static_cast<int>(root.integer("threads", 0, 0, 64));

    if (const nlohmann::json* pj = root.object("projector", true)) {
      FieldReader p(*pj, "projector", errors);
      p.only({"backend", "name", "intrinsics", "refresh_hz", "irradiance_at_1m", "black_level", "gamma",
              "aperture_mm", "focus_mm", "faults"});
      check_backend(p);
      ProjectorModel& m = c.projector;
      m.name = p.string("name", std::string("sim projector"));
      m.intrinsics = parse_intrinsics(p, "intrinsics");
      m.refresh_hz = p.positive("refresh_hz", 60.0, "Hz");
      m.irradiance_at_1m = p.positive("irradiance_at_1m", 1.0, "iu");
      m.black_level = p.number("black_level", 0.01, "fraction", 0.0, 0.999);
      m.gamma = p.positive("gamma", 2.2);
      m.aperture_mm = p.number("aperture_mm", 2.0, "mm", 0.0, 1000.0);
      m.focus_mm = p.positive("focus_mm", 800.0, "mm");
      c.projector_faults = parse_faults(p, false);
    }

    const nlohmann::json* cams = root.get("cameras");
    if (cams == nullptr) {
      root.fail("cameras", "missing (required array of camera objects)");
    } else if (!cams->is_array() || cams->empty()) {
      root.fail("cameras", "must be a non-empty array of camera objects");
    } else {
      for (size_t i = 0; i < cams->size() && errors.ok(); ++i) {
        FieldReader r((*cams)[i], "cameras[" + std::to_string(i) + "]", errors);
        r.only({"backend", "id", "intrinsics", "cam_from_proj", "bit_depth", "exposure_us", "gain_db",
                "sensitivity", "full_well_e", "read_noise_e", "shot_noise", "lens", "faults", "light"});
        check_backend(r);
        SimCameraConfig cam;
        cam.id = r.string("id", "sim" + std::to_string(i));
        cam.calibration.intrinsics = parse_intrinsics(r, "intrinsics");
        cam.calibration.cam_from_proj = parse_rigid(r, "cam_from_proj");
        SensorModel& s = cam.sensor;
        s.bit_depth = static_cast<uint32_t>(r.integer("bit_depth", 8, 8, 16));
        s.exposure_us = r.number("exposure_us", 10000.0, "µs", 1e-3, 1e7);
        s.gain_db = r.number("gain_db", 0.0, "dB", 0.0, 48.0);
        s.sensitivity = r.positive("sensitivity", 2.0, "electrons per (ru · µs)");
        s.full_well_e = r.positive("full_well_e", 10000.0, "electrons");
        s.read_noise_e = r.number("read_noise_e", 10.0, "electrons RMS", 0.0, 1e6);
        s.shot_noise = r.boolean("shot_noise", true);
        if (const nlohmann::json* lj = r.object("lens", false)) {
          FieldReader l(*lj, r.field("lens"), r.errors());
          l.only({"aperture_mm", "focus_mm"});
          cam.lens.aperture_mm = l.number("aperture_mm", 0.0, "mm", 0.0, 1000.0);
          cam.lens.focus_mm = l.positive("focus_mm", 800.0, "mm");
        }
        cam.faults = parse_faults(r, true);
        if (const nlohmann::json* lj = r.object("light", false)) {
          FieldReader l(*lj, r.field("light"), r.errors());
          l.only({"name", "cam_from_light", "field", "irradiance_at_1m", "comment"});
          SimLightConfig light;
          light.name = l.string("name", cam.id + " light");
          if (l.has("cam_from_light")) light.cam_from_light = parse_rigid(l, "cam_from_light");
          light.model.name = light.name;
          light.model.intrinsics = l.has("field") ? parse_intrinsics(l, "field") : hw::default_light_field();
          light.model.irradiance_at_1m = l.positive("irradiance_at_1m", 1.0, "iu");
          light.model.black_level = 0;  // the light is on or off: no pattern, no black level
          light.model.gamma = 1;
          light.model.aperture_mm = 0;  // a flood: no defocus
          cam.light = std::move(light);
        }
        c.cameras.push_back(std::move(cam));
      }
    }
    if (!errors.ok()) return errors.first;
    return c;
  } catch (const std::exception& e) {
    return Error(Code::internal, source + ": unexpected error while parsing: " + e.what());
  }
}

// ---- SimProjector -------------------------------------------------------------

Status SimProjector::show(const procam_image& pattern, uint64_t pattern_id) {
  // Prepared into the spare buffer (storage reused frame to frame), swapped
  // in unless the display drops it.
  if (Status st = rig_.spare_pattern_.assign(pattern, rig_.config_.projector, rig_.config_.threads); !st.ok())
    return st.with_context("sim projector: show");
  const FaultConfig& fc = rig_.config_.projector_faults;
  const uint64_t k = ++rig_.projector_faults_.events;
  if (fault_fires(fc.drop_every, fc.seed, k, rig_.projector_fault_rng_)) {
    // Dropped by the display: the screen keeps the previous pattern.
    ++rig_.projector_faults_.dropped;
    rig_.pattern_id_ = pattern_id;
    rig_.pattern_shown_ = true;
    rig_.pattern_dropped_ = true;
    return Status::Ok();
  }
  std::swap(rig_.pattern_, rig_.spare_pattern_);
  rig_.pattern_id_ = pattern_id;
  rig_.pattern_shown_ = true;
  rig_.pattern_dropped_ = false;
  rig_.pattern_late_ = fault_fires(fc.late_every, fc.seed, k, rig_.projector_fault_rng_);
  if (rig_.pattern_late_) ++rig_.projector_faults_.late;
  return Status::Ok();
}

Result<hw::Presentation> SimProjector::wait_presented(uint64_t pattern_id, std::chrono::milliseconds) {
  if (!rig_.pattern_shown_ || pattern_id != rig_.pattern_id_)
    return Error(Code::failed_precondition,
                 "sim projector: pattern " + std::to_string(pattern_id) + " was not shown" +
                     (rig_.pattern_shown_ ? " (last shown: " + std::to_string(rig_.pattern_id_) + ")" : ""),
                 "call show() with this id first");
  if (rig_.pattern_dropped_)
    return Error(Code::timeout, "sim projector: pattern " + std::to_string(pattern_id) +
                                    " was dropped by the display (fault injection: projector.faults.drop_every)",
                 "show the pattern again");
  const auto late_ns = rig_.pattern_late_ ? static_cast<int64_t>(rig_.config_.projector_faults.late_ms * 1e6) : 0;
  return hw::Presentation{pattern_id, mono_ns() + late_ns};
}

Status SimProjector::set_focus_mm(double focus_mm) {
  if (std::isinf(focus_mm))
    return Error(Code::invalid_argument, "sim projector: focus_mm must be finite",
                 "give the focal-plane distance in mm, or <= 0 for the rig default");
  rig_.focus_mm_ = (std::isnan(focus_mm) || focus_mm <= 0) ? 0.0 : focus_mm;
  return Status::Ok();
}

Status SimProjector::set_polarizer_deg(double deg) {
  if (std::isinf(deg))
    return Error(Code::invalid_argument, "sim projector: projector_polarizer_deg must be finite or NaN (none)");
  // Recorded only: the renderer does not model polarisation yet, so the
  // radiance does not depend on this angle (a later issue adds the model).
  polarizer_deg_ = deg;
  return Status::Ok();
}

// ---- SimCamera ------------------------------------------------------------------

Status SimCamera::configure(const hw::CameraSettings& settings) {
  const SensorModel& s = rig_.config_.cameras[index_].sensor;
  if (settings.exposure_us > 1e7 || std::isnan(settings.exposure_us))
    return Error(Code::invalid_argument,
                 "sim camera " + info_.id + ": exposure_us " + std::to_string(settings.exposure_us) +
                     " out of range", "use 0 < exposure_us <= 1e7 (or <= 0 for the default)");
  if (settings.gain_db > 48 || std::isnan(settings.gain_db))
    return Error(Code::invalid_argument,
                 "sim camera " + info_.id + ": gain_db " + std::to_string(settings.gain_db) + " out of range",
                 "use 0 <= gain_db <= 48 (or < 0 for the default)");
  exposure_us_ = settings.exposure_us > 0 ? settings.exposure_us : s.exposure_us;
  gain_db_ = settings.gain_db >= 0 ? settings.gain_db : s.gain_db;
  polarizer_deg_ = settings.polarizer_deg;  // analyser for the next captures (NaN: none)
  return Status::Ok();
}

Result<hw::Frame> SimCamera::capture(std::chrono::milliseconds timeout) {
  const FaultConfig& fc = rig_.config_.cameras[index_].faults;
  const uint64_t k = ++faults_.events;
  if (fault_fires(fc.timeout_every, fc.seed, k, fault_rng_)) {
    ++faults_.timeouts;
    return Error(Code::timeout, "sim camera " + info_.id + ": no frame within " + std::to_string(timeout.count()) +
                                    " ms (fault injection: faults.timeout_every)");
  }
  if (fault_fires(fc.drop_every, fc.seed, k, fault_rng_)) {
    ++faults_.dropped;
    ++next_frame_id_;  // that frame was lost: the delivered one carries the next id
  }
  const bool late = fault_fires(fc.late_every, fc.seed, k, fault_rng_);
  if (late) ++faults_.late;
  // The projector's pattern, or the selected light alone (select_light).
  const size_t light = rig_.light_;
  Renderer* renp = rig_.renderers_[index_].get();
  if (light > 0) {
    auto lr = rig_.light_renderer(index_, light);
    if (!lr.ok()) return lr.status().with_context("sim camera " + info_.id + ": capture");
    renp = *lr;
  }
  Renderer& ren = *renp;
  if (light == 0) ren.set_focus_mm(rig_.current_focus_mm());
  ren.set_polarization(rig_.projector_.polarizer_deg(), polarizer_deg_);
  // A dynamic medium is rendered at this frame's time: frame id x period.
  if (rig_.scene_.legendre_medium)
    set_legendre_time(ren, static_cast<double>(next_frame_id_) * rig_.scene_.legendre_medium->frame_period_s);
  radiance_.resize(ren.view().pixel_count());
  Status st = ren.render_radiance(light > 0 ? rig_.light_patterns_[light - 1] : rig_.pattern_, radiance_.data(), true);
  if (!st.ok()) return st.with_context("sim camera " + info_.id + ": capture");
  const SensorModel& s = rig_.config_.cameras[index_].sensor;
  hw::Frame f;
  f.frame_id = next_frame_id_++;
  f.image = expose(radiance_.data(), ren.width(), ren.height(), s, exposure_us_, gain_db_,
                   frame_noise_seed(rig_.config_.seed, index_, f.frame_id), rig_.config_.threads);
  f.timestamp_ns = mono_ns() + (late ? static_cast<int64_t>(fc.late_ms * 1e6) : 0);
  f.camera_index = index_;
  return f;
}

// ---- SimRig -------------------------------------------------------------------

SimRig::SimRig(SimRigConfig config, hw::RigContext ctx)
    : config_(std::move(config)), ctx_(std::move(ctx)), projector_(*this) {
  if (config_.threads <= 0) config_.threads = detail::default_threads();
  scene_dirs_ = ctx_.scene_dirs;
  if (scene_dirs_.empty())
    scene_dirs_.push_back((fs::path(ctx_.config_dir.empty() ? "." : ctx_.config_dir) / ".." / "scenes").string());
  projector_.info_.backend = "sim";
  projector_.info_.name = config_.projector.name;
  projector_.info_.width = config_.projector.intrinsics.width;
  projector_.info_.height = config_.projector.intrinsics.height;
  projector_.info_.refresh_hz = config_.projector.refresh_hz;
  for (size_t i = 0; i < config_.cameras.size(); ++i) {
    const SimCameraConfig& cc = config_.cameras[i];
    calibrations_.push_back(cc.calibration);
    auto cam = std::make_unique<SimCamera>(*this, static_cast<uint32_t>(i));
    cam->info_.backend = "sim";
    cam->info_.id = cc.id;
    cam->info_.width = cc.calibration.intrinsics.width;
    cam->info_.height = cc.calibration.intrinsics.height;
    cam->info_.bit_depth = cc.sensor.bit_depth;
    cam->exposure_us_ = cc.sensor.exposure_us;
    cam->gain_db_ = cc.sensor.gain_db;
    cam->polarizer_deg_ = std::nan("");
    cameras_.push_back(std::move(cam));
    if (cc.light) light_camera_.push_back(i);
  }
}

Result<std::unique_ptr<SimRig>> SimRig::create(SimRigConfig config, hw::RigContext ctx) {
  try {
    if (config.cameras.empty()) return Error(Code::invalid_argument, "sim rig: no cameras configured");
    std::unique_ptr<SimRig> rig(new SimRig(std::move(config), std::move(ctx)));
    // The projector starts out showing black (pattern value 0 everywhere).
    Image black(rig->config_.projector.intrinsics.width, rig->config_.projector.intrinsics.height, PixelType::u8);
    auto p = PreparedPattern::from_pattern(black.view(), rig->config_.projector);
    if (!p.ok()) return p.status();
    rig->pattern_ = std::move(p).value();
    for (size_t c : rig->light_camera_) {
      const Intrinsics& f = rig->config_.cameras[c].light->model.intrinsics;
      Image ones(f.width, f.height, PixelType::f32);
      std::fill(ones.ptr<float>(), ones.ptr<float>() + size_t{f.width} * f.height, 1.0f);
      auto lp = PreparedPattern::from_emitted(ones);
      if (!lp.ok()) return lp.status().with_context("sim rig: light of camera " + std::to_string(c));
      rig->light_patterns_.push_back(std::move(lp).value());
    }
    Status st = rig->set_scene(rig->config_.scene);
    if (!st.ok()) return st.with_context("sim rig: loading default scene (rig config field \"scene\")");
    return rig;
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("sim rig: unexpected error: ") + e.what());
  }
}

hw::Camera& SimRig::camera(size_t index) {
  assert(index < cameras_.size());
  return *cameras_[std::min(index, cameras_.size() - 1)];
}

double SimRig::current_focus_mm() const {
  return focus_mm_ > 0 ? focus_mm_ : config_.projector.focus_mm;
}

Status SimRig::set_scene(const std::string& name_or_path) {
  try {
    auto scene = load_scene(name_or_path, scene_dirs_, ctx_.config_dir);
    if (!scene.ok()) return scene.status();
    std::string key = scene->source;
    std::error_code ec;
    const auto mtime = fs::last_write_time(key, ec);
    if (!ec) key += "@" + std::to_string(mtime.time_since_epoch().count());
    if (!scene_key_.empty() && key == scene_key_) return Status::Ok();

    std::vector<std::unique_ptr<Renderer>> renderers;
    const Rigid3& world_from_proj = calibrations_[0].cam_from_proj;
    for (size_t i = 0; i < calibrations_.size(); ++i) {
      auto ren = make_scene_renderer(*scene, config_.projector, calibrations_[i], world_from_proj, GlobalOptions{},
                                     config_.threads);
      if (!ren.ok()) return ren.status().with_context("sim rig: camera " + std::to_string(i));
      (*ren)->set_camera_lens(config_.cameras[i].lens);
      renderers.push_back(std::move(ren).value());
    }
    renderers_ = std::move(renderers);
    light_renderers_.clear();  // rebuilt for the new scene on first use
    scene_ = std::move(scene).value();
    scene_key_ = key;
    PROCAM_LOG(sim, info) << "scene '" << scene_.name << "' loaded from " << scene_.source;
    return Status::Ok();
  } catch (const std::exception& e) {
    return Error(Code::internal, "sim rig: unexpected error loading scene '" + name_or_path + "': " + e.what());
  }
}

std::vector<hw::LightInfo> SimRig::lights() const {
  std::vector<hw::LightInfo> out;
  for (size_t c : light_camera_) {
    const SimLightConfig& l = *config_.cameras[c].light;
    out.push_back({l.name, static_cast<uint32_t>(c), l.cam_from_light, l.model.intrinsics, l.model.irradiance_at_1m});
  }
  return out;
}

Status SimRig::select_light(size_t light_index) {
  if (light_index > light_camera_.size())
    return Error(Code::failed_precondition,
                 "sim rig: no light " + std::to_string(light_index) + " (the rig has " +
                     std::to_string(light_camera_.size()) + ")",
                 "give cameras a \"light\" in the rig config (hw/sim/SCENES.md)");
  light_ = light_index;
  return Status::Ok();
}

Result<Renderer*> SimRig::light_renderer(size_t camera, size_t light) {
  auto key = std::make_pair(camera, light);
  if (auto it = light_renderers_.find(key); it != light_renderers_.end()) return it->second.get();
  // The light plays the projector's part: camera i's calibration relative to
  // it is cam_i_from_light = cam_i_from_proj · proj_from_cam_c · cam_c_from_light
  // (c the camera it is mounted on); the world stays camera 0's frame.
  const size_t c = light_camera_[light - 1];
  const SimLightConfig& l = *config_.cameras[c].light;
  const Rigid3 proj_from_light = calibrations_[c].cam_from_proj.inverse() * l.cam_from_light;
  CameraCalibration cal = calibrations_[camera];
  cal.cam_from_proj = calibrations_[camera].cam_from_proj * proj_from_light;
  const Rigid3 world_from_light = calibrations_[0].cam_from_proj * proj_from_light;
  auto ren = make_scene_renderer(scene_, l.model, cal, world_from_light, GlobalOptions{}, config_.threads);
  if (!ren.ok())
    return ren.status().with_context("sim rig: camera " + std::to_string(camera) + " lit by light " +
                                     std::to_string(light));
  (*ren)->set_camera_lens(config_.cameras[camera].lens);
  (*ren)->set_focus_mm(0);
  Renderer* out = ren->get();
  light_renderers_.emplace(key, std::move(ren).value());
  return out;
}

nlohmann::json SimRig::describe() const {
  nlohmann::json j;
  try {
    const ProjectorModel& p = config_.projector;
    j["name"] = config_.name;
    nlohmann::json cam_backends = nlohmann::json::array();
    nlohmann::json cams = nlohmann::json::array();
    for (size_t i = 0; i < cameras_.size(); ++i) {
      const hw::CameraInfo& ci = cameras_[i]->info();
      cam_backends.push_back(ci.backend);
      cams.push_back({{"backend", ci.backend},
                      {"id", ci.id},
                      {"width", ci.width},
                      {"height", ci.height},
                      {"bit_depth", ci.bit_depth},
                      {"calibration", calibrations_[i]}});
    }
    j["backends"] = {{"projector", "sim"}, {"cameras", cam_backends}};
    j["projector"] = {{"backend", "sim"},
                      {"name", p.name},
                      {"width", p.intrinsics.width},
                      {"height", p.intrinsics.height},
                      {"refresh_hz", p.refresh_hz},
                      {"intrinsics", p.intrinsics},
                      {"focus_mm", p.focus_mm},
                      {"aperture_mm", p.aperture_mm}};
    j["cameras"] = cams;
    nlohmann::json lights = nlohmann::json::array();
    for (const hw::LightInfo& l : this->lights())
      lights.push_back({{"name", l.name},
                        {"camera", l.camera},
                        {"cam_from_light", l.cam_from_light},
                        {"field", l.field},
                        {"irradiance_at_1m", l.irradiance_at_1m}});
    if (!lights.empty()) j["lights"] = std::move(lights);
    // Backend state (proto/PROTOCOL.md "Rig description": `state`).
    j["state"] = {{"scene", scene_.name},
                  {"scene_file", scene_.source},
                  {"projector_focus_mm", current_focus_mm()},
                  {"seed", config_.seed}};
    bool any_faults = config_.projector_faults.any();
    for (const auto& cc : config_.cameras) any_faults = any_faults || cc.faults.any();
    if (any_faults) {
      nlohmann::json cams_f = nlohmann::json::array();
      for (const auto& c : cameras_) cams_f.push_back(counters_json(c->fault_counters(), true));
      j["state"]["faults"] = {{"projector", counters_json(projector_faults_, false)}, {"cameras", cams_f}};
    }
  } catch (const std::exception& e) {
    j = {{"name", config_.name}, {"error", std::string("describe failed: ") + e.what()}};
  }
  return j;
}

Status SimRig::check_scan_options(const nlohmann::json& options) const {
  try {
    if (options.is_null()) return Status::Ok();
    if (!options.is_object())
      return Error(Code::invalid_argument,
                   std::string("rig_options must be a JSON object, got ") + options.type_name(),
                   "for the sim rig: {\"scene\": \"<scene name>\"}");
    for (auto it = options.begin(); it != options.end(); ++it) {
      if (it.key() != "scene")
        return Error(Code::invalid_argument, "rig_options: unknown key '" + it.key() + "' for the sim rig",
                     "known keys: scene");
    }
    auto it = options.find("scene");
    if (it == options.end()) return Status::Ok();
    if (!it->is_string())
      return Error(Code::invalid_argument, std::string("rig_options.scene: must be a string, got ") + it->type_name(),
                   "give a scene name such as \"tilted-box\"");
    auto file = resolve_scene_name(it->get<std::string>(), scene_dirs_);
    if (!file.ok()) return file.status().with_context("rig_options.scene");
    return Status::Ok();
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("sim rig: check_scan_options: ") + e.what());
  }
}

nlohmann::json SimRig::scan_options() const {
  nlohmann::json values = nlohmann::json::array();
  try {
    for (const auto& name : list_scenes(scene_dirs_)) {
      nlohmann::json v = {{"name", name}};
      // The scene file's own "description" (reading JSON only: no scene is built).
      if (auto file = resolve_scene_name(name, scene_dirs_); file.ok()) {
        std::ifstream in(*file);
        auto j = nlohmann::json::parse(in, nullptr, false);
        if (j.is_object() && j.contains("description") && j["description"].is_string())
          v["description"] = j["description"];
      }
      values.push_back(std::move(v));
    }
  } catch (const std::exception& e) {
    PROCAM_LOG(sim, warn) << "listing scenes: " << e.what();
  }
  return {{"scene",
           {{"type", "string"},
            {"description", "the simulated scene to scan: a name from the rig's scene folders"},
            {"default", config_.scene},
            {"values", std::move(values)}}}};
}

Status SimRig::apply_scan_options(const nlohmann::json& options) {
  try {
    PROCAM_TRY(check_scan_options(options));
    // Every scan starts its frame sequence at 1, so a frame's sensor noise
    // (frame_noise_seed) and a dynamic medium's time depend on the rig's
    // seed and the frame's index in the scan alone: a scan is reproducible,
    // and two methods benched on one scene see the same noise on the frames
    // they share (e.g. ensemble's first round and ensemble-nocorr).
    for (auto& cam : cameras_) cam->next_frame_id_ = 1;
    if (options.is_null()) return set_scene(config_.scene);
    auto it = options.find("scene");
    if (it == options.end()) return set_scene(config_.scene);
    auto file = resolve_scene_name(it->get<std::string>(), scene_dirs_);
    if (!file.ok()) return file.status().with_context("rig_options.scene");
    return set_scene(*file).with_context("rig_options.scene");
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("sim rig: apply_scan_options: ") + e.what());
  }
}

Result<hw::GroundTruth> SimRig::ground_truth(size_t index) {
  if (index >= renderers_.size())
    return Error(Code::not_found, "sim rig: no camera " + std::to_string(index) + " (the rig has " +
                                      std::to_string(renderers_.size()) + ")");
  Renderer& ren = *renderers_[index];
  ren.set_focus_mm(current_focus_mm());  // the focus the next capture renders with
  hw::GroundTruth gt = ground_truth_from_view(ren.view());
  const SimCamera& cam = *cameras_[index];
  ren.set_polarization(std::nan(""), std::nan(""));  // truth without polariser/analyser; capture sets its own
  Status st = add_white_components(gt, ren, config_.projector, config_.cameras[index].sensor, cam.exposure_us(),
                                   cam.gain_db());
  if (st.ok())
    st = add_medium_components(gt, ren, scene_.medium ? &*scene_.medium : nullptr, config_.projector,
                               config_.cameras[index].sensor, cam.exposure_us(), cam.gain_db(),
                               projector_.polarizer_deg());
  if (!st.ok()) return st.with_context("sim rig: ground truth of camera " + std::to_string(index));
  return gt;
}

Result<std::unique_ptr<hw::Rig>> create_sim_rig(const nlohmann::json& config, const hw::RigContext& ctx) {
  auto parsed = parse_sim_rig_config(config, "rig config");
  if (!parsed.ok()) return parsed.status();
  auto rig = SimRig::create(std::move(parsed).value(), ctx);
  if (!rig.ok()) return rig.status();
  return std::unique_ptr<hw::Rig>(std::move(rig).value());
}

}  // namespace procam::sim
