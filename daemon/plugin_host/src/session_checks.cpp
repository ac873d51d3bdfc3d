// SPDX-License-Identifier: MIT
// Checks of plans and outputs a plugin returns (see session_checks.hpp).
#include "session_checks.hpp"

#include <cmath>
#include <cstring>
#include <set>
#include <utility>

#include "plugin_loader.hpp"
#include "procam/core/image.hpp"

namespace procam::host::detail {
namespace {

constexpr uint32_t kMaxFrames = 100000;
constexpr uint32_t kMaxOutputs = 10000;
constexpr size_t kMaxLabel = 255;
constexpr size_t kMaxText = 64 * 1024;        // unit, description, note, point_fields
constexpr size_t kMaxJson = size_t{1} << 30;  // JSON outputs

// Copies a plugin string of at most `max` bytes; error text if it is longer
// (or, as far as we can tell, not NUL-terminated).
bool copy_string(const char* s, size_t max, std::string& out) {
  const size_t n = ::strnlen(s, max + 1);
  if (n > max) return false;
  out.assign(s, n);
  return true;
}

// Labels become parts of file names: no path separators or control chars.
const char* label_problem(const std::string& l) {
  if (l.empty()) return "is empty";
  if (l == "." || l == "..") return "is \".\" or \"..\"";
  for (char c : l) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '/' || c == '\\') return "contains a path separator ('/' or '\\')";
    if (u < 0x20 || u == 0x7f) return "contains a control character";
  }
  return nullptr;
}

}  // namespace

namespace {
// An ABI 1/2 frame in the current layout: same members, light_index 0.
procam_pattern_frame frame_from_v2(const procam_pattern_frame_v2& f) {
  procam_pattern_frame out{};
  out.label = f.label;
  out.pattern = f.pattern;
  const procam_frame_settings_v2& s = f.settings;
  // A correct v2 struct_size becomes the current one; a wrong one stays
  // wrong (the check below reports it with the v2 size expected).
  out.settings.struct_size =
      s.struct_size == sizeof(procam_frame_settings_v2) ? sizeof(procam_frame_settings) : s.struct_size;
  out.settings.camera_index = s.camera_index;
  out.settings.exposure_us = s.exposure_us;
  out.settings.gain_db = s.gain_db;
  out.settings.projector_focus_mm = s.projector_focus_mm;
  out.settings.polarizer_deg = s.polarizer_deg;
  out.settings.projector_polarizer_deg = s.projector_polarizer_deg;
  out.settings.light_index = 0;  // the projector: the only light before ABI 3
  out.settings.reserved3 = 0;
  return out;
}
}  // namespace

Result<Plan> plan_from_abi(const procam_plan* plan, const std::string& who, uint32_t round, uint32_t abi) {
  const std::string bad =
      who + " returned an invalid plan (round " + std::to_string(round) + "): ";
  if (plan == nullptr) return Error(Code::plugin_error, bad + "next_plan returned 1 but no plan");
  if (plan->frame_count == 0)
    return Error(Code::plugin_error, bad + "0 frames (return 0 from next_plan when done)");
  if (plan->frame_count > kMaxFrames)
    return Error(Code::plugin_error, bad + std::to_string(plan->frame_count) +
                                         " frames, more than the limit of " +
                                         std::to_string(kMaxFrames));
  if (plan->frames == nullptr)
    return Error(Code::plugin_error, bad + "frame_count is " + std::to_string(plan->frame_count) +
                                         " but frames is NULL");
  Plan out;
  if (plan->note != nullptr && !copy_string(plan->note, kMaxText, out.note))
    return Error(Code::plugin_error, bad + "note is longer than 64 KiB");
  out.frames.reserve(plan->frame_count);
  for (uint32_t i = 0; i < plan->frame_count; ++i) {
    const bool old = abi < 3;
    const procam_pattern_frame f =
        old ? frame_from_v2(reinterpret_cast<const procam_pattern_frame_v2*>(plan->frames)[i]) : plan->frames[i];
    const std::string at = bad + "frame " + std::to_string(i) + " ";
    PlannedFrame pf;
    if (f.label == nullptr) return Error(Code::plugin_error, at + "has a NULL label");
    if (!copy_string(f.label, kMaxLabel, pf.label))
      return Error(Code::plugin_error, at + "label is longer than 255 bytes");
    if (const char* p = label_problem(pf.label))
      return Error(Code::plugin_error, at + "label \"" + detail::printable(pf.label) + "\" " + p +
                                           " (labels are used in file names)");
    if (const char* p = validate_view(f.pattern))
      return Error(Code::plugin_error, at + "pattern: " + p);
    if (f.pattern.channels != 1)
      return Error(Code::plugin_error, at + "pattern has " + std::to_string(f.pattern.channels) +
                                           " channels, projector patterns must have 1");
    const procam_frame_settings& s = f.settings;
    const size_t want = old ? sizeof(procam_frame_settings_v2) : sizeof(procam_frame_settings);
    if (s.struct_size != sizeof(procam_frame_settings))
      return Error(Code::plugin_error, at + "settings.struct_size is " + std::to_string(s.struct_size) +
                                           ", expected " + std::to_string(want) +
                                           " (set it to sizeof(procam_frame_settings))");
    if (s.camera_index < 0)
      return Error(Code::plugin_error, at + "settings.camera_index is negative");
    if (s.light_index < 0)
      return Error(Code::plugin_error, at + "settings.light_index is negative (0 = the projector, k = light k)");
    if (!std::isfinite(s.exposure_us) || !std::isfinite(s.gain_db) ||
        !std::isfinite(s.projector_focus_mm))
      return Error(Code::plugin_error,
                   at + "settings has a NaN or infinite exposure_us, gain_db or "
                        "projector_focus_mm (use the documented 'rig default' values)");
    if (std::isinf(s.polarizer_deg) || std::isinf(s.projector_polarizer_deg))
      return Error(Code::plugin_error, at + "settings has an infinite polariser angle");
    pf.pattern = f.pattern;
    pf.settings = s;
    out.frames.push_back(std::move(pf));
  }
  return out;
}

Result<std::vector<Output>> outputs_from_abi(const procam_output* outs, uint32_t count,
                                            const std::string& who) {
  const std::string bad = who + " returned invalid outputs: ";
  if (count > kMaxOutputs)
    return Error(Code::plugin_error, bad + std::to_string(count) +
                                         " outputs, more than the limit of " +
                                         std::to_string(kMaxOutputs));
  if (count > 0 && outs == nullptr)
    return Error(Code::plugin_error,
                 bad + "count is " + std::to_string(count) + " but the array is NULL");
  std::vector<Output> result;
  result.reserve(count);
  std::set<std::string> names;
  for (uint32_t i = 0; i < count; ++i) {
    const procam_output& o = outs[i];
    Output r;
    std::string at = bad + "output " + std::to_string(i) + " ";
    if (o.name == nullptr) return Error(Code::plugin_error, at + "has a NULL name");
    if (!copy_string(o.name, 64, r.name) || !detail::valid_output_name(r.name)) {
      std::string shown;
      if (!copy_string(o.name, 64, shown)) shown = std::string(o.name, 64) + "...";
      return Error(Code::plugin_error,
                   at + "has invalid name \"" + detail::printable(shown) +
                       "\": names must be 1..64 characters of a-z, 0-9 and '_' (they become "
                       "file names)");
    }
    at = bad + "output '" + r.name + "' ";
    if (!names.insert(r.name).second) return Error(Code::plugin_error, at + "appears twice");
    if (o.unit != nullptr && !copy_string(o.unit, kMaxText, r.unit))
      return Error(Code::plugin_error, at + "unit is longer than 64 KiB");
    if (o.description != nullptr && !copy_string(o.description, kMaxText, r.description))
      return Error(Code::plugin_error, at + "description is longer than 64 KiB");
    switch (o.kind) {
      case PROCAM_OUTPUT_IMAGE:
        if (const char* p = validate_view(o.image))
          return Error(Code::plugin_error, at + "image: " + p);
        r.image = o.image;
        break;
      case PROCAM_OUTPUT_SCALAR: r.scalar = o.scalar; break;
      case PROCAM_OUTPUT_POINTS:
        if (o.point_count > 0 && o.points == nullptr)
          return Error(Code::plugin_error, at + "has " + std::to_string(o.point_count) +
                                               " points but a NULL points array");
        if (o.point_stride < 3 || o.point_stride > 1024)
          return Error(Code::plugin_error, at + "point_stride is " +
                                               std::to_string(o.point_stride) +
                                               ", expected 3..1024 floats per point");
        if (o.point_count > (uint64_t{1} << 40) / o.point_stride)
          return Error(Code::plugin_error, at + "point_count " + std::to_string(o.point_count) +
                                               " is implausibly large");
        if (o.point_fields != nullptr && !copy_string(o.point_fields, kMaxText, r.point_fields))
          return Error(Code::plugin_error, at + "point_fields is longer than 64 KiB");
        r.points = o.points;
        r.point_count = o.point_count;
        r.point_stride = o.point_stride;
        break;
      case PROCAM_OUTPUT_JSON:
        if (o.json == nullptr) return Error(Code::plugin_error, at + "is JSON but json is NULL");
        if (!copy_string(o.json, kMaxJson, r.json))
          return Error(Code::plugin_error, at + "json is longer than 1 GiB");
        if (!nlohmann::json::accept(r.json))
          return Error(Code::plugin_error,
                       at + "json does not parse: \"" + detail::printable(r.json) + "\"");
        break;
      default:
        return Error(Code::plugin_error, at + "has unknown kind " + std::to_string(o.kind));
    }
    r.kind = static_cast<procam_output_kind>(o.kind);
    result.push_back(std::move(r));
  }
  return result;
}

}  // namespace procam::host::detail
