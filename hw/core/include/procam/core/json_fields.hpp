// SPDX-License-Identifier: MIT
// Strict reading of JSON config fields with errors that name the source and
// the field path ("scenes/x.json: objects[2].radius_mm: must be > 0"); shared
// by every config parser of the hardware layer (sim scenes and rigs, device backends).
//
// Usage: construct a FieldReader per JSON object, read fields, then check
// `error()`. The first error is latched; later reads return defaults and do
// not overwrite it, so parse code can read everything and check once.
// Never throws (only uses non-throwing nlohmann accessors).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/base/geometry.hpp"
#include "procam/core/status.hpp"

namespace procam {

// Shared error latch for one parse (one file).
struct ParseErrors {
  std::string source;  // file name or "rig config"
  Status first;
  void fail(const std::string& field_path, const std::string& what, const std::string& hint = {}) {
    if (!first.ok()) return;
    first = Error(Code::invalid_argument, source + ": " + field_path + ": " + what, hint);
  }
  bool ok() const { return first.ok(); }
};

inline const char* json_type_name(const nlohmann::json& j) { return j.type_name(); }

class FieldReader {
public:
  // `obj` must outlive the reader. `path` is this object's path ("objects[2]"),
  // empty for the root.
  FieldReader(const nlohmann::json& obj, std::string path, ParseErrors& errors)
      : obj_(obj), path_(std::move(path)), errors_(errors) {
    if (!obj_.is_object()) errors_.fail(path_.empty() ? "(root)" : path_,
                                        std::string("must be a JSON object, got ") + json_type_name(obj_));
  }

  std::string field(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  const std::string& path() const { return path_; }
  bool has(const char* key) const { return obj_.is_object() && obj_.contains(key); }
  const nlohmann::json* get(const char* key) const {
    if (!obj_.is_object()) return nullptr;
    auto it = obj_.find(key);
    return it == obj_.end() ? nullptr : &*it;
  }
  void fail(const char* key, const std::string& what, const std::string& hint = {}) {
    errors_.fail(field(key), what, hint);
  }
  ParseErrors& errors() { return errors_; }

  // Required number (`def` empty) or optional with default; finite; within [lo, hi].
  double number(const char* key, std::optional<double> def, const char* unit_note = "",
                double lo = -std::numeric_limits<double>::infinity(),
                double hi = std::numeric_limits<double>::infinity()) {
    const nlohmann::json* v = get(key);
    if (v == nullptr) {
      if (def) return *def;
      fail(key, std::string("missing (required number") + (*unit_note ? std::string(", ") + unit_note : "") + ")");
      return 0;
    }
    if (!v->is_number()) {
      fail(key, std::string("must be a number, got ") + json_type_name(*v));
      return def.value_or(0);
    }
    const double x = v->get<double>();
    if (!std::isfinite(x) || x < lo || x > hi) {
      fail(key, "must be in [" + num_str(lo) + ", " + num_str(hi) + "], got " + num_str(x));
      return def.value_or(0);
    }
    return x;
  }
  // Number that must be > lo (exclusive).
  double positive(const char* key, std::optional<double> def, const char* unit_note = "") {
    double x = number(key, def, unit_note);
    if (errors_.ok() && !(x > 0)) {
      fail(key, "must be > 0, got " + num_str(x));
    }
    return x;
  }
  // Non-negative integer within [lo, hi].
  uint64_t integer(const char* key, std::optional<uint64_t> def, uint64_t lo, uint64_t hi) {
    const nlohmann::json* v = get(key);
    if (v == nullptr) {
      if (def) return *def;
      fail(key, "missing (required integer)");
      return 0;
    }
    if (!v->is_number_integer() || (v->is_number_integer() && !v->is_number_unsigned() && v->get<int64_t>() < 0)) {
      fail(key, std::string("must be a non-negative integer, got ") + v->dump());
      return def.value_or(lo);
    }
    const uint64_t x = v->get<uint64_t>();
    if (x < lo || x > hi) {
      fail(key, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + std::to_string(x));
      return def.value_or(lo);
    }
    return x;
  }
  bool boolean(const char* key, bool def) {
    const nlohmann::json* v = get(key);
    if (v == nullptr) return def;
    if (!v->is_boolean()) {
      fail(key, std::string("must be true or false, got ") + json_type_name(*v));
      return def;
    }
    return v->get<bool>();
  }
  std::string string(const char* key, std::optional<std::string> def) {
    const nlohmann::json* v = get(key);
    if (v == nullptr) {
      if (def) return *def;
      fail(key, "missing (required string)");
      return {};
    }
    if (!v->is_string()) {
      fail(key, std::string("must be a string, got ") + json_type_name(*v));
      return def.value_or("");
    }
    return v->get<std::string>();
  }
  // Array of exactly n finite numbers.
  template <size_t N>
  std::array<double, N> numbers(const char* key, std::optional<std::array<double, N>> def, const char* unit_note = "") {
    const nlohmann::json* v = get(key);
    if (v == nullptr) {
      if (def) return *def;
      fail(key, "missing (required array of " + std::to_string(N) + " numbers" +
                    (*unit_note ? std::string(", ") + unit_note : "") + ")");
      return {};
    }
    std::array<double, N> out{};
    if (!v->is_array() || v->size() != N) {
      fail(key, "must be an array of " + std::to_string(N) + " numbers, got " + v->dump());
      return def.value_or(out);
    }
    for (size_t i = 0; i < N; ++i) {
      const auto& e = (*v)[i];
      if (!e.is_number() || !std::isfinite(e.get<double>())) {
        fail(key, "must be an array of " + std::to_string(N) + " finite numbers, element " +
                      std::to_string(i) + " is " + e.dump());
        return def.value_or(out);
      }
      out[i] = e.get<double>();
    }
    return out;
  }
  Vec3 vec3(const char* key, std::optional<Vec3> def, const char* unit_note = "") {
    std::optional<std::array<double, 3>> d;
    if (def) d = std::array<double, 3>{def->x, def->y, def->z};
    auto a = numbers<3>(key, d, unit_note);
    return {a[0], a[1], a[2]};
  }
  // Sub-object (required unless `optional`); nullptr if absent or wrong type.
  const nlohmann::json* object(const char* key, bool required) {
    const nlohmann::json* v = get(key);
    if (v == nullptr) {
      if (required) fail(key, "missing (required object)");
      return nullptr;
    }
    if (!v->is_object()) {
      fail(key, std::string("must be a JSON object, got ") + json_type_name(*v));
      return nullptr;
    }
    return v;
  }
  // Reject keys not in `known` (catches typos such as "radius" for "radius_mm").
  void only(std::initializer_list<const char*> known) {
    only(std::vector<std::string>(known.begin(), known.end()));
  }
  // The same for a key list built at run time (e.g. a backend's keys plus the
  // calibration keys its caller handles); `hint` replaces the default
  // "known fields here: ..." hint when given.
  void only(const std::vector<std::string>& known, const std::string& hint = {}) {
    if (!obj_.is_object()) return;
    for (auto it = obj_.begin(); it != obj_.end(); ++it) {
      bool found = false;
      for (const std::string& k : known) found = found || it.key() == k;
      if (!found) {
        std::string list;
        for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
        fail(it.key().c_str(), "unknown field", hint.empty() ? "known fields here: " + list : hint);
        return;
      }
    }
  }
  // A device chosen by name or index ("monitor": "HDMI-1" or 0): the string,
  // or the index written in decimal; `def` when absent.
  std::string name_or_index(const char* key, const std::string& def) {
    const nlohmann::json* v = get(key);
    if (v == nullptr) return def;
    if (v->is_string()) return v->get<std::string>();
    if (v->is_number_integer() && (v->is_number_unsigned() || v->get<int64_t>() >= 0))
      return std::to_string(v->get<uint64_t>());
    fail(key, std::string("must be a name or a non-negative index, got ") + v->dump());
    return def;
  }

  static std::string num_str(double x) {
    if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
    nlohmann::json j = x;
    return j.dump();
  }

private:
  const nlohmann::json& obj_;
  std::string path_;
  ParseErrors& errors_;
};

}  // namespace procam
