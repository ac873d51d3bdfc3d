// SPDX-License-Identifier: MIT
// Method parameters declared once (ParamSpec) and used twice: to describe the
// method (describe() JSON) and to validate the params_json a session gets.
//
// parse_params() rejects unknown keys, wrong types and out-of-range values
// with messages such as
//   parameter 'bits' must be an integer in 1..16, got "x"
//   unknown parameter 'bitz' for method 'gray' (known: rows, binarize)
// and fills every parameter the caller left out with its default.
// Errors: PROCAM_ERR_INVALID_ARGUMENT; nothing throws except std::bad_alloc.
// Thread-safety: reentrant; ParamSpec lists are normally immutable globals.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/sdk/error.hpp"

namespace procam::sdk {

enum class ParamType { boolean, integer, number, string };

struct ParamSpec {
  std::string name;            // lower_snake_case
  ParamType type = ParamType::number;
  nlohmann::json default_value;
  double min = -std::numeric_limits<double>::infinity();  // integer/number range, inclusive
  double max = std::numeric_limits<double>::infinity();
  std::vector<std::string> choices;  // string: allowed values (empty = any string)
  std::string description;           // what it does and why its default
};

inline const char* param_type_name(ParamType t) noexcept {
  switch (t) {
    case ParamType::boolean: return "bool";
    case ParamType::integer: return "int";
    case ParamType::number: return "number";
    default: return "string";
  }
}

namespace detail {
inline std::string format_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}
// The expectation in words: "an integer in 1..16", "a number >= 0", ...
inline std::string expectation(const ParamSpec& s) {
  std::string what;
  switch (s.type) {
    case ParamType::boolean: return "true or false";
    case ParamType::integer: what = "an integer"; break;
    case ParamType::number: what = "a number"; break;
    case ParamType::string:
      if (s.choices.empty()) return "a string";
      what = "one of ";
      for (size_t i = 0; i < s.choices.size(); ++i)
        what += (i ? ", \"" : "\"") + s.choices[i] + "\"";
      return what;
  }
  const bool lo = std::isfinite(s.min), hi = std::isfinite(s.max);
  if (lo && hi) return what + " in " + format_number(s.min) + ".." + format_number(s.max);
  if (lo) return what + " >= " + format_number(s.min);
  if (hi) return what + " <= " + format_number(s.max);
  return what;
}
// A short rendering of the offending value for messages.
inline std::string shown(const nlohmann::json& v) {
  std::string s = v.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}
}  // namespace detail

// describe() form of one method's parameters:
// [{"name":..,"type":"bool","default":..,"min":..,"max":..,"choices":[..],"description":..}]
inline nlohmann::json describe_params(const std::vector<ParamSpec>& specs) {
  nlohmann::json arr = nlohmann::json::array();
  for (const ParamSpec& s : specs) {
    nlohmann::json j = {{"name", s.name},
                        {"type", param_type_name(s.type)},
                        {"default", s.default_value},
                        {"description", s.description}};
    if (std::isfinite(s.min)) j["min"] = s.min;
    if (std::isfinite(s.max)) j["max"] = s.max;
    if (!s.choices.empty()) j["choices"] = s.choices;
    arr.push_back(std::move(j));
  }
  return arr;
}

class Params;
inline Error parse_params(const nlohmann::json& in, const std::vector<ParamSpec>& specs,
                          Params& out, const std::string& method);

// Validated parameter values (every spec present, defaults filled in).
class Params {
 public:
  // Accessors for names the spec declared with that type; a wrong name or
  // type is a plugin bug and throws nlohmann::json::exception.
  bool get_bool(const std::string& name) const { return values_.at(name).get<bool>(); }
  int64_t get_int(const std::string& name) const { return values_.at(name).get<int64_t>(); }
  double get_number(const std::string& name) const { return values_.at(name).get<double>(); }
  std::string get_string(const std::string& name) const {
    return values_.at(name).get<std::string>();
  }
  // All values as one object, e.g. for a report.
  const nlohmann::json& json() const noexcept { return values_; }

 private:
  friend Error parse_params(const nlohmann::json&, const std::vector<ParamSpec>&, Params&,
                            const std::string&);
  nlohmann::json values_ = nlohmann::json::object();
};

// Validate `in` (a JSON object, or null meaning {}) against `specs` for
// method `method` and fill `out`. Integers may be written as 3 or 3.0.
inline Error parse_params(const nlohmann::json& in, const std::vector<ParamSpec>& specs,
                          Params& out, const std::string& method) {
  if (!in.is_null() && !in.is_object())
    return invalid_argument("params for method '" + method + "' must be a JSON object, got " +
                            detail::shown(in));
  nlohmann::json values = nlohmann::json::object();
  for (const ParamSpec& s : specs) values[s.name] = s.default_value;
  if (in.is_object()) {
    for (auto it = in.begin(); it != in.end(); ++it) {
      const std::string& key = it.key();  // (no structured binding: captured below)
      const nlohmann::json& v = it.value();
      const ParamSpec* spec = nullptr;
      for (const ParamSpec& s : specs)
        if (s.name == key) spec = &s;
      if (spec == nullptr) {
        std::string known;
        for (const ParamSpec& s : specs) known += (known.empty() ? "" : ", ") + s.name;
        return invalid_argument("unknown parameter '" + key + "' for method '" + method +
                                "' (known: " + (known.empty() ? "none" : known) + ")");
      }
      const auto fail = [&] {
        return invalid_argument("parameter '" + key + "' must be " + detail::expectation(*spec) +
                                ", got " + detail::shown(v));
      };
      switch (spec->type) {
        case ParamType::boolean:
          if (!v.is_boolean()) return fail();
          values[key] = v;
          break;
        case ParamType::integer: {
          if (!v.is_number()) return fail();
          const double d = v.get<double>();
          if (!std::isfinite(d) || d != std::floor(d) || d < spec->min || d > spec->max ||
              std::abs(d) > 9.0e15)
            return fail();
          values[key] = v.is_number_float() ? nlohmann::json(static_cast<int64_t>(d)) : v;
          break;
        }
        case ParamType::number: {
          if (!v.is_number()) return fail();
          const double d = v.get<double>();
          if (!std::isfinite(d) || d < spec->min || d > spec->max) return fail();
          values[key] = d;
          break;
        }
        case ParamType::string: {
          if (!v.is_string()) return fail();
          if (!spec->choices.empty()) {
            bool found = false;
            for (const std::string& c : spec->choices) found = found || (c == v.get<std::string>());
            if (!found) return fail();
          }
          values[key] = v;
          break;
        }
      }
    }
  }
  out.values_ = std::move(values);
  return ok();
}

}  // namespace procam::sdk
