// SPDX-License-Identifier: MIT
// Helpers shared by the plugin loading steps and Session (see plugin_loader.hpp);
// the steps themselves: plugin_info_check.cpp (ELF), plugin_probe.cpp (forked
// probe), plugin_dlopen_check.cpp (dlopen + checks).
#include "plugin_loader.hpp"

#include <dlfcn.h>

#include <cstddef>
#include <cstdio>
#include <cstring>

namespace procam::host::detail {

std::string quoted(const std::string& file) { return "plugin '" + file + "'"; }

LoadedPlugin::~LoadedPlugin() {
  if (handle != nullptr && unload) ::dlclose(handle);
}

Create2Fn create2_of(const LoadedPlugin& plugin) {
  const procam_plugin_vtable& vt = *plugin.vtable;
  constexpr size_t need = offsetof(procam_plugin_vtable, session_create2) + sizeof(vt.session_create2);
  if (plugin.abi < 2 || vt.struct_size < need) return nullptr;  // the field is not there
  return vt.session_create2;
}

bool valid_plugin_name(std::string_view s) {
  if (s.empty() || s.size() > 63) return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-')) return false;
  return true;
}

bool valid_output_name(std::string_view s) {
  if (s.empty() || s.size() > 64) return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_')) return false;
  return true;
}

std::string printable(std::string_view s, size_t max_len) {
  std::string out;
  for (size_t i = 0; i < s.size() && i < max_len; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7f && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
  }
  if (s.size() > max_len) out += "...";
  return out;
}

std::string error_message(const procam_error& err) {
  const size_t n = ::strnlen(err.message, sizeof err.message);
  std::string m(err.message, n);
  return m.empty() ? std::string("(the plugin gave no message)") : m;
}

Code code_for_rc(int rc) {
  switch (rc) {
    case PROCAM_ERR_INVALID_ARGUMENT: return Code::invalid_argument;
    case PROCAM_ERR_BAD_FRAME: return Code::corrupt_data;
    case PROCAM_ERR_STATE: return Code::failed_precondition;
    case PROCAM_ERR_FAILED_PRECONDITION: return Code::failed_precondition;
    default: return Code::plugin_error;
  }
}

std::string rc_name(int rc) {
  const char* name = procam_rc_name(rc);  // plugin_abi.h, shared with the SDK
  return name != nullptr ? std::string(name) : "undocumented return code " + std::to_string(rc);
}

const char* phase_text(Phase p) {
  switch (p) {
    case Phase::none: return "before loading started";
    case Phase::dlopen: return "in dlopen (its static constructors or libraries it depends on)";
    case Phase::create: return "in procam_plugin_create()";
    case Phase::vtable: return "while its function table was checked";
    case Phase::describe: return "in describe()";
    case Phase::done: return "after all checks passed";
  }
  return "at an unknown step";
}

}  // namespace procam::host::detail
