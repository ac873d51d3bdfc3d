// SPDX-License-Identifier: MIT
// Backend registry: create_rig() builds a rig from its config by backend name.
//
// Backends come from two tables of {name, kind, factory, summary}:
//   - kRigBackends below: backends that build a whole rig ("sim": projector
//     and cameras simulated together);
//   - the device backend table of the composite rig (kDeviceBackends in
//     hw/compose/src/composite_rig.cpp): one projector ("sim", "glfw") or
//     camera ("aravis", "screencam", "libcamera") each.
// A rig whose devices all name the same rig backend is built by it; any other
// rig is a composite: its projector names a projector backend and every camera
// a camera backend, freely mixed (e.g. glfw + aravis + screencam). A sim
// camera exists only in the all-sim rig or as an aravis camera's "feed".
//
// How to add a backend (see also hw/README.md "How to add a backend"):
//   1. One folder hw/<name>/ with a library procam_<name> implementing
//      procam::hw::Projector or Camera (hw/include/procam/hw/) and a strict
//      config parser that names the field in every error.
//   2. One row in a table: a device backend in kDeviceBackends
//      (hw/compose/src/composite_rig.cpp, under #if PROCAM_HAVE_<NAME>, plus
//      its name in the list in hw/compose/CMakeLists.txt); a whole-rig
//      backend in kRigBackends below.
//   (and add_subdirectory(<name>) in hw/CMakeLists.txt, a configs/rigs/ example,
//   tests beside the code.) Nothing else picks backends by name.
// Errors from create_rig name the offending field and list the backends.
#include <string>
#include <vector>

#include "procam/hw/compose/composite_rig.hpp"
#include "procam/hw/rig.hpp"
#include "procam/hw/sim/sim_rig.hpp"

namespace procam::hw {
namespace {

using compose::BackendKind;
using RigFactory = Result<std::unique_ptr<Rig>> (*)(const nlohmann::json&, const RigContext&);

struct RigBackend {
  const char* name;
  BackendKind kind;  // always rig here
  RigFactory create;
  const char* summary;
};

// Whole-rig backends. They come first in listings.
constexpr RigBackend kRigBackends[] = {
    {"sim", BackendKind::rig, &procam::sim::create_sim_rig,
     "simulated projector and cameras rendering a scene (hw/sim)"},
};

const RigBackend* find_rig_backend(const std::string& name) {
  for (const RigBackend& b : kRigBackends)
    if (name == b.name) return &b;
  return nullptr;
}

bool is_known(const std::string& name) {
  return find_rig_backend(name) != nullptr || compose::is_projector_backend(name) ||
         compose::is_camera_backend(name);
}

std::string backend_list() {
  std::string s;
  for (const std::string& n : available_backends()) s += (s.empty() ? "" : ", ") + n;
  return s;
}

// Backend named by `device[field]`, or an error naming the field.
Result<std::string> backend_of(const nlohmann::json& device, const std::string& field) {
  if (!device.is_object())
    return Error(Code::invalid_argument, "rig config: " + field + ": must be a JSON object");
  auto it = device.find("backend");
  if (it == device.end())
    return Error(Code::invalid_argument, "rig config: " + field + ".backend: missing",
                 "available backends: " + backend_list());
  if (!it->is_string())
    return Error(Code::invalid_argument, "rig config: " + field + ".backend: must be a string",
                 "available backends: " + backend_list());
  const std::string name = it->get<std::string>();
  if (!is_known(name))
    return Error(Code::invalid_argument,
                 "rig config: " + field + ".backend: unknown backend '" + name + "'",
                 "available backends: " + backend_list());
  return name;
}

}  // namespace

std::vector<std::string> available_backends() {
  std::vector<std::string> out;
  auto add = [&out](const std::string& n) {
    for (const std::string& o : out)
      if (o == n) return;
    out.push_back(n);
  };
  for (const RigBackend& b : kRigBackends) add(b.name);
  for (const compose::BackendEntry& b : compose::device_backends()) add(b.name);
  return out;
}

Result<std::unique_ptr<Rig>> create_rig(const nlohmann::json& config, const RigContext& ctx) {
  try {
    if (!config.is_object())
      return Error(Code::invalid_argument, "rig config: must be a JSON object",
                   "see configs/rigs/sim.json for an example");
    auto pj = config.find("projector");
    if (pj == config.end())
      return Error(Code::invalid_argument, "rig config: projector: missing",
                   "add \"projector\": {\"backend\": \"sim\", ...}; available backends: " + backend_list());
    auto projector_backend = backend_of(*pj, "projector");
    if (!projector_backend.ok()) return projector_backend.status();
    auto cams = config.find("cameras");
    if (cams == config.end() || !cams->is_array() || cams->empty())
      return Error(Code::invalid_argument, "rig config: cameras: must be a non-empty array",
                   "add \"cameras\": [{\"backend\": \"" + *projector_backend + "\", ...}]");
    std::vector<std::string> camera_backends;
    bool all_same = true;
    for (size_t i = 0; i < cams->size(); ++i) {
      auto cb = backend_of((*cams)[i], "cameras[" + std::to_string(i) + "]");
      if (!cb.ok()) return cb.status();
      all_same = all_same && *cb == *projector_backend;
      camera_backends.push_back(*cb);
    }
    // Every device names the same whole-rig backend: that backend builds the rig.
    if (const RigBackend* rb = find_rig_backend(*projector_backend); rb != nullptr && all_same)
      return rb->create(config, ctx);
    // Otherwise a composite rig: one projector backend, camera backends per camera.
    if (!compose::is_projector_backend(*projector_backend))
      return Error(Code::invalid_argument,
                   "rig config: projector.backend: '" + *projector_backend + "' is not a projector backend",
                   "projector backends: " + compose::backend_names(BackendKind::projector));
    for (size_t i = 0; i < camera_backends.size(); ++i)
      if (!compose::is_camera_backend(camera_backends[i]))
        return Error(Code::invalid_argument,
                     "rig config: cameras[" + std::to_string(i) + "].backend: '" + camera_backends[i] +
                         "' cannot be combined with projector '" + *projector_backend + "'",
                     "camera backends: " + compose::backend_names(BackendKind::camera) +
                         (camera_backends[i] == "sim" ? " (a sim camera exists only in an all-sim rig, or as an "
                                                        "aravis camera's \"feed\")"
                                                      : ""));
    return compose::create_composite_rig(config, ctx);
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("create_rig: unexpected error: ") + e.what());
  }
}

}  // namespace procam::hw
