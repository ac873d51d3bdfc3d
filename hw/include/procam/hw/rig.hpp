// SPDX-License-Identifier: MIT
// Rig: a projector plus one or more cameras with their calibration, built by
// backend name from a rig config (configs/rigs/*.json). Extension point: see
// hw/README.md "How to add a backend".
//
// Threads: a Rig is created and used on one thread at a time (the daemon's scan
// worker); describe() results are plain data and may be copied anywhere.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/base/calibration.hpp"
#include "procam/core/image.hpp"
#include "procam/core/status.hpp"
#include "procam/hw/camera.hpp"
#include "procam/hw/projector.hpp"

namespace procam::hw {

// Per-camera-pixel truth a simulated rig knows (float maps use NaN where
// undefined). Coordinates: pixel centres at integers.
struct GroundTruth {
  Image depth_mm;       // F32: z of the first surface in the camera frame
  Image proj_col;       // F32: continuous projector column seen at this pixel
  Image proj_row;       // F32: continuous projector row
  Image lit;            // U8: 255 where the projector lights the visible point
  Image object;         // U8: 1 + index of the visible object in the scene (0 = none); may be empty
  // Light transport split of the frame under a full-white pattern (thesis
  // §2.5): the projector light reaching the pixel straight from the visible
  // point (direct) and by every other path (global: inter-reflection,
  // sub-surface scattering, ...). F32, camera-sized, in the camera's digital
  // numbers at its current exposure and gain, noise-free, before rounding and
  // clamping, without ambient light: direct + global + ambient = the expected
  // white frame. Empty when the rig cannot separate them.
  Image direct;
  Image global;
  // Participating medium (thesis Eq. 5.1: E = D + A + B), same units and
  // white pattern as direct/global, no analyser; empty when the scene has no
  // medium. medium_direct: D, surface light attenuated on both legs (=
  // `direct` then); medium_indirect: A, light forward-scattered in the medium
  // and then reflected (the sim approximates it, docs/media.md); medium_backscatter:
  // B, single-scattered light from the medium; medium_backscatter_dop: the
  // degree of polarization of B (0..1) for the projector polariser set at the
  // time of the call (unpolarized light without one), NaN where B = 0.
  Image medium_direct;
  Image medium_indirect;
  Image medium_backscatter;
  Image medium_backscatter_dop;
  // Tank rig (docs/media.md "Tank rig"): the light source seen straight
  // through the medium (the bulb, attenuated: Eq. 4.3's regime), same units
  // and white pattern; empty without one. With a bulb, medium_backscatter is
  // the bulb's single-scattered light (Eq. 4.1-4.2) and `medium` holds the
  // geometry a plugin needs under "tank" (tank.json beside the images).
  Image medium_source;
  // Truth of a participating medium's parameters (e.g. {"extinction_per_mm":
  // 0.002}), keyed by the name a plugin's output carries after "medium_";
  // null when the scene has none or the rig does not know it.
  nlohmann::json medium;
};

// A light of the rig other than the projector (ABI 3 frame settings
// `light_index`; proto/PROTOCOL.md "Rig description" "lights"): a small
// source mounted on camera `camera`, e.g. a ring light around its lens or a
// source behind a beam splitter (cam_from_light identity = co-located with
// the camera's centre). It floods the scene inside its field (`field`: a
// pinhole image whose extent bounds the lit cone, pixel edges at -0.5 and
// w - 0.5) isotropically with `irradiance_at_1m` (the projector's unit: a
// full-white projector frame of irradiance_at_1m 1 gives the same light at
// 1 m). Lengths mm.
struct LightInfo {
  std::string name;
  uint32_t camera = 0;        // the camera it is mounted on
  Rigid3 cam_from_light;      // x_cam = R x_light + t (mm)
  Intrinsics field;           // emission cone
  double irradiance_at_1m = 1.0;
};

// The field of a light whose config gives none: a 256 x 256 pinhole image of
// f = 64 px centred on its axis, i.e. +-63.4 deg about it.
inline Intrinsics default_light_field() {
  Intrinsics k;
  k.width = 256;
  k.height = 256;
  k.fx = k.fy = 64.0;
  k.cx = k.cy = 127.5;
  return k;
}

class Rig {
public:
  virtual ~Rig() = default;

  virtual Projector& projector() = 0;
  virtual size_t camera_count() const = 0;
  virtual Camera& camera(size_t index) = 0;

  // Calibration used for decoding; cameras()[i] belongs to camera(i).
  virtual const Intrinsics& projector_intrinsics() const = 0;
  virtual const std::vector<CameraCalibration>& camera_calibrations() const = 0;

  // The rig description of proto/PROTOCOL.md ("Rig description"): name,
  // backends, resolutions, calibration, and backend state.
  virtual nlohmann::json describe() const = 0;

  // Per-scan options (the scan request's "rig_options"), e.g. the sim rig's
  // {"scene": "v-groove"}. Unknown keys are an invalid_argument error naming
  // the key. Applies until the next call.
  virtual Status apply_scan_options(const nlohmann::json& options) = 0;
  // Checks `options` without applying them, so a service can refuse a bad
  // request when it arrives instead of when its scan runs. Same errors as
  // apply_scan_options would give (invalid_argument naming the key). Must be
  // thread-safe (docs/threading.md): it may run while another thread uses the
  // rig. Default: accepts only null or an empty object (a rig with no options).
  virtual Status check_scan_options(const nlohmann::json& options) const {
    if (options.is_null() || (options.is_object() && options.empty())) return Status::Ok();
    return Error(Code::invalid_argument, "rig_options: this rig takes no options, got " + options.dump(),
                 "send the scan without rig_options");
  }

  // What check_scan_options accepts, for clients (request list_rig_options,
  // PROTOCOL.md 5.11): {"<key>": {"type", "description", "default"?,
  // "values"?: [{"name", "description"?}]}}. Thread-safe like
  // check_scan_options. Default: {} (no options).
  virtual nlohmann::json scan_options() const { return nlohmann::json::object(); }

  // Ground truth for camera `index` of the current scene; not_found/unavailable
  // on hardware rigs.
  virtual Result<GroundTruth> ground_truth(size_t index) = 0;

  // --- additive (issue 5); defaults keep older backends compiling ---
  // Synchronization settings for the daemon's sync engine: the rig config's
  // "sync" object ({"mode", "display_latency_ms", "camera_latency_ms",
  // "retries", ...}) merged with values stored by set_sync_state(); {} when
  // the rig has none (the engine then uses software-trigger defaults).
  virtual nlohmann::json sync_settings() const { return nlohmann::json::object(); }
  // Store measured synchronization values (e.g. calibrated latencies); they
  // override the config in sync_settings() and show in describe()["state"].
  virtual void set_sync_state(const nlohmann::json& state) { (void)state; }

  // --- additive (issue 13, plugin ABI 3); defaults: a rig with no lights ---
  // The rig's lights besides the projector; lights()[k - 1] is light_index k.
  virtual std::vector<LightInfo> lights() const { return {}; }
  // The light of the following captures: 0 = the projector showing its
  // pattern (the default); k in 1..lights().size() = light k alone, the
  // projector dark (its pattern is ignored). failed_precondition for a light
  // the rig does not have.
  virtual Status select_light(size_t light_index) {
    if (light_index == 0) return Status::Ok();
    return Error(Code::failed_precondition,
                 "the plan asks for light " + std::to_string(light_index) + " but this rig has no lights",
                 "use a rig with lights co-located with its cameras (e.g. configs/rigs/sim-helmholtz.json)");
  }
};

struct RigContext {
  std::string config_dir;                // relative paths in the config resolve here
  std::vector<std::string> scene_dirs;   // where scene names are looked up
};

// Build a rig from its config JSON. Errors name the offending field and the
// backends available.
Result<std::unique_ptr<Rig>> create_rig(const nlohmann::json& config, const RigContext& ctx);

// Names of compiled-in backends, e.g. {"sim"}.
std::vector<std::string> available_backends();

}  // namespace procam::hw
