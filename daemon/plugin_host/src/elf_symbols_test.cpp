// SPDX-License-Identifier: MIT
// Tests for the ELF .dynsym reader: real fixture library, hand-broken copies,
// and random byte flips (must never crash).
#include "elf_symbols.hpp"

#include <elf.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>

#include "procam/plugin_abi.h"

namespace procam::host::elf {
namespace {

const std::string kGood = PROCAM_HOST_FIXTURE_DIR "/good.so";

std::vector<uint8_t> slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

template <typename T>
T get(const std::vector<uint8_t>& b, size_t off) {
  T v;
  std::memcpy(&v, b.data() + off, sizeof v);
  return v;
}
template <typename T>
void put(std::vector<uint8_t>& b, size_t off, const T& v) {
  std::memcpy(b.data() + off, &v, sizeof v);
}

// Locations inside good.so, found with <elf.h> (the test trusts the real file).
struct Layout {
  Elf64_Ehdr eh{};
  size_t dynsym_shdr = 0;  // file offset of .dynsym's section header
  Elf64_Shdr dynsym{};
  size_t info_sym = 0;  // file offset of procam_plugin_info's Elf64_Sym
  Elf64_Sym info{};
};

Layout layout_of(const std::vector<uint8_t>& b) {
  Layout l;
  l.eh = get<Elf64_Ehdr>(b, 0);
  Elf64_Shdr strtab{};
  for (size_t i = 0; i < l.eh.e_shnum; ++i) {
    const size_t off = l.eh.e_shoff + i * l.eh.e_shentsize;
    auto sh = get<Elf64_Shdr>(b, off);
    if (sh.sh_type == SHT_DYNSYM) {
      l.dynsym_shdr = off;
      l.dynsym = sh;
    }
  }
  strtab = get<Elf64_Shdr>(b, l.eh.e_shoff + l.dynsym.sh_link * l.eh.e_shentsize);
  for (size_t off = l.dynsym.sh_offset; off < l.dynsym.sh_offset + l.dynsym.sh_size;
       off += sizeof(Elf64_Sym)) {
    auto s = get<Elf64_Sym>(b, off);
    const char* name = reinterpret_cast<const char*>(b.data() + strtab.sh_offset + s.st_name);
    if (std::strcmp(name, PROCAM_PLUGIN_INFO_SYMBOL) == 0) {
      l.info_sym = off;
      l.info = s;
    }
  }
  return l;
}

class ElfTest : public ::testing::Test {
protected:
  void SetUp() override {
    good_ = slurp(kGood);
    ASSERT_GT(good_.size(), 1000u) << kGood;
    lay_ = layout_of(good_);
    ASSERT_NE(lay_.info_sym, 0u) << "fixture good.so lacks procam_plugin_info";
  }
  // Error of parsing `bytes` and reading the info symbol ("" if it worked).
  static Status read_info(std::vector<uint8_t> bytes, size_t n = sizeof(procam_plugin_info)) {
    auto f = ElfFile::from_bytes(std::move(bytes));
    if (!f.ok()) return f.status();
    auto s = f->find_symbol(PROCAM_PLUGIN_INFO_SYMBOL);
    if (!s.ok()) return s.status();
    auto r = f->read_symbol(*s, n);
    return r.status();
  }
  std::vector<uint8_t> good_;
  Layout lay_;
};

TEST_F(ElfTest, ReadsInfoFromRealLibrary) {
  auto bytes = read_symbol(kGood, PROCAM_PLUGIN_INFO_SYMBOL, sizeof(procam_plugin_info));
  ASSERT_TRUE(bytes.ok()) << bytes.status().to_string();
  ASSERT_EQ(bytes->size(), sizeof(procam_plugin_info));
  procam_plugin_info info;
  std::memcpy(&info, bytes->data(), sizeof info);
  EXPECT_EQ(info.magic, PROCAM_PLUGIN_MAGIC);
  EXPECT_EQ(info.abi_version, PROCAM_PLUGIN_ABI_VERSION);
  EXPECT_EQ(info.struct_size, sizeof(procam_plugin_info));
  EXPECT_STREQ(info.name, "null");
  EXPECT_STREQ(info.methods, "null");

  auto f = ElfFile::open(kGood);
  ASSERT_TRUE(f.ok());
  EXPECT_EQ(f->machine(), host_machine());
  auto create = f->find_symbol(PROCAM_PLUGIN_CREATE_SYMBOL);
  ASSERT_TRUE(create.ok()) << create.status().to_string();
  EXPECT_EQ(create->type, STT_FUNC);
  // A function is not data.
  auto fn = f->read_symbol(*create, 4);
  EXPECT_EQ(fn.status().code(), Code::corrupt_data);
  EXPECT_NE(fn.status().message().find("function"), std::string::npos) << fn.status().message();
}

TEST_F(ElfTest, MissingSymbolAndTooLargeRead) {
  auto f = ElfFile::open(kGood);
  ASSERT_TRUE(f.ok());
  auto none = f->find_symbol("no_such_symbol");
  EXPECT_EQ(none.status().code(), Code::not_found);
  // Imported (undefined) symbols are not definitions.
  auto imported = f->find_symbol("calloc");
  EXPECT_EQ(imported.status().code(), Code::not_found);
  EXPECT_NE(imported.status().message().find("imported"), std::string::npos)
      << imported.status().message();
  auto info = f->find_symbol(PROCAM_PLUGIN_INFO_SYMBOL);
  ASSERT_TRUE(info.ok());
  auto big = f->read_symbol(*info, sizeof(procam_plugin_info) + 1);
  EXPECT_EQ(big.status().code(), Code::corrupt_data);
  EXPECT_NE(big.status().message().find("st_size"), std::string::npos) << big.status().message();
}

TEST_F(ElfTest, OpenErrors) {
  auto missing = ElfFile::open("/nonexistent/dir/x.so");
  EXPECT_EQ(missing.status().code(), Code::not_found);
  auto dir = ElfFile::open(PROCAM_HOST_FIXTURE_DIR);
  EXPECT_EQ(dir.status().code(), Code::io_error);
  EXPECT_NE(dir.status().message().find("not a regular file"), std::string::npos);
}

TEST_F(ElfTest, GarbageIsRejected) {
  auto st = read_info({});
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("too short"), std::string::npos) << st.message();

  std::string text = "#!/bin/sh\necho this is not a library\n";
  st = read_info(std::vector<uint8_t>(text.begin(), text.end()));
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("not an ELF file"), std::string::npos) << st.message();
  EXPECT_NE(st.message().find("23 21 2f 62"), std::string::npos) << st.message();
}

TEST_F(ElfTest, WrongClassEncodingTypeRejected) {
  auto b = good_;
  b[EI_CLASS] = ELFCLASS32;
  auto st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("32-bit"), std::string::npos) << st.message();

  b = good_;
  b[EI_DATA] = ELFDATA2MSB;
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("big-endian"), std::string::npos) << st.message();

  b = good_;
  put<uint16_t>(b, offsetof(Elf64_Ehdr, e_type), ET_EXEC);
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("executable"), std::string::npos) << st.message();
}

TEST_F(ElfTest, TruncatedFilesRejectedAtEveryLength) {
  // Section headers sit at the end of the file, so every strict prefix lacks
  // something the reader needs.
  for (size_t len = 0; len < good_.size(); len += (len < 128 ? 1 : 61)) {
    std::vector<uint8_t> b(good_.begin(), good_.begin() + static_cast<std::ptrdiff_t>(len));
    auto st = read_info(b);
    ASSERT_FALSE(st.ok()) << "prefix of " << len << " bytes was accepted";
    EXPECT_EQ(st.code(), Code::corrupt_data) << len << ": " << st.to_string();
  }
  std::vector<uint8_t> b(good_.begin(), good_.end() - 1);
  auto st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("past the end of the file"), std::string::npos) << st.message();
}

TEST_F(ElfTest, BogusHeaderFieldsRejected) {
  auto b = good_;
  put<uint64_t>(b, offsetof(Elf64_Ehdr, e_shoff), 0xfffffffffffffff0ull);
  auto st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("past the end"), std::string::npos) << st.message();

  b = good_;
  put<uint16_t>(b, offsetof(Elf64_Ehdr, e_shnum), 0xfff0);
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("section header table"), std::string::npos) << st.message();

  b = good_;
  put<uint16_t>(b, offsetof(Elf64_Ehdr, e_shentsize), 12);
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("e_shentsize"), std::string::npos) << st.message();

  b = good_;
  put<uint64_t>(b, offsetof(Elf64_Ehdr, e_shoff), 0);
  st = read_info(b);
  EXPECT_NE(st.message().find("no section header table"), std::string::npos) << st.message();
}

TEST_F(ElfTest, BogusDynsymRejected) {
  // .dynsym linked to a non-existent string table.
  auto b = good_;
  put<uint32_t>(b, lay_.dynsym_shdr + offsetof(Elf64_Shdr, sh_link), 0x7fff);
  auto st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("does not exist"), std::string::npos) << st.message();

  // .dynsym extends past the end of the file.
  b = good_;
  put<uint64_t>(b, lay_.dynsym_shdr + offsetof(Elf64_Shdr, sh_size), 24ull * 100000);
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find(".dynsym"), std::string::npos) << st.message();

  // A symbol's name index outside .dynstr.
  b = good_;
  put<uint32_t>(b, lay_.info_sym + offsetof(Elf64_Sym, st_name), 0xffffff00u);
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("outside .dynstr"), std::string::npos) << st.message();

  // The symbol's address outside its section.
  b = good_;
  put<uint64_t>(b, lay_.info_sym + offsetof(Elf64_Sym, st_value), 0x7fffffff0000ull);
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("does not lie inside"), std::string::npos) << st.message();

  // A section index beyond the table.
  b = good_;
  put<uint16_t>(b, lay_.info_sym + offsetof(Elf64_Sym, st_shndx), 0x7f00);
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("refers to section"), std::string::npos) << st.message();

  // Special section index (SHN_ABS).
  b = good_;
  put<uint16_t>(b, lay_.info_sym + offsetof(Elf64_Sym, st_shndx), SHN_ABS);
  st = read_info(b);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("special section"), std::string::npos) << st.message();
}

TEST_F(ElfTest, NobitsSectionReadsZeros) {
  auto b = good_;
  const size_t shdr = lay_.eh.e_shoff + lay_.info.st_shndx * lay_.eh.e_shentsize;
  put<uint32_t>(b, shdr + offsetof(Elf64_Shdr, sh_type), SHT_NOBITS);
  auto f = ElfFile::from_bytes(b);
  ASSERT_TRUE(f.ok()) << f.status().to_string();
  auto s = f->find_symbol(PROCAM_PLUGIN_INFO_SYMBOL);
  ASSERT_TRUE(s.ok());
  auto r = f->read_symbol(*s, sizeof(procam_plugin_info));
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  for (uint8_t v : *r) ASSERT_EQ(v, 0);
}

TEST_F(ElfTest, RandomByteFlipsNeverCrash) {
  std::mt19937_64 rng(20240601);
  const size_t sh_begin = lay_.eh.e_shoff;
  int ok = 0, failed = 0;
  // PROCAM_ELF_FUZZ_ITERATIONS runs longer (e.g. under ASan); default stays fast.
  const char* env = std::getenv("PROCAM_ELF_FUZZ_ITERATIONS");
  const long iterations = env != nullptr ? std::atol(env) : 600;
  for (long it = 0; it < iterations; ++it) {
    auto b = good_;
    const int flips = 1 + static_cast<int>(rng() % 8);
    for (int k = 0; k < flips; ++k) {
      size_t pos;
      switch (rng() % 4) {  // aim most flips at the structures the reader parses
        case 0: pos = rng() % 64; break;
        case 1: pos = sh_begin + rng() % (b.size() - sh_begin); break;
        case 2: pos = lay_.dynsym.sh_offset + rng() % lay_.dynsym.sh_size; break;
        default: pos = rng() % b.size(); break;
      }
      b[pos] = static_cast<uint8_t>(rng());
    }
    // Random truncation now and then.
    if (rng() % 5 == 0) b.resize(rng() % b.size());
    auto f = ElfFile::from_bytes(std::move(b));
    if (!f.ok()) {
      ++failed;
      EXPECT_FALSE(f.status().message().empty());
      continue;
    }
    for (const char* name : {PROCAM_PLUGIN_INFO_SYMBOL, PROCAM_PLUGIN_CREATE_SYMBOL, "x"}) {
      auto s = f->find_symbol(name);
      if (!s.ok()) continue;
      auto r = f->read_symbol(*s, std::min<uint64_t>(s->size, 4096));
      if (r.ok()) {
        ++ok;
        EXPECT_EQ(r->size(), std::min<uint64_t>(s->size, 4096));
      }
    }
  }
  // Both outcomes must have happened, or the fuzzing did not exercise much.
  EXPECT_GT(ok, 0);
  EXPECT_GT(failed, 0);
}

}  // namespace
}  // namespace procam::host::elf
