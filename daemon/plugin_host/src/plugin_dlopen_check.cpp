// SPDX-License-Identifier: MIT
// Loading one plugin file, step 3 (and what the probe child runs): dlopen it
// and check its symbols, function table and describe() JSON. See plugin_loader.hpp.
#include <dlfcn.h>

#include <cstring>
#include <set>

#include "plugin_loader.hpp"

namespace procam::host::detail {
namespace {

template <typename Fn>
Fn symbol_as(void* sym) {
  Fn fn;
  static_assert(sizeof fn == sizeof sym);
  std::memcpy(&fn, &sym, sizeof fn);  // object -> function pointer (POSIX dlsym)
  return fn;
}

// describe()'s "inputs" of one method (plugin_abi.h "Scan inputs"): absent
// or [] = none; otherwise objects with a unique name [a-z0-9_]{1,64}, kind
// "image_f32", optional string unit/description and boolean required
// (default true). ABI 1 plugins cannot take inputs, so they may not declare any.
Status parse_inputs(const nlohmann::json& method, uint32_t abi, std::vector<InputSpec>& out) {
  const auto it = method.find("inputs");
  if (it == method.end() || it->is_null()) return {};
  if (!it->is_array()) return Error(Code::plugin_error, "\"inputs\" must be an array of objects");
  if (!it->empty() && abi < 2)
    return Error(Code::plugin_error, "declares \"inputs\" but was built for plugin ABI " +
                                         std::to_string(abi) + ", which cannot pass them");
  std::set<std::string> seen;
  for (size_t i = 0; i < it->size(); ++i) {
    const nlohmann::json& e = (*it)[i];
    const std::string at = "inputs[" + std::to_string(i) + "]";
    if (!e.is_object() || !e.contains("name") || !e["name"].is_string())
      return Error(Code::plugin_error, at + " is not an object with a string \"name\"");
    InputSpec spec;
    spec.name = e["name"].get<std::string>();
    if (!valid_output_name(spec.name))
      return Error(Code::plugin_error, at + " has name \"" + printable(spec.name) +
                                           "\"; input names are 1..64 characters of a-z, 0-9 and '_'");
    if (!seen.insert(spec.name).second)
      return Error(Code::plugin_error, "input '" + spec.name + "' is listed twice");
    const auto kind = e.find("kind");
    if (kind == e.end() || !kind->is_string() || kind->get<std::string>() != "image_f32")
      return Error(Code::plugin_error, "input '" + spec.name +
                                           "' needs \"kind\": \"image_f32\" (the only kind this procamd knows)");
    spec.kind = kind->get<std::string>();
    for (const char* key : {"unit", "description"}) {
      const auto v = e.find(key);
      if (v == e.end()) continue;
      if (!v->is_string())
        return Error(Code::plugin_error, "input '" + spec.name + "' has a non-string \"" + key + "\"");
      (std::string_view(key) == "unit" ? spec.unit : spec.description) = v->get<std::string>();
    }
    if (const auto r = e.find("required"); r != e.end()) {
      if (!r->is_boolean())
        return Error(Code::plugin_error, "input '" + spec.name + "' has a non-boolean \"required\"");
      spec.required = r->get<bool>();
    }
    out.push_back(std::move(spec));
  }
  return {};
}

}  // namespace

Result<Checked> load_and_check(const std::string& path, const FileInfo& file,
                               const std::function<void(Phase)>& on_phase, bool unload) {
  const std::string who = quoted(path);
  const std::string name(file.info.name);  // NUL-terminated: checked in step 1

  on_phase(Phase::dlopen);
  // A path without '/' would make dlopen search LD_LIBRARY_PATH etc.
  const std::string dl_path = path.find('/') == std::string::npos ? "./" + path : path;
  ::dlerror();
  void* handle = ::dlopen(dl_path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* e = ::dlerror();
    return Error(Code::plugin_error,
                 who + " could not be loaded: " + std::string(e ? e : "dlopen failed") +
                     ": install the libraries it needs or rebuild it");
  }
  auto plugin = std::make_shared<LoadedPlugin>();
  plugin->handle = handle;  // dlclose'd by ~LoadedPlugin on any early return
  plugin->unload = unload;
  plugin->name = name;
  plugin->file = path;

  void* info_sym = ::dlsym(handle, PROCAM_PLUGIN_INFO_SYMBOL);
  void* create_sym = ::dlsym(handle, PROCAM_PLUGIN_CREATE_SYMBOL);
  if (info_sym == nullptr || create_sym == nullptr)
    return Error(Code::corrupt_data,
                 who + ": after loading, " +
                     (info_sym ? PROCAM_PLUGIN_CREATE_SYMBOL : PROCAM_PLUGIN_INFO_SYMBOL) +
                     " cannot be resolved although the file defines it");
  Dl_info di_info{}, di_create{};
  if (::dladdr(info_sym, &di_info) == 0 || ::dladdr(create_sym, &di_create) == 0 ||
      di_info.dli_fbase != di_create.dli_fbase)
    return Error(Code::corrupt_data,
                 who +
                     ": " PROCAM_PLUGIN_INFO_SYMBOL " and " PROCAM_PLUGIN_CREATE_SYMBOL
                     " resolve to different libraries (" +
                     std::string(di_info.dli_fname ? di_info.dli_fname : "?") + ", " +
                     std::string(di_create.dli_fname ? di_create.dli_fname : "?") + ")");
  if (std::memcmp(info_sym, &file.info, sizeof file.info) != 0)
    return Error(Code::corrupt_data,
                 who +
                     ": its procam_plugin_info in memory differs from the file (was the file "
                     "replaced while loading, or does the plugin write to it?)");

  on_phase(Phase::create);
  // Ask for the ABI the file says it was built for (step 1 accepted it):
  // an ABI 1 plugin serves only procam_plugin_create(1).
  const uint32_t abi = file.info.abi_version;
  auto create = symbol_as<procam_plugin_create_fn>(create_sym);
  const procam_plugin_vtable* vt = create(abi);
  if (vt == nullptr)
    return Error(Code::abi_mismatch,
                 who + ": procam_plugin_create(" + std::to_string(abi) +
                     ") returned NULL although its procam_plugin_info declares ABI " +
                     std::to_string(abi) + "; rebuild it against this procamd's plugin_abi.h");

  on_phase(Phase::vtable);
  if (vt->abi_version != abi)
    return Error(Code::abi_mismatch,
                 who + ": procam_plugin_create returned a function table for ABI " +
                     std::to_string(vt->abi_version) + " but its procam_plugin_info declares ABI " +
                     std::to_string(abi) + ": rebuild the plugin against this procamd's plugin_abi.h");
  // Table sizes per version (plugin_abi.h "Version history"): ABI 1 has the
  // first table (up to get_outputs) and the one with session_set_host; ABI 2
  // is the full table with session_create2.
  const bool size_ok = abi == 1 ? (vt->struct_size == PROCAM_PLUGIN_VTABLE_V1_SIZE ||
                                   vt->struct_size == PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE)
                                : vt->struct_size == sizeof(procam_plugin_vtable);
  if (!size_ok)
    return Error(Code::abi_mismatch,
                 who + ": its ABI " + std::to_string(abi) + " function table is " +
                     std::to_string(vt->struct_size) + " bytes (struct_size), expected " +
                     (abi == 1 ? std::to_string(PROCAM_PLUGIN_VTABLE_V1_SIZE) + " or " +
                                     std::to_string(PROCAM_PLUGIN_VTABLE_V1_HOST_SIZE)
                               : std::to_string(sizeof(procam_plugin_vtable))) +
                     ": rebuild the plugin against this procamd's plugin_abi.h");
  std::string missing;
  auto need = [&missing](bool set, const char* fn) {
    if (!set) missing += (missing.empty() ? "" : ", ") + std::string(fn);
  };
  need(vt->describe != nullptr, "describe");
  need(vt->session_create != nullptr, "session_create");
  need(vt->session_destroy != nullptr, "session_destroy");
  need(vt->next_plan != nullptr, "next_plan");
  need(vt->add_frame != nullptr, "add_frame");
  need(vt->end_round != nullptr, "end_round");
  need(vt->get_outputs != nullptr, "get_outputs");
  if (!missing.empty())
    return Error(Code::plugin_error, who + ": its function table has NULL function pointers (" +
                                         missing +
                                         "): every function of procam_plugin_vtable must be set");

  on_phase(Phase::describe);
  const char* text = vt->describe();
  if (text == nullptr)
    return Error(Code::plugin_error, who + ": describe() returned NULL, expected a JSON array");
  constexpr size_t kMaxDescribe = 16u << 20;
  const size_t len = ::strnlen(text, kMaxDescribe + 1);
  if (len > kMaxDescribe)
    return Error(Code::plugin_error, who + ": describe() returned more than 16 MiB");
  auto doc =
      nlohmann::json::parse(std::string_view(text, len), nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded())
    return Error(Code::plugin_error, who + ": describe() did not return valid JSON: \"" +
                                         printable(std::string_view(text, len)) + "\"");
  if (!doc.is_array())
    return Error(Code::plugin_error, who + ": describe() returned JSON " +
                                         std::string(doc.type_name()) +
                                         ", expected an array of method objects");
  Checked out;
  std::set<std::string> described;
  for (size_t i = 0; i < doc.size(); ++i) {
    const auto& m = doc[i];
    const auto n = m.is_object() ? m.find("name") : m.end();
    if (!m.is_object() || n == m.end() || !n->is_string())
      return Error(Code::plugin_error, who + ": describe() entry " + std::to_string(i) +
                                           " is not an object with a string \"name\"");
    const std::string mname = n->get<std::string>();
    if (!described.insert(mname).second)
      return Error(Code::plugin_error,
                   who + ": describe() lists method '" + printable(mname) + "' twice");
    bool listed = false;
    for (const auto& x : file.methods) listed = listed || x == mname;
    if (!listed)
      return Error(Code::plugin_error, who + ": describe() has method '" + printable(mname) +
                                           "' that procam_plugin_info.methods does not list");
    auto d = m.find("description");
    if (d != m.end() && !d->is_string())
      return Error(Code::plugin_error,
                   who + ": describe() method '" + mname + "' has a non-string \"description\"");
  }
  for (const auto& mname : file.methods) {
    if (!described.count(mname))
      return Error(Code::plugin_error,
                   who + ": method '" + mname +
                       "' is listed in procam_plugin_info.methods but not in describe()");
    for (const auto& m : doc) {
      if (m.find("name")->get_ref<const std::string&>() != mname) continue;
      MethodInfo mi;
      mi.name = mname;
      auto d = m.find("description");
      if (d != m.end()) mi.description = d->get<std::string>();
      mi.describe = m;
      if (Status st = parse_inputs(m, abi, mi.inputs); !st.ok())
        return Error(Code::plugin_error, who + ": describe() method '" + mname + "': " + st.message());
      out.methods.push_back(std::move(mi));
    }
  }
  on_phase(Phase::done);
  plugin->vtable = vt;
  plugin->abi = abi;
  out.plugin = std::move(plugin);
  return out;
}

}  // namespace procam::host::detail
