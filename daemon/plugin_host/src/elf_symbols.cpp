// SPDX-License-Identifier: MIT
// Defensive ELF64 little-endian .dynsym reader (see elf_symbols.hpp).
#include "elf_symbols.hpp"

#include <elf.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

namespace procam::host::elf {
namespace {

// Sizes of the ELF64 structures we decode field by field (no struct casts, so
// alignment and host endianness never matter).
constexpr size_t kEhdrSize = 64;
constexpr size_t kShdrSize = 64;
constexpr size_t kSymSize = 24;
// Sanity caps: far above any real plugin, low enough to refuse absurd input.
constexpr uint64_t kMaxSections = 1u << 20;
constexpr uint64_t kMaxTableBytes = 64ull << 20;  // .dynsym / .dynstr

uint16_t le16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t le32(const uint8_t* p) {
  return uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24);
}
uint64_t le64(const uint8_t* p) { return uint64_t{le32(p)} | (uint64_t{le32(p + 4)} << 32); }

std::string hex(uint64_t v) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "0x%llx", static_cast<unsigned long long>(v));
  return buf;
}

Status corrupt(std::string msg) { return Error(Code::corrupt_data, std::move(msg)); }

std::string hex_bytes(const uint8_t* p, size_t n) {
  static const char* digits = "0123456789abcdef";
  std::string s;
  for (size_t i = 0; i < n; ++i) {
    if (i) s += ' ';
    s += digits[p[i] >> 4];
    s += digits[p[i] & 15];
  }
  return s;
}

const char* type_name(uint8_t stt) {
  switch (stt) {
    case STT_NOTYPE: return "an untyped symbol";
    case STT_OBJECT: return "a data object";
    case STT_FUNC: return "a function";
    case STT_SECTION: return "a section symbol";
    case STT_FILE: return "a file symbol";
    case STT_COMMON: return "a common symbol";
    case STT_TLS: return "a thread-local variable";
    case STT_GNU_IFUNC: return "an indirect function";
    default: return "a symbol of unknown type";
  }
}

}  // namespace

std::string machine_name(uint16_t m) {
  switch (m) {
    case EM_386: return "x86 (32-bit)";
    case EM_X86_64: return "x86-64";
    case EM_ARM: return "ARM (32-bit)";
    case EM_AARCH64: return "AArch64";
    case EM_RISCV: return "RISC-V";
    case EM_PPC64: return "PowerPC64";
    case EM_S390: return "S/390";
    default: return "machine " + std::to_string(m);
  }
}

uint16_t host_machine() {
#if defined(__x86_64__)
  return EM_X86_64;
#elif defined(__aarch64__)
  return EM_AARCH64;
#elif defined(__riscv) && __riscv_xlen == 64
  return EM_RISCV;
#elif defined(__powerpc64__)
  return EM_PPC64;
#elif defined(__s390x__)
  return EM_S390;
#else
  return 0;
#endif
}

ElfFile::ElfFile(ElfFile&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)),
      bytes_(std::move(o.bytes_)),
      size_(o.size_),
      machine_(o.machine_),
      sections_(std::move(o.sections_)),
      dynsym_entsize_(o.dynsym_entsize_),
      dynsym_(std::move(o.dynsym_)),
      dynstr_(std::move(o.dynstr_)) {}

ElfFile& ElfFile::operator=(ElfFile&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
    bytes_ = std::move(o.bytes_);
    size_ = o.size_;
    machine_ = o.machine_;
    sections_ = std::move(o.sections_);
    dynsym_entsize_ = o.dynsym_entsize_;
    dynsym_ = std::move(o.dynsym_);
    dynstr_ = std::move(o.dynstr_);
  }
  return *this;
}

ElfFile::~ElfFile() {
  if (fd_ >= 0) ::close(fd_);
}

Result<ElfFile> ElfFile::open(const std::string& path) {
  ElfFile f;
  // O_NONBLOCK: opening a FIFO must not block; we refuse non-regular files below.
  f.fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (f.fd_ < 0) {
    int e = errno;
    return Error(e == ENOENT ? Code::not_found : Code::io_error,
                 "cannot open: " + std::string(std::strerror(e)));
  }
  struct stat st {};
  if (::fstat(f.fd_, &st) != 0)
    return Error(Code::io_error, "cannot stat: " + std::string(std::strerror(errno)));
  if (!S_ISREG(st.st_mode)) return Error(Code::io_error, "not a regular file");
  f.size_ = static_cast<uint64_t>(st.st_size);
  PROCAM_TRY(f.parse());
  return f;
}

Result<ElfFile> ElfFile::from_bytes(std::vector<uint8_t> bytes) {
  ElfFile f;
  f.size_ = bytes.size();
  f.bytes_ = std::move(bytes);
  PROCAM_TRY(f.parse());
  return f;
}

Status ElfFile::read_at(uint64_t offset, void* dst, size_t n, const char* what) const {
  if (offset > size_ || n > size_ - offset)
    return corrupt(std::string(what) + " (" + std::to_string(n) + " bytes at offset " +
                   std::to_string(offset) + ") extends past the end of the file (" +
                   std::to_string(size_) + " bytes; truncated?)");
  if (n == 0) return {};
  if (fd_ < 0) {
    std::memcpy(dst, bytes_.data() + offset, n);
    return {};
  }
  auto* out = static_cast<uint8_t*>(dst);
  size_t done = 0;
  while (done < n) {
    ssize_t r = ::pread(fd_, out + done, n - done, static_cast<off_t>(offset + done));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0)
      return Error(Code::io_error, std::string("reading ") + what + ": " + std::strerror(errno));
    if (r == 0)
      return corrupt(std::string(what) + ": file shrank while being read (truncated at " +
                     std::to_string(offset + done) + " bytes)");
    done += static_cast<size_t>(r);
  }
  return {};
}

Status ElfFile::parse() {
  uint8_t eh[kEhdrSize] = {};
  if (size_ < EI_NIDENT)
    return corrupt("file is " + std::to_string(size_) +
                   " bytes, too short to be an ELF file (needs at least 16)");
  PROCAM_TRY(read_at(0, eh, EI_NIDENT, "ELF identification"));
  if (std::memcmp(eh, ELFMAG, SELFMAG) != 0)
    return corrupt("not an ELF file (starts with bytes " + hex_bytes(eh, 4) +
                   ", expected 7f 45 4c 46 = \"\\x7fELF\")");
  if (eh[EI_CLASS] == ELFCLASS32)
    return corrupt("32-bit ELF file (ELFCLASS32); plugins must be 64-bit ELF shared objects");
  if (eh[EI_CLASS] != ELFCLASS64)
    return corrupt("unknown ELF class " + std::to_string(eh[EI_CLASS]) +
                   " (expected 2, ELFCLASS64)");
  if (eh[EI_DATA] == ELFDATA2MSB)
    return corrupt("big-endian ELF file (ELFDATA2MSB); plugins must be little-endian");
  if (eh[EI_DATA] != ELFDATA2LSB)
    return corrupt("unknown ELF data encoding " + std::to_string(eh[EI_DATA]) +
                   " (expected 1, little-endian)");
  if (eh[EI_VERSION] != EV_CURRENT)
    return corrupt("unknown ELF version " + std::to_string(eh[EI_VERSION]) + " (expected 1)");
  if (size_ < kEhdrSize)
    return corrupt("file is " + std::to_string(size_) +
                   " bytes, too short for the 64-byte ELF64 header (truncated)");
  PROCAM_TRY(read_at(0, eh, kEhdrSize, "ELF header"));

  const uint16_t e_type = le16(eh + 16);
  machine_ = le16(eh + 18);
  const uint64_t e_shoff = le64(eh + 40);
  const uint16_t e_ehsize = le16(eh + 52);
  const uint16_t e_shentsize = le16(eh + 58);
  uint64_t shnum = le16(eh + 60);
  if (e_type != ET_DYN)
    return corrupt("ELF type " + std::to_string(e_type) +
                   (e_type == ET_EXEC   ? " (executable)"
                    : e_type == ET_REL  ? " (relocatable object, not linked)"
                    : e_type == ET_CORE ? " (core dump)"
                                        : "") +
                   " is not a shared object (ET_DYN = 3)");
  if (e_ehsize < kEhdrSize)
    return corrupt("ELF header size e_ehsize " + std::to_string(e_ehsize) + " is below 64");
  if (e_shoff == 0) return corrupt("no section header table (e_shoff is 0); cannot find .dynsym");
  if (e_shentsize < kShdrSize)
    return corrupt("section header entry size e_shentsize " + std::to_string(e_shentsize) +
                   " is below 64");

  // Section 0 is always present when e_shoff != 0; with more than 0xff00
  // sections e_shnum is 0 and section 0's sh_size holds the real count.
  uint8_t sh[kShdrSize] = {};
  PROCAM_TRY(read_at(e_shoff, sh, kShdrSize, "section header 0"));
  if (shnum == 0) shnum = le64(sh + 32);
  if (shnum == 0 || shnum > kMaxSections)
    return corrupt("section count " + std::to_string(shnum) + " is out of range (1.." +
                   std::to_string(kMaxSections) + ")");
  if (e_shoff > size_ || shnum > (size_ - e_shoff) / e_shentsize)
    return corrupt("section header table (offset " + std::to_string(e_shoff) + ", " +
                   std::to_string(shnum) + " entries of " + std::to_string(e_shentsize) +
                   " bytes) extends past the end of the file (" + std::to_string(size_) +
                   " bytes; truncated?)");

  sections_.resize(shnum);
  int dynsym_index = -1;
  for (uint64_t i = 0; i < shnum; ++i) {
    PROCAM_TRY(read_at(e_shoff + i * e_shentsize, sh, kShdrSize, "section header"));
    Section& s = sections_[i];
    s.type = le32(sh + 4);
    s.flags = le64(sh + 8);
    s.addr = le64(sh + 16);
    s.offset = le64(sh + 24);
    s.size = le64(sh + 32);
    s.link = le32(sh + 40);
    s.entsize = le64(sh + 56);
    if (s.type == SHT_DYNSYM) {
      if (dynsym_index >= 0)
        return corrupt("more than one .dynsym section (sections " + std::to_string(dynsym_index) +
                       " and " + std::to_string(i) + ")");
      dynsym_index = static_cast<int>(i);
    }
  }
  if (dynsym_index < 0)
    return corrupt("no dynamic symbol table (.dynsym): not a shared library exporting symbols");

  const Section& ds = sections_[static_cast<size_t>(dynsym_index)];
  if (ds.entsize < kSymSize)
    return corrupt(".dynsym entry size " + std::to_string(ds.entsize) + " is below 24");
  if (ds.size % ds.entsize != 0)
    return corrupt(".dynsym size " + std::to_string(ds.size) +
                   " is not a multiple of its entry size " + std::to_string(ds.entsize));
  if (ds.size > kMaxTableBytes)
    return corrupt(".dynsym size " + std::to_string(ds.size) + " bytes exceeds the 64 MiB limit");
  if (ds.link == 0 || ds.link >= shnum)
    return corrupt(".dynsym links to string table section " + std::to_string(ds.link) +
                   ", which does not exist (" + std::to_string(shnum) + " sections)");
  const Section& ss = sections_[ds.link];
  if (ss.type != SHT_STRTAB)
    return corrupt(".dynsym links to section " + std::to_string(ds.link) + " of type " +
                   std::to_string(ss.type) + ", expected a string table (SHT_STRTAB = 3)");
  if (ss.size > kMaxTableBytes)
    return corrupt(".dynstr size " + std::to_string(ss.size) + " bytes exceeds the 64 MiB limit");

  // Range checks before allocating (read_at would catch them, but after).
  for (const auto& [sec, what] : {std::pair{&ds, ".dynsym"}, std::pair{&ss, ".dynstr"}})
    if (sec->offset > size_ || sec->size > size_ - sec->offset)
      return corrupt(std::string(what) + " section (" + std::to_string(sec->size) +
                     " bytes at offset " + std::to_string(sec->offset) +
                     ") extends past the end of the file (" + std::to_string(size_) +
                     " bytes; truncated?)");
  dynsym_entsize_ = ds.entsize;
  dynsym_.resize(static_cast<size_t>(ds.size));
  PROCAM_TRY(read_at(ds.offset, dynsym_.data(), dynsym_.size(), ".dynsym section"));
  dynstr_.resize(static_cast<size_t>(ss.size));
  PROCAM_TRY(read_at(ss.offset, dynstr_.data(), dynstr_.size(), ".dynstr section"));
  return {};
}

Result<Symbol> ElfFile::find_symbol(std::string_view name) const {
  if (sections_.empty()) return Error(Code::internal, "ElfFile used after move");
  const uint64_t entsize = dynsym_entsize_;
  const size_t count = dynsym_.size() / entsize;
  bool seen_undefined = false;
  for (size_t i = 1; i < count; ++i) {  // entry 0 is the reserved null symbol
    const uint8_t* p = dynsym_.data() + i * entsize;
    const uint32_t st_name = le32(p);
    if (st_name >= dynstr_.size())
      return corrupt(".dynsym entry " + std::to_string(i) + " has name index " +
                     std::to_string(st_name) + " outside .dynstr (" +
                     std::to_string(dynstr_.size()) + " bytes)");
    const char* s = reinterpret_cast<const char*>(dynstr_.data()) + st_name;
    const void* nul = std::memchr(s, 0, dynstr_.size() - st_name);
    if (nul == nullptr)
      return corrupt(".dynsym entry " + std::to_string(i) +
                     " has a name that is not NUL-terminated within .dynstr");
    std::string_view sym_name(s, static_cast<size_t>(static_cast<const char*>(nul) - s));
    if (sym_name != name) continue;
    Symbol sym;
    sym.section = le16(p + 6);
    if (sym.section == SHN_UNDEF) {
      seen_undefined = true;
      continue;
    }
    sym.name = std::string(sym_name);
    sym.type = static_cast<uint8_t>(p[4] & 0xf);
    sym.bind = static_cast<uint8_t>(p[4] >> 4);
    sym.value = le64(p + 8);
    sym.size = le64(p + 16);
    return sym;
  }
  return Error(Code::not_found,
               "no defined dynamic symbol '" + std::string(name) + "'" +
                   (seen_undefined ? " (it is only referenced, i.e. imported, not defined)" : ""));
}

Result<std::vector<uint8_t>> ElfFile::read_symbol(const Symbol& sym, size_t n) const {
  const std::string what = "symbol '" + sym.name + "'";
  if (sym.type != STT_OBJECT)
    return corrupt(what + " is " + type_name(sym.type) + ", expected a data object (STT_OBJECT)");
  if (sym.size < n)
    return corrupt(what + " is " + std::to_string(sym.size) +
                   " bytes (st_size), expected at least " + std::to_string(n));
  if (sym.section >= SHN_LORESERVE)
    return corrupt(what + " is in special section index " + hex(sym.section) +
                   " (absolute/common), not in a section of the file");
  if (sym.section >= sections_.size())
    return corrupt(what + " refers to section " + std::to_string(sym.section) +
                   ", but there are only " + std::to_string(sections_.size()));
  const Section& sec = sections_[sym.section];
  if (sec.type == SHT_NULL || (sec.flags & SHF_ALLOC) == 0)
    return corrupt(what + " refers to section " + std::to_string(sym.section) +
                   ", which is not loaded into memory (no SHF_ALLOC)");
  if (sym.value < sec.addr || sym.value - sec.addr > sec.size ||
      sym.size > sec.size - (sym.value - sec.addr))
    return corrupt(what + " (address " + hex(sym.value) + ", " + std::to_string(sym.size) +
                   " bytes) does not lie inside its section " + std::to_string(sym.section) +
                   " (address " + hex(sec.addr) + ", " + std::to_string(sec.size) + " bytes)");
  std::vector<uint8_t> out(n, 0);
  if (sec.type == SHT_NOBITS) return out;  // .bss: zero-initialised
  const uint64_t delta = sym.value - sec.addr;
  if (sec.offset > UINT64_MAX - delta) return corrupt(what + ": section file offset overflows");
  PROCAM_TRY(read_at(sec.offset + delta, out.data(), n, (what + " data").c_str()));
  return out;
}

Result<std::vector<uint8_t>> read_symbol(const std::string& path, std::string_view symbol,
                                         size_t n) {
  auto f = ElfFile::open(path);
  if (!f.ok()) return f.status();
  auto sym = f->find_symbol(symbol);
  if (!sym.ok()) return sym.status();
  return f->read_symbol(*sym, n);
}

}  // namespace procam::host::elf
