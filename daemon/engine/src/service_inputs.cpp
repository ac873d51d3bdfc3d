// SPDX-License-Identifier: MIT
// ScanService: a scan request's inputs (PROTOCOL.md 5.4 "inputs") resolved to
// the stored outputs of finished scans and read into memory at submit time,
// so every problem is the request's error reply and nothing is queued.
#include "procam/engine/inputs.hpp"
#include "procam/engine/service.hpp"
#include "service_internal.hpp"

#include <filesystem>

namespace procam::engine {
namespace fs = std::filesystem;

Result<LoadedInputs> ScanService::load_inputs(const ScanRequest& req) const {
  try {
    return load_inputs_impl(req);
  } catch (const std::exception& e) {  // a manifest edited by hand, out of memory: never take the daemon down
    return Error(Code::internal, std::string("reading the scan's inputs: ") + e.what());
  }
}

Result<LoadedInputs> ScanService::load_inputs_impl(const ScanRequest& req) const {
  LoadedInputs out;
  const auto [cam_w, cam_h] = camera0_size(plugin_rig_json_);
  for (const auto& [name, src] : req.inputs) {
    const std::string at = "input '" + name + "'";
    const std::string scan = "scan '" + src.scan_id + "'";
    {
      std::lock_guard lock(mu_);
      auto it = scans_.find(src.scan_id);
      if (it == scans_.end())
        return Error(Code::not_found, at + " names " + scan + ", which this daemon does not have",
                     "check the scan id (procam status --scan ID); deleted scans cannot be used");
      const Record& r = *it->second;
      if (!service_detail::is_final(r.state))
        return Error(Code::failed_precondition, at + " names " + scan + ", which is still " + r.state,
                     "wait until it is done (its final state event, or poll status), then send this scan again");
      if (r.state == "failed")
        return Error(Code::failed_precondition,
                     at + " names " + scan + ", which failed" +
                         (r.error.ok() ? std::string() : " (" + r.error.message() + ")") + ": it has no outputs to use",
                     "scan again and use the new scan's id");
    }
    auto manifest = this->manifest(src.scan_id);
    if (!manifest) return manifest.status().with_context(at);
    const nlohmann::json* entry = nullptr;  // into `outputs`
    std::string names;
    const nlohmann::json& outputs = (*manifest)["outputs"];
    if (!outputs.is_array())
      return Error(Code::corrupt_data, at + ": the manifest of " + scan + " has no outputs list",
                   "tell the operator: the results folder was changed by hand");
    for (const auto& o : outputs) {
      if (!o.is_object()) continue;
      const std::string n = o.value("name", "");
      names += (names.empty() ? "" : ", ") + n;
      if (n == src.output) entry = &o;
    }
    if (entry == nullptr)
      return Error(Code::not_found, at + ": " + scan + " has no output '" + src.output + "'",
                   "its outputs: " + (names.empty() ? std::string("none") : names));
    const std::string kind = entry->value("kind", "");
    const auto file = entry->find("file");
    if (kind != "image" || file == entry->end() || !file->is_string())
      return Error(Code::invalid_argument,
                   at + ": output '" + src.output + "' of " + scan + " is a " + kind + ", not a map",
                   "inputs are per-pixel maps stored as exr-f32, e.g. depth_mm");
    if (entry->value("format", "") != "exr-f32")
      return Error(Code::invalid_argument,
                   at + ": output '" + src.output + "' of " + scan + " is a " + entry->value("format", "") +
                       " image; the input needs a float map (image_f32, stored as exr-f32)",
                   "name a float output such as depth_mm, not a mask or a class map");
    auto path = file_path(src.scan_id, file->get<std::string>());
    if (!path) return path.status().with_context(at);
    auto img = read_input_map(name, *path, "output " + src.output + " of " + scan, cam_w, cam_h);
    if (!img) return img.status();
    out.add(name, entry->value("unit", ""), src.output + " of scan " + src.scan_id, std::move(*img));
  }
  return out;
}

}  // namespace procam::engine
