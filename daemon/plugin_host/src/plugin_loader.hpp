// SPDX-License-Identifier: MIT
// Internal steps of loading one plugin file: read + check its info from the
// ELF file (plugin_info_check.cpp), probe it in a child process
// (plugin_probe.cpp), dlopen + check it in this process (plugin_dlopen_check.cpp).
//
// Every function returns a Status whose message starts with "plugin '<file>'"
// and says what was found and what to do. Nothing throws.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/plugin_abi.h"

namespace procam::host::detail {

// A plugin library loaded into this process. Owns the dlopen handle (closed
// when the last Session and the PluginHost entry using it are gone).
// Immutable after construction; safe to share between threads.
struct LoadedPlugin {
  std::string name;
  std::string file;
  void* handle = nullptr;
  const procam_plugin_vtable* vtable = nullptr;
  uint32_t abi = PROCAM_PLUGIN_ABI_VERSION;  // the ABI its table and plans follow (1, 2 or 3)
  bool unload = true;  // dlclose on destruction (false in the probe child)

  LoadedPlugin() = default;
  LoadedPlugin(const LoadedPlugin&) = delete;
  LoadedPlugin& operator=(const LoadedPlugin&) = delete;
  ~LoadedPlugin();
};

// The plugin's session_create2 (plugin_abi.h "Scan inputs"), or nullptr for an
// ABI 1 table or a v2 table that left it NULL (methods without inputs).
using Create2Fn = int (*)(const char*, const char*, const char*, const procam_output*, uint32_t,
                          procam_session**, procam_error*);
Create2Fn create2_of(const LoadedPlugin& plugin);

// What step 1 found in the file.
struct FileInfo {
  procam_plugin_info info{};         // exact bytes of the symbol in the file
  std::vector<std::string> methods;  // info.methods split on ',' and validated
};

// Step 1: reads procam_plugin_info from the ELF file without loading it and
// checks machine, magic, ABI version, struct size, strings, names, and that
// procam_plugin_create is defined. No plugin code runs.
Result<FileInfo> read_plugin_info(const std::string& path);

// Where step 3 got to; the probe child reports each phase to its parent so a
// crash or hang can be blamed on the right step.
enum class Phase : uint8_t { none = 0, dlopen, create, vtable, describe, done };
const char* phase_text(Phase p);

struct Checked {
  std::shared_ptr<LoadedPlugin> plugin;
  std::vector<MethodInfo> methods;
};

// Step 3 (and what the probe child does): dlopen(RTLD_NOW | RTLD_LOCAL),
// compare the in-memory procam_plugin_info with the file's, call
// procam_plugin_create(<the file's ABI version>), check the vtable and the
// describe() JSON (with each method's "inputs"). `on_phase` is called before each step. Runs plugin code:
// a broken plugin may crash or hang the calling process (hence step 2).
// `unload` false: never dlclose (the probe child, which _exits: the plugin's
// static destructors must not run there and blur the report).
Result<Checked> load_and_check(const std::string& path, const FileInfo& file,
                               const std::function<void(Phase)>& on_phase, bool unload = true);

// Step 2: runs load_and_check in a fork()ed child and waits up to `timeout`.
// Crash (signal) -> plugin_error, hang -> timeout (child killed), failure ->
// the child's Status. Must be called while the process is single-threaded.
Status probe_in_child(const std::string& path, const FileInfo& file,
                      std::chrono::milliseconds timeout);

// Helpers shared by the steps (plugin_loader.cpp) and with Session.
// "plugin '<file>'": how every loader message names the file.
std::string quoted(const std::string& file);
bool valid_plugin_name(std::string_view s);  // [a-z0-9_-]{1,63}
bool valid_output_name(std::string_view s);  // [a-z0-9_]{1,64}
// A printable rendering of untrusted text for messages (non-printables as \xNN).
std::string printable(std::string_view s, size_t max_len = 80);
// The plugin's error message, copied up to the first NUL or the buffer end.
std::string error_message(const procam_error& err);
// "PROCAM_ERR_BAD_FRAME" etc.; "undocumented return code N" otherwise.
std::string rc_name(int rc);
// The Status code for a plugin's error return: the caller's fault
// (invalid argument, bad frame, call order) keeps its meaning so clients can
// react; anything else is the plugin's failure (plugin_error).
Code code_for_rc(int rc);

}  // namespace procam::host::detail
