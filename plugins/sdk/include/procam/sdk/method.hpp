// SPDX-License-Identifier: MIT
// MethodDescription: a typed description of one decoder method, serialised by
// to_json() into the entry describe() returns for it (and the daemon forwards
// in list_plugins, proto/PROTOCOL.md §5.2), so plugins stop hand-writing
// describe() JSON. Every key is documented in plugins/sdk/README.md.
//
// JSON form (an object; nlohmann::json orders keys by name):
//   {"name", "description", "patterns" (integer or null), ["patterns_formula"],
//    "rounds" (integer, or a string when it depends on the scene/params),
//    "outputs" [names], "params" [describe_params()]}
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

  nlohmann::json to_json() const {
    if (name.empty() || summary.empty())
      throw std::invalid_argument("method description: name and summary are required");
    for (const std::string& o : outputs)
      if (!is_output_name(o))
        throw std::invalid_argument("method '" + name + "': output name '" + o +
                                    "' is not lower_snake_case");
    nlohmann::json j = nlohmann::json::object();
    j["name"] = name;
    j["description"] = summary;
    j["patterns"] = patterns ? nlohmann::json(*patterns) : nlohmann::json(nullptr);
    if (!patterns_formula.empty()) j["patterns_formula"] = patterns_formula;
    j["rounds"] = rounds_formula.empty() ? nlohmann::json(rounds) : nlohmann::json(rounds_formula);
    j["outputs"] = outputs;
    j["params"] = describe_params(params);
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
