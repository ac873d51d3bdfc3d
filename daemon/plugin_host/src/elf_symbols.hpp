// SPDX-License-Identifier: MIT
// Minimal, defensive ELF64 reader: finds a symbol in .dynsym and reads its
// bytes from the file, without loading (dlopen) anything.
//
// Used to check a plugin's procam_plugin_info before any plugin code runs (as
// libcamera does for IPA modules). Only ELF64 little-endian shared objects
// (e_type ET_DYN) are accepted; everything else is corrupt_data.
//
// Contract:
//   - Every offset, size, count and string index read from the file is
//     bounds-checked against the file size before use. Malformed input gives
//     Code::corrupt_data with a message naming the structure and the numbers
//     involved; it never crashes, throws or reads outside the file.
//   - Messages describe the problem only; callers add which file it was.
//   - Errors: io_error (cannot open/read), corrupt_data (malformed or not an
//     ELF64 LE shared object), not_found (no such defined dynamic symbol).
//   - Threads: an ElfFile is immutable after open(); const calls are safe from
//     any thread (reads use pread, no shared file position).
//   - Ownership: ElfFile owns its file descriptor (or its byte copy); move-only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "procam/core/status.hpp"

namespace procam::host::elf {

// One defined entry of .dynsym.
struct Symbol {
  std::string name;
  uint64_t value = 0;    // st_value (virtual address)
  uint64_t size = 0;     // st_size
  uint16_t section = 0;  // st_shndx
  uint8_t type = 0;      // STT_* (STT_OBJECT, STT_FUNC, ...)
  uint8_t bind = 0;      // STB_* (STB_GLOBAL, STB_WEAK, ...)
};

class ElfFile {
public:
  // Opens and parses the headers of `path` (must be a regular file). The file
  // stays open (O_RDONLY | O_CLOEXEC) until the ElfFile dies.
  static Result<ElfFile> open(const std::string& path);
  // Same checks on an in-memory copy of a file (tests, fuzzing).
  static Result<ElfFile> from_bytes(std::vector<uint8_t> bytes);

  ElfFile(ElfFile&& other) noexcept;
  ElfFile& operator=(ElfFile&& other) noexcept;
  ElfFile(const ElfFile&) = delete;
  ElfFile& operator=(const ElfFile&) = delete;
  ~ElfFile();

  uint16_t machine() const { return machine_; }  // e_machine (EM_X86_64, ...)
  uint64_t file_size() const { return size_; }

  // The first *defined* dynamic symbol called `name` (undefined = imported
  // symbols are skipped). not_found if there is none.
  Result<Symbol> find_symbol(std::string_view name) const;

  // Reads the first `n` bytes of `sym`'s data from the file: the symbol must
  // be STT_OBJECT, have st_size >= n, and lie wholly inside its allocated
  // section; SHT_NOBITS (.bss) sections read as zeros.
  Result<std::vector<uint8_t>> read_symbol(const Symbol& sym, size_t n) const;

private:
  ElfFile() = default;
  Status parse();
  // Reads [offset, offset + n) of the file into dst; corrupt_data naming
  // `what` if that range is not inside the file.
  Status read_at(uint64_t offset, void* dst, size_t n, const char* what) const;

  struct Section {
    uint32_t type = 0;
    uint64_t flags = 0, addr = 0, offset = 0, size = 0, entsize = 0;
    uint32_t link = 0;
  };

  int fd_ = -1;
  std::vector<uint8_t> bytes_;  // used when fd_ < 0
  uint64_t size_ = 0;
  uint16_t machine_ = 0;
  std::vector<Section> sections_;
  uint64_t dynsym_entsize_ = 24;
  std::vector<uint8_t> dynsym_;  // raw .dynsym
  std::vector<uint8_t> dynstr_;  // raw .dynstr (linked from .dynsym)
};

// Convenience: open `path`, find defined dynamic symbol `symbol`, read `n`
// bytes of it (see ElfFile::read_symbol for the rules).
Result<std::vector<uint8_t>> read_symbol(const std::string& path, std::string_view symbol,
                                         size_t n);

// Human-readable machine name for messages ("x86-64", "AArch64", "machine 42").
std::string machine_name(uint16_t e_machine);
// e_machine of the host process's own architecture; 0 if unknown here.
uint16_t host_machine();

}  // namespace procam::host::elf
