// SPDX-License-Identifier: MIT
// Loading one plugin file, step 1: read and check procam_plugin_info straight
// from the ELF file (no plugin code runs). See plugin_loader.hpp.
#include <elf.h>

#include <cstdio>
#include <cstring>
#include <optional>
#include <set>

#include "elf_symbols.hpp"
#include "plugin_loader.hpp"

namespace procam::host::detail {
namespace {

std::string hex32(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08x", v);
  return buf;
}

// A fixed-size char field of procam_plugin_info as a string; nullopt if it
// has no NUL inside its size.
std::optional<std::string> field_string(const char* field, size_t size) {
  const void* nul = std::memchr(field, 0, size);
  if (nul == nullptr) return std::nullopt;
  return std::string(field, static_cast<size_t>(static_cast<const char*>(nul) - field));
}

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return std::string(s);
}

}  // namespace

Result<FileInfo> read_plugin_info(const std::string& path) {
  const std::string who = quoted(path);
  auto elf_file = elf::ElfFile::open(path);
  if (!elf_file.ok()) {
    const Status& e = elf_file.status();
    if (e.code() == Code::corrupt_data)
      return Error(Code::corrupt_data, who + " is not a valid plugin library: " + e.message() +
                                           ": remove it from the plugin directory or rebuild it");
    return e.with_context(who);
  }
  const elf::ElfFile& f = *elf_file;
  const uint16_t host = elf::host_machine();
  if (host != 0 && f.machine() != host)
    return Error(Code::abi_mismatch, who + " was built for " + elf::machine_name(f.machine()) +
                                         ", this procamd runs on " + elf::machine_name(host) +
                                         ": rebuild the plugin for this machine");

  auto sym = f.find_symbol(PROCAM_PLUGIN_INFO_SYMBOL);
  if (!sym.ok()) {
    if (sym.status().code() == Code::not_found)
      return Error(Code::corrupt_data,
                   who + " exports no '" PROCAM_PLUGIN_INFO_SYMBOL
                         "' symbol: it is not a procam decoder plugin (plugins export "
                         "procam_plugin_info and procam_plugin_create, see plugin_abi.h)");
    return Error(Code::corrupt_data,
                 who + " is not a valid plugin library: " + sym.status().message());
  }

  // Header first (magic, versions), so an older/newer ABI with a different
  // struct size is reported as an ABI mismatch, not as a size problem.
  constexpr size_t kHeader = 3 * sizeof(uint32_t);
  auto head = f.read_symbol(*sym, kHeader);
  if (!head.ok())
    return Error(Code::corrupt_data,
                 who + ": cannot read its procam_plugin_info: " + head.status().message());
  uint32_t magic = 0, abi = 0, size = 0;
  std::memcpy(&magic, head->data(), 4);
  std::memcpy(&abi, head->data() + 4, 4);
  std::memcpy(&size, head->data() + 8, 4);
  if (magic != PROCAM_PLUGIN_MAGIC)
    return Error(Code::corrupt_data, who + " has procam_plugin_info magic " + hex32(magic) +
                                         ", expected " + hex32(PROCAM_PLUGIN_MAGIC) +
                                         " (\"PCPI\"): the file is corrupt or not a procam plugin");
  // ABI 2 hosts still load ABI 1 plugins (plugin_abi.h "Version history").
  if (abi < PROCAM_PLUGIN_ABI_VERSION_MIN || abi > PROCAM_PLUGIN_ABI_VERSION)
    return Error(Code::abi_mismatch,
                 who + " was built for plugin ABI " + std::to_string(abi) +
                     ", this procamd speaks ABI " + std::to_string(PROCAM_PLUGIN_ABI_VERSION_MIN) +
                     ".." + std::to_string(PROCAM_PLUGIN_ABI_VERSION) +
                     ": rebuild the plugin against this procamd's plugin_abi.h");
  if (size != sizeof(procam_plugin_info))
    return Error(Code::abi_mismatch,
                 who + " declares plugin ABI " + std::to_string(abi) +
                     " but a procam_plugin_info of " + std::to_string(size) +
                     " bytes, this procamd's is " + std::to_string(sizeof(procam_plugin_info)) +
                     ": it was built against a different plugin_abi.h; rebuild it against "
                     "this procamd's plugin_abi.h");
  auto full = f.read_symbol(*sym, sizeof(procam_plugin_info));
  if (!full.ok())
    return Error(Code::corrupt_data,
                 who + ": cannot read its procam_plugin_info: " + full.status().message());
  FileInfo out;
  std::memcpy(&out.info, full->data(), sizeof out.info);

  auto name = field_string(out.info.name, sizeof out.info.name);
  if (!name)
    return Error(Code::corrupt_data, who +
                                         ": procam_plugin_info.name is not NUL-terminated "
                                         "within its 64 bytes");
  if (!valid_plugin_name(*name))
    return Error(Code::corrupt_data, who + " has invalid plugin name \"" + printable(*name) +
                                         "\": names are 1..63 characters of a-z, 0-9, '_' and '-'");
  auto version = field_string(out.info.version, sizeof out.info.version);
  if (!version)
    return Error(Code::corrupt_data, who +
                                         ": procam_plugin_info.version is not NUL-terminated "
                                         "within its 32 bytes");
  if (version->empty() || printable(*version, version->size()) != *version)
    return Error(Code::corrupt_data, who + " has invalid version \"" + printable(*version) +
                                         "\": it must be non-empty printable ASCII");
  auto methods = field_string(out.info.methods, sizeof out.info.methods);
  if (!methods)
    return Error(Code::corrupt_data, who +
                                         ": procam_plugin_info.methods is not NUL-terminated "
                                         "within its 1024 bytes");
  std::set<std::string> seen;
  size_t pos = 0;
  while (pos <= methods->size()) {
    size_t end = methods->find(',', pos);
    if (end == std::string::npos) end = methods->size();
    std::string m = trim(std::string_view(*methods).substr(pos, end - pos));
    if (!valid_plugin_name(m))
      return Error(Code::corrupt_data,
                   who + " has invalid method list \"" + printable(*methods) +
                       "\": it must be comma-separated names of 1..63 characters of a-z, "
                       "0-9, '_' and '-'");
    if (!seen.insert(m).second)
      return Error(Code::corrupt_data,
                   who + " lists method '" + m + "' twice in procam_plugin_info.methods");
    out.methods.push_back(m);
    pos = end + 1;
  }

  auto create = f.find_symbol(PROCAM_PLUGIN_CREATE_SYMBOL);
  if (!create.ok()) {
    if (create.status().code() == Code::not_found)
      return Error(Code::corrupt_data,
                   who + " exports no '" PROCAM_PLUGIN_CREATE_SYMBOL
                         "' function: a plugin must export procam_plugin_create (see "
                         "plugin_abi.h; C++ plugins need extern \"C\" and default visibility)");
    return Error(Code::corrupt_data,
                 who + " is not a valid plugin library: " + create.status().message());
  }
  if (create->type != STT_FUNC && create->type != STT_GNU_IFUNC)
    return Error(Code::corrupt_data,
                 who + ": '" PROCAM_PLUGIN_CREATE_SYMBOL "' is not a function (symbol type " +
                     std::to_string(create->type) + ")");
  return out;
}

}  // namespace procam::host::detail
