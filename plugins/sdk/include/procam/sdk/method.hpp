// SPDX-License-Identifier: MIT
// MethodDescription: a typed description of one decoder method, serialised by
// to_json() into the entry describe() returns for it (and the daemon forwards
// in list_plugins, proto/PROTOCOL.md §5.2), so plugins stop hand-writing
// describe() JSON. Every key is documented in plugins/sdk/README.md.
//
// JSON form (an object; nlohmann::json orders keys by name):
//   {"name", "description", "patterns" (integer or null), ["patterns_formula"],
//    "rounds" (integer, or a string when it depends on the scene/params),
//    "outputs" [names], "params" [describe_params()],
//    ["inputs" [{"name","kind","unit","required","description"}]]}
// "inputs" (plugin ABI 2, plugin_abi.h "Scan inputs") is present only for a
// method that takes outputs of an earlier scan; the host refuses scans that
// give undeclared inputs or leave out required ones.
// Errors: to_json() throws std::invalid_argument for a plugin bug (empty name
// or summary, an output name that is not lower_snake_case); describe() runs
// inside the SDK's exception barrier.
// Thread-safety: a plain value type; descriptions are normally built once.
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/sdk/outputs.hpp"
#include "procam/sdk/params.hpp"

namespace procam::sdk {

// One input a method takes (CreateArgs::inputs, sdk/inputs.hpp).
struct InputSpec {
  std::string name;                // lower_snake_case with unit suffix, e.g. "depth_mm"
  std::string kind = "image_f32";  // the only kind: 1-channel F32 map of camera 0's size
  std::string unit;                // e.g. "mm"
  bool required = true;
  std::string description;         // what the method does with it, for `procam plugins`

  nlohmann::json to_json() const {
    return {{"name", name}, {"kind", kind}, {"unit", unit}, {"required", required},
            {"description", description}};
  }
};

struct MethodDescription {
  std::string name;     // method name as in PROCAM_DEFINE_PLUGIN's list
  std::string summary;  // one line for humans -> "description"
  // Patterns the first round projects with default parameters; nullopt when
  // that depends on the rig (e.g. ceil(log2 projector width)) -> null.
  std::optional<uint32_t> patterns;
  std::string patterns_formula;  // how the count follows from rig/params; "" = omitted
  // Capture rounds: a fixed count, or (when rounds_formula is not empty) a
  // description such as "1 + up to correction_rounds", emitted instead.
  uint32_t rounds = 1;
  std::string rounds_formula;
  std::vector<std::string> outputs;  // output names the method may produce
  std::vector<ParamSpec> params;     // as validated by parse_params()
  std::vector<InputSpec> inputs;     // outputs of an earlier scan it takes; empty = none

  nlohmann::json to_json() const {
    if (name.empty() || summary.empty())
      throw std::invalid_argument("method description: name and summary are required");
    for (const std::string& o : outputs)
      if (!is_output_name(o))
        throw std::invalid_argument("method '" + name + "': output name '" + o +
                                    "' is not lower_snake_case");
    for (size_t i = 0; i < inputs.size(); ++i) {
      const InputSpec& in = inputs[i];
      if (!is_output_name(in.name))
        throw std::invalid_argument("method '" + name + "': input name '" + in.name +
                                    "' is not lower_snake_case");
      if (in.kind != "image_f32")
        throw std::invalid_argument("method '" + name + "': input '" + in.name + "' has kind '" +
                                    in.kind + "'; the only kind is image_f32");
      for (size_t k = 0; k < i; ++k)
        if (inputs[k].name == in.name)
          throw std::invalid_argument("method '" + name + "': input '" + in.name + "' is listed twice");
    }
    nlohmann::json j = nlohmann::json::object();
    j["name"] = name;
    j["description"] = summary;
    j["patterns"] = patterns ? nlohmann::json(*patterns) : nlohmann::json(nullptr);
    if (!patterns_formula.empty()) j["patterns_formula"] = patterns_formula;
    j["rounds"] = rounds_formula.empty() ? nlohmann::json(rounds) : nlohmann::json(rounds_formula);
    j["outputs"] = outputs;
    j["params"] = describe_params(params);
    if (!inputs.empty()) {
      nlohmann::json in = nlohmann::json::array();
      for (const InputSpec& i : inputs) in.push_back(i.to_json());
      j["inputs"] = std::move(in);
    }
    return j;
  }
};

// The describe() string of a plugin: a JSON array of its methods' to_json().
inline std::string describe_methods(const std::vector<MethodDescription>& methods) {
  nlohmann::json a = nlohmann::json::array();
  for (const MethodDescription& m : methods) a.push_back(m.to_json());
  return a.dump();
}

}  // namespace procam::sdk
