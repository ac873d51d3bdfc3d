// SPDX-License-Identifier: MIT
// Backend registry: create_rig() builds a rig from its config by backend name.
//
// How to add a backend (see also hw/README.md):
//   1. Create hw/<name>/ with a library target procam_<name> (alias
//      procam::<name>) whose public header declares
//        Result<std::unique_ptr<hw::Rig>> create_<name>_rig(const nlohmann::json&,
//                                                          const hw::RigContext&);
//      implementing procam::hw::Projector / Camera / Rig (hw/include/procam/hw/).
//   2. Add it to hw/CMakeLists.txt (add_subdirectory) and link it PRIVATE into
//      procam_hw there.
//   3. Add one row {"<name>", &create_<name>_rig} to kBackends below.
//   4. Give it a config in configs/rigs/<name>.json that sets
//      "projector": {"backend": "<name>"} and "cameras": [{"backend": "<name>"}].
//   5. Test it beside its code (hw/<name>/src/*_test.cpp); tests that need
//      hardware or an emulator they cannot find skip with a reason.
// Errors from create_rig name the offending field and list the backends.
#include <string>
#include <vector>

#include "procam/hw/compose/composite_rig.hpp"
#include "procam/hw/rig.hpp"
#include "procam/hw/sim/sim_rig.hpp"

namespace procam::hw {
namespace {

using RigFactory = Result<std::unique_ptr<Rig>> (*)(const nlohmann::json&, const RigContext&);

struct Backend {
  const char* name;
  RigFactory create;
};

// Compiled-in backends. One rig is built by one backend: the projector and all
// cameras must name the same backend (mixing is not supported yet).
// Device-level backends (issue 5) are built by the composite rig
// (hw/compose), which combines one projector backend with camera backends; a
// rig whose devices are all "sim" stays the pure sim rig.
constexpr Backend kBackends[] = {
    {"sim", &procam::sim::create_sim_rig},
    {"aravis", &procam::compose::create_composite_rig},
    {"glfw", &procam::compose::create_composite_rig},
    {"screencam", &procam::compose::create_composite_rig},
    {"libcamera", &procam::compose::create_composite_rig},
};

std::string backend_list() {
  std::string s;
  for (const Backend& b : kBackends) s += (s.empty() ? "" : ", ") + std::string(b.name);
  return s;
}

const Backend* find_backend(const std::string& name) {
  for (const Backend& b : kBackends)
    if (name == b.name) return &b;
  return nullptr;
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
  if (find_backend(name) == nullptr)
    return Error(Code::invalid_argument,
                 "rig config: " + field + ".backend: unknown backend '" + name + "'",
                 "available backends: " + backend_list());
  return name;
}

}  // namespace

std::vector<std::string> available_backends() {
  std::vector<std::string> out;
  for (const Backend& b : kBackends) out.emplace_back(b.name);
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
    bool composite = false;
    for (size_t i = 0; i < cams->size(); ++i) {
      const std::string field = "cameras[" + std::to_string(i) + "]";
      auto cb = backend_of((*cams)[i], field);
      if (!cb.ok()) return cb.status();
      // Device-level backends may be mixed with any projector the composite rig knows.
      if (procam::compose::is_camera_backend(*cb) && procam::compose::is_projector_backend(*projector_backend)) {
        composite = true;
        continue;
      }
      if (*cb != *projector_backend)
        return Error(Code::invalid_argument,
                     "rig config: " + field + ".backend: '" + *cb + "' differs from the projector's '" +
                         *projector_backend + "'",
                     "mixing backends in one rig is not supported yet; use one backend for all devices");
    }
    if (composite) return procam::compose::create_composite_rig(config, ctx);
    return find_backend(*projector_backend)->create(config, ctx);
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("create_rig: unexpected error: ") + e.what());
  }
}

}  // namespace procam::hw
