// SPDX-License-Identifier: MIT
// Shared by the conformance and accuracy suites: every plugin method found at
// run time in PROCAM_PLUGIN_DIR, and one scan of a method on the sim rig
// through the real path (plan -> sim capture via engine::run_scan, all
// rounds -> streaming decode -> outputs).
//
// Threads: test-thread only. Errors: gtest assertions in the caller's test.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <cctype>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/engine/calibration_tables.hpp"
#include "procam/engine/rig_json.hpp"
#include "procam/engine/scan_runner.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/hw/rig.hpp"

namespace procam::suite {

inline std::string source(const std::string& rel) { return std::string(PROCAM_SOURCE_DIR) + "/" + rel; }

struct MethodCase {
  std::string plugin, method;
  nlohmann::json describe;  // the method's describe() object
};
inline void PrintTo(const MethodCase& c, std::ostream* os) { *os << c.plugin << "/" << c.method; }

// Every method of every plugin the host loads from PROCAM_PLUGIN_DIR.
inline std::vector<MethodCase> all_methods() {
  host::PluginHost host;
  host.load_directories({PROCAM_PLUGIN_DIR});
  std::vector<MethodCase> cases;
  for (const auto& p : host.plugins())
    for (const auto& m : p.methods) cases.push_back({p.name, m.name, m.describe});
  return cases;
}

// A gtest-safe test name: "<plugin>_<method>[_<suffix>]" with [^A-Za-z0-9] -> '_'.
inline std::string case_name(const std::string& plugin, const std::string& method, const std::string& suffix = "") {
  std::string n = plugin + "_" + method + (suffix.empty() ? "" : "_" + suffix);
  for (char& ch : n)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return n;
}

// The shipped sim rigs, in the order a method is tried on them: the
// one-camera rig (configs/rigs/sim.json) first; a method that refuses it with
// failed_precondition (it needs more than one camera and a projector) runs on
// the first of the others it accepts: two cameras (binocular stereo) and
// camera+light units (lights co-located with five cameras, plugin ABI 3), and
// the co-located rig of thesis ch. 2, the one that ships the calibration
// tables the defocus methods and separation's one-focal-depth need (made on
// that rig: a method refuses a rig without its table).
inline const std::vector<std::string>& sim_rig_files() {
  static const std::vector<std::string> files = {"sim.json", "sim-tank-stereo.json", "sim-helmholtz.json",
                                                 "sim-colocated.json"};
  return files;
}

// The shipped sim rig configs/rigs/<file> showing `scene`; a fresh rig per
// call, so its frame noise starts from the same seed.
inline std::unique_ptr<hw::Rig> sim_rig(const std::string& scene, const std::string& file = "sim.json") {
  auto cfg = engine::read_json_file(source("configs/rigs/" + file));
  EXPECT_TRUE(cfg.ok()) << cfg.status().message();
  if (!cfg.ok()) return nullptr;
  auto rig = hw::create_rig(*cfg, {source("configs/rigs"), {source("configs/scenes")}});
  EXPECT_TRUE(rig.ok()) << rig.status().message();
  if (!rig.ok()) return nullptr;
  EXPECT_TRUE((*rig)->apply_scan_options({{"scene", scene}}).ok());
  return std::move(*rig);
}

// The plugin's rig description for the shipped rig configs/rigs/<file>, with
// the calibration tables that config names loaded into it, as procamd and
// `procam decode` do (docs/calibration.md).
inline nlohmann::json plugin_rig_json_for(hw::Rig& rig, const std::string& file) {
  nlohmann::json j = engine::plugin_rig_json(rig, 2);
  auto cfg = engine::read_json_file(source("configs/rigs/" + file));
  EXPECT_TRUE(cfg.ok()) << cfg.status().message();
  if (!cfg.ok()) return j;
  auto tables = engine::load_calibration_tables(*cfg, source("configs/rigs"), file);
  EXPECT_TRUE(tables.ok()) << tables.status().message();
  if (tables.ok() && tables->is_object() && !tables->empty()) j["calibration_tables"] = *tables;
  return j;
}

// The inputs a method declares as required (describe() "inputs", ABI 2),
// made from what the sim rig knows: "depth_mm" is the ground-truth depth of
// the scene; any other F32 input a camera-sized map of ones. `storage` owns
// the pixels the returned views point into.
inline std::vector<host::InputImage> required_inputs(const nlohmann::json& describe, hw::Rig& rig,
                                                     std::vector<std::vector<float>>& storage) {
  std::vector<host::InputImage> inputs;
  if (!describe.contains("inputs") || !describe["inputs"].is_array()) return inputs;
  auto truth = rig.ground_truth(0);
  EXPECT_TRUE(truth.ok()) << truth.status().message();
  if (!truth.ok()) return inputs;
  const uint32_t w = truth->depth_mm.width(), h = truth->depth_mm.height();
  storage.reserve(describe["inputs"].size());
  for (const auto& in : describe["inputs"]) {
    if (!in.value("required", false)) continue;
    const std::string name = in.value("name", "");
    const float* src = name == "depth_mm" ? truth->depth_mm.ptr<float>() : nullptr;
    storage.emplace_back(size_t{w} * h, 1.0f);
    if (src != nullptr) std::copy(src, src + storage.back().size(), storage.back().begin());
    host::InputImage img;
    img.name = name;
    img.unit = in.value("unit", "");
    img.description = "conformance suite: sim ground truth";
    img.image = procam_image{.width = w, .height = h, .channels = 1, .pixel_type = PROCAM_PIXEL_F32,
                             .bit_depth = 32, .reserved = 0, .stride_bytes = size_t{w} * sizeof(float),
                             .data = storage.back().data()};
    inputs.push_back(img);
  }
  return inputs;
}

// One finished scan. `session` owns the memory `outputs` point into.
// `skip_reason`: set (and the run not started) when the method refused every
// shipped sim rig with failed_precondition, i.e. it needs rig data none of
// them has (a calibration table made on another rig): the caller skips with
// that reason instead of failing. `rig_file`: the rig it ran on.
struct SimRun {
  std::string rig_file;
  std::unique_ptr<hw::Rig> rig;
  nlohmann::json rig_json;
  std::optional<host::Session> session;
  engine::ScanOutcome outcome;
  std::vector<host::Output> outputs;
  std::string skip_reason;
};

// Runs plugin/method with parameters `params` (JSON; default: the
// method's defaults) on `scene`; ADD_FAILUREs and returns false when any
// step fails.
inline bool run_on_sim(const std::string& plugin, const std::string& method, const std::string& scene, SimRun& run,
                       const std::string& params = "{}") {
  host::PluginHost host;
  host.load_directories({PROCAM_PLUGIN_DIR});
  nlohmann::json describe;
  if (const auto* p = host.find(plugin))
    for (const auto& m : p->methods)
      if (m.name == method) describe = m.describe;
  std::optional<host::Session> created;
  std::vector<std::string> refusals;
  for (const std::string& file : sim_rig_files()) {
    run.rig = sim_rig(scene, file);
    if (!run.rig) return false;
    run.rig_file = file;
    run.rig_json = plugin_rig_json_for(*run.rig, file);
    std::vector<std::vector<float>> storage;
    const std::vector<host::InputImage> inputs = required_inputs(describe, *run.rig, storage);
    auto session = host.create_session(plugin, method, params, run.rig_json.dump(), inputs);
    if (!session.ok() && session.status().code() == Code::failed_precondition &&
        !session.status().message().empty()) {
      refusals.push_back(file + ": " + session.status().message());
      continue;
    }
    if (!session.ok()) {
      ADD_FAILURE() << "create_session on " << file << ": " << session.status().message();
      return false;
    }
    created.emplace(std::move(*session));
    break;
  }
  if (!created) {
    for (const auto& r : refusals) run.skip_reason += (run.skip_reason.empty() ? "" : "; ") + r;
    return false;
  }
  auto& session = created;
  run.session.emplace(std::move(*session));
  std::atomic<bool> cancel{false};
  auto outcome = engine::run_scan(*run.rig, *run.session, engine::CaptureOptions{}, nullptr, cancel);
  if (!outcome.ok()) {
    ADD_FAILURE() << "run_scan: " << outcome.status().message();
    return false;
  }
  run.outcome = std::move(*outcome);
  auto outs = run.session->outputs();
  if (!outs.ok()) {
    ADD_FAILURE() << "outputs: " << outs.status().message();
    return false;
  }
  run.outputs = std::move(*outs);
  return true;
}

inline const host::Output* find_output(const std::vector<host::Output>& outs, const std::string& name) {
  for (const auto& o : outs)
    if (o.name == name) return &o;
  return nullptr;
}

}  // namespace procam::suite
