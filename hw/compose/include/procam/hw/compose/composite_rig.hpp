// SPDX-License-Identifier: MIT
// Composite rig: one projector backend plus camera backends chosen per device
// (e.g. projector "glfw" + camera "aravis", or projector "sim" + camera
// "aravis" fed by the simulated rig). Used by hw/registry.cpp whenever a rig
// config names a device-level backend (aravis, glfw, libcamera, screencam).
// Devices are opened through a table of device backends {name, kind,
// factory, summary} (composite_rig.cpp); a backend left out of the build has
// no row, so its name is reported as unknown with the available ones listed.
//
// The "sim projector + Aravis Fake camera fed by the sim" bridge: when the
// projector is "sim" and a camera entry has a "feed": {"backend": "sim", ...}
// object (sim sensor fields), the composite builds a SimRig for the projector
// and the feeding sim cameras, and opens the camera's Aravis in-process Fake
// device with a fill callback that renders what the sim projector shows now.
// The sim projector is wrapped so that show()/scene changes and the Aravis
// stream thread's rendering are serialised by one mutex. Frames then travel
// through a real Aravis acquisition path (stream, buffers, status, ids), and
// ground_truth() delegates to the sim rig, so accuracy is evaluated exactly as
// on the pure sim rig.
//
// Config (configs/rigs/*.json): the sim fields for a sim projector, plus
//   "sync": {"mode": "software|hardware|free_run", "display_latency_ms": x,
//            "camera_latency_ms": y, "retries": n, ...}   (see daemon sync engine)
//   "cameras": [{"backend": "aravis", "intrinsics": {...}, "cam_from_proj": {...},
//                ...backend keys..., "feed": {...}?}]
// Threads: thread-bound (docs/threading.md) like every Rig. Errors: Status naming the field.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/hw/rig.hpp"

namespace procam::compose {

// What a backend builds: a whole rig (hw/registry.cpp, e.g. "sim"), or one
// device of a composite rig (a projector or a camera).
enum class BackendKind { rig, projector, camera };

// One row of a backend table, as listed to users (the factory stays private
// to the table that owns it).
struct BackendEntry {
  const char* name;     // the rig config's "backend" value
  BackendKind kind;
  const char* summary;  // one line for listings
};

// Device backends compiled into this build (the table in composite_rig.cpp):
// projectors first (sim, then glfw), then cameras (aravis, screencam,
// libcamera), each only if built (hw/CMakeLists.txt may leave one out).
std::vector<BackendEntry> device_backends();
// Names of the device backends of `kind`, comma-separated ("sim, glfw").
std::string backend_names(BackendKind kind);
bool is_projector_backend(const std::string& name);
bool is_camera_backend(const std::string& name);

Result<std::unique_ptr<hw::Rig>> create_composite_rig(const nlohmann::json& config, const hw::RigContext& ctx);

}  // namespace procam::compose
