// SPDX-License-Identifier: MIT
// The simulated rig backend ("sim"): procam::hw Projector / Camera / Rig
// adapters over the renderer (renderer.hpp) and sensor model (sensor.hpp).
// Config schema: hw/sim/SCENES.md "Rig config".
//
// Behaviour: SimProjector::show copies the pattern into the rig's shared state;
// wait_presented returns at once (CLOCK_MONOTONIC timestamp, no pacing);
// SimCamera::capture renders what the projector shows now at the projector's
// current focus. Noise is deterministic per (rig seed, camera, frame id).
//
// Threads: thread-bound (docs/threading.md) like every Rig (one thread at a time uses the rig and
// its devices; the renderer may use `threads` workers inside a call);
// info()/describe() results are plain data. Errors are returned, never thrown.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/hw/rig.hpp"
#include "procam/hw/sim/models.hpp"
#include "procam/hw/sim/renderer.hpp"
#include "procam/hw/sim/scene.hpp"

namespace procam::sim {

// Fault injection for synchronisation work (docs/sim.md "Fault injection"):
// rig config "faults" object on the projector or a camera. Event k (1-based
// count of show()/capture() calls) faults when k % every == 0, or, with
// seed != 0, with probability 1/every from a generator seeded by `seed`.
// 0 disables a fault.
struct FaultConfig {
  uint64_t drop_every = 0;     // projector: the shown pattern never reaches the screen, wait_presented times out;
                               // camera: a frame is lost, the next one comes with the following frame id
  uint64_t late_every = 0;     // presentation / exposure reported late_ms later than it happened
  double late_ms = 0;          // ms
  uint64_t timeout_every = 0;  // camera only: capture() fails with Code::timeout
  uint64_t seed = 0;           // 0: deterministic every-N; else random with probability 1/N
  bool any() const { return drop_every || late_every || timeout_every; }
};

// Counters of injected faults (describe()["state"]["faults"]).
struct FaultCounters {
  uint64_t events = 0, dropped = 0, late = 0, timeouts = 0;
};

// A light mounted on a camera (rig config cameras[i].light; hw::LightInfo):
// rendered as a flood from `model` (its field as intrinsics, irradiance_at_1m,
// emitted light 1 everywhere, no defocus) placed at cam_from_light, through
// the same renderer as the projector (direct light, shadows, the medium's
// attenuation and single scattering with the medium taps of this (camera,
// light) pair).
struct SimLightConfig {
  std::string name;
  Rigid3 cam_from_light;           // identity: co-located with the camera's centre
  ProjectorModel model;
};

struct SimCameraConfig {
  std::string id;                  // "sim0", "sim1", ... unless given
  std::optional<SimLightConfig> light;  // a light mounted on this camera
  CameraCalibration calibration;   // intrinsics + cam_from_proj (true = reported)
  SensorModel sensor;
  CameraLens lens;                 // camera defocus; aperture 0 (default) = pinhole
  FaultConfig faults;
};

struct SimRigConfig {
  std::string name = "sim";
  std::string description;
  std::string scene = "plane";     // default scene: name or path
  uint64_t seed = 1;               // noise seed
  int threads = 0;                 // renderer worker threads; 0: hardware threads (≤ 8)
  ProjectorModel projector;
  FaultConfig projector_faults;
  std::vector<SimCameraConfig> cameras;
};

// Strict parse of a sim rig config; errors name `source` and the field
// ("rig config: cameras[0].bit_depth: must be in [8, 16], got 4").
Result<SimRigConfig> parse_sim_rig_config(const nlohmann::json& config,
                                          const std::string& source = "rig config");

class SimRig;

class SimProjector final : public hw::Projector {
public:
  explicit SimProjector(SimRig& rig) : rig_(rig) {}
  const hw::ProjectorInfo& info() const override { return info_; }
  // invalid_argument on a wrong size/type (message names both sizes).
  Status show(const procam_image& pattern, uint64_t pattern_id) override;
  // Immediate. failed_precondition if `pattern_id` is not the last shown.
  Result<hw::Presentation> wait_presented(uint64_t pattern_id, std::chrono::milliseconds timeout) override;
  // <= 0 or NaN: the configured focus_mm. Takes effect for the next capture.
  Status set_focus_mm(double focus_mm) override;
  // Accepts any finite angle or NaN (no polariser) for the next captures;
  // invalid_argument for ±inf. Takes effect in scenes with a medium
  // (backscatter keeps polarization, docs/media.md); surface light is
  // depolarized, so without a medium it changes nothing.
  Status set_polarizer_deg(double deg) override;
  // The angle last set (NaN: none), as the scan runner delivered it.
  double polarizer_deg() const { return polarizer_deg_; }

private:
  friend class SimRig;
  SimRig& rig_;
  hw::ProjectorInfo info_;
  double polarizer_deg_ = std::numeric_limits<double>::quiet_NaN();
};

class SimCamera final : public hw::Camera {
public:
  SimCamera(SimRig& rig, uint32_t index) : rig_(rig), index_(index) {}
  const hw::CameraInfo& info() const override { return info_; }
  // exposure_us (0 < x ≤ 1e7) and gain_db (0 ≤ x ≤ 48) override the configured
  // defaults; unset values restore them. polarizer_deg is the analyser angle
  // (NaN: none): depolarized surface light passes at 1/2, a medium's
  // backscatter by its Stokes vector (docs/media.md).
  Status configure(const hw::CameraSettings& settings) override;
  // Renders the projector's current pattern; times out only through fault
  // injection (SimCameraConfig::faults).
  Result<hw::Frame> capture(std::chrono::milliseconds timeout) override;
  const FaultCounters& fault_counters() const { return faults_; }

  double exposure_us() const { return exposure_us_; }
  double gain_db() const { return gain_db_; }
  double polarizer_deg() const { return polarizer_deg_; }

private:
  friend class SimRig;
  SimRig& rig_;
  uint32_t index_;
  hw::CameraInfo info_;
  double exposure_us_ = 0, gain_db_ = 0, polarizer_deg_ = 0;
  uint64_t next_frame_id_ = 1;
  std::vector<float> radiance_;  // scratch, width*height
  FaultCounters faults_;
  uint64_t fault_rng_ = 0;
};

class SimRig final : public hw::Rig {
public:
  // Loads the default scene and prepares every camera. Scene names resolve in
  // ctx.scene_dirs, or `<config_dir>/../scenes` when that list is empty.
  static Result<std::unique_ptr<SimRig>> create(SimRigConfig config, hw::RigContext ctx);

  hw::Projector& projector() override { return projector_; }
  size_t camera_count() const override { return cameras_.size(); }
  // index < camera_count() (asserted; clamped in release builds).
  hw::Camera& camera(size_t index) override;
  const Intrinsics& projector_intrinsics() const override { return config_.projector.intrinsics; }
  const std::vector<CameraCalibration>& camera_calibrations() const override { return calibrations_; }
  // proto/PROTOCOL.md "Rig description" plus "backends"; "state" holds
  // {"scene", "scene_file", "projector_focus_mm", "seed"} and, when any fault
  // injection is configured, "faults": {"projector": counters, "cameras": [counters]}.
  nlohmann::json describe() const override;
  // Keys: "scene": the NAME of a scene in the rig's scene folders (a file
  // <folder>/<name>.json; names are [A-Za-z0-9_-] segments, '/' allowed
  // between segments, never a path: rig_options come from remote clients, so
  // they must not name host files). A call without "scene" (or with null/{})
  // restores the configured default scene (the rig config may give a path).
  // Errors: invalid_argument naming the key, listing the known scenes.
  Status apply_scan_options(const nlohmann::json& options) override;
  // The same checks without loading anything; thread-safe (reads the config
  // and the scene folders only).
  Status check_scan_options(const nlohmann::json& options) const override;
  // {"scene": {"type": "string", "default": <the rig config's scene>,
  // "values": every scene of the scene folders with its description}}.
  nlohmann::json scan_options() const override;
  Result<hw::GroundTruth> ground_truth(size_t index) override;
  // The cameras' lights in camera order (light_index k = lights()[k − 1]).
  std::vector<hw::LightInfo> lights() const override;
  // 0: the projector; k: light k alone for the following captures (the
  // projector's pattern is not rendered). failed_precondition beyond lights().
  Status select_light(size_t light_index) override;
  size_t selected_light() const { return light_; }

  // Load and prepare a scene (no-op if the same file is already loaded).
  Status set_scene(const std::string& name_or_path);
  const Scene& scene() const { return scene_; }
  const SimRigConfig& config() const { return config_; }
  // The renderer of camera `camera_index` (< camera_count()) for the current
  // scene; replaced by set_scene(), so do not keep the reference across it.
  Renderer& renderer(size_t camera_index) { return *renderers_[camera_index]; }
  // Focus the next captures use (the configured default when unset).
  double current_focus_mm() const;

private:
  friend class SimProjector;
  friend class SimCamera;
  SimRig(SimRigConfig config, hw::RigContext ctx);

  SimRigConfig config_;
  hw::RigContext ctx_;
  std::vector<std::string> scene_dirs_;
  std::vector<CameraCalibration> calibrations_;
  Scene scene_;
  std::string scene_key_;  // resolved file + modification time of the loaded scene
  std::vector<std::unique_ptr<Renderer>> renderers_;
  SimProjector projector_;
  std::vector<std::unique_ptr<SimCamera>> cameras_;
  // Lights (SimCameraConfig::light): the camera each is mounted on, in order.
  std::vector<size_t> light_camera_;
  std::vector<PreparedPattern> light_patterns_;  // per light: emitted 1 over its field
  size_t light_ = 0;                             // selected light; 0 = the projector
  // Renderers per (camera, light) pair, built on first use for the scene.
  std::map<std::pair<size_t, size_t>, std::unique_ptr<Renderer>> light_renderers_;
  Result<Renderer*> light_renderer(size_t camera, size_t light);
  // Shared projector state.
  PreparedPattern pattern_;
  PreparedPattern spare_pattern_;  // the next pattern is prepared here (storage reuse)
  uint64_t pattern_id_ = 0;
  bool pattern_shown_ = false;
  bool pattern_dropped_ = false;  // fault injection: the last show() never reached the screen
  bool pattern_late_ = false;     // fault injection: its presentation is reported late
  double focus_mm_ = 0;  // <= 0: configured default
  FaultCounters projector_faults_;
  uint64_t projector_fault_rng_ = 0;

public:
  const FaultCounters& projector_fault_counters() const { return projector_faults_; }
};

// create_rig() entry for the "sim" backend (used by hw/registry.cpp).
Result<std::unique_ptr<hw::Rig>> create_sim_rig(const nlohmann::json& config, const hw::RigContext& ctx);

}  // namespace procam::sim
