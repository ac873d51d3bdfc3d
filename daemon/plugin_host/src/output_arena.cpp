// SPDX-License-Identifier: MIT
// Output arena and the daemon's private snapshot of it (output_arena.hpp).
#include "output_arena.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <mutex>
#include <string>
#include <vector>

namespace procam::host::wire {
namespace {

constexpr uint64_t kMinArena = uint64_t{1} << 20;
constexpr uint64_t kPage = 4096;
#ifdef MADV_POPULATE_READ
constexpr int kPopulateRead = MADV_POPULATE_READ;
#else
constexpr int kPopulateRead = 22;  // Linux 5.14
#endif
constexpr uint64_t kRound = uint64_t{2} << 20;  // sizes rounded up to 2 MiB

uint64_t grown(uint64_t need) {
  const uint64_t want = std::max(kMinArena, need + need / 4);
  return std::min<uint64_t>(kMaxBlob, (want + kRound - 1) / kRound * kRound);
}

// Daemon-wide spare copy buffers: a snapshot whose worker ended gives its
// buffer here, so the next worker's first outputs land in warm memory too
// (a fresh worker per scan, IsolationOptions::max_idle_workers 0). At most
// kSpareCount buffers and kSpareBytes in all; the rest is unmapped.
constexpr size_t kSpareCount = 2;
constexpr uint64_t kSpareBytes = uint64_t{256} << 20;
std::mutex g_spare_mu;
std::vector<Mapping>* g_spare = new std::vector<Mapping>;  // never destroyed: used from destructors

Mapping take_spare(uint64_t need) {
  std::lock_guard<std::mutex> lock(g_spare_mu);
  for (auto it = g_spare->begin(); it != g_spare->end(); ++it)
    if (it->size() >= need) {
      Mapping m = std::move(*it);
      g_spare->erase(it);
      return m;
    }
  return Mapping();
}

void give_spare(Mapping m) {
  if (m.size() == 0 || m.size() > kSpareBytes) return;
  std::lock_guard<std::mutex> lock(g_spare_mu);
  uint64_t held = 0;
  for (const Mapping& s : *g_spare) held += s.size();
  if (g_spare->size() >= kSpareCount || held + m.size() > kSpareBytes) g_spare->erase(g_spare->begin());
  g_spare->push_back(std::move(m));
}

}  // namespace

Result<OutputArena::Written> OutputArena::write(const std::function<void(Writer&)>& encode) {
  Writer count = Writer::counting();
  encode(count);
  const uint64_t n = count.size();
  if (n > kMaxBlob)
    return Error(Code::invalid_argument, "outputs of " + std::to_string(n) + " bytes are over the " +
                                             std::to_string(kMaxBlob) + "-byte limit");
  Written out;
  if (n > map_.size()) {
    // The first arena fits this reply (a scan's outputs keep their size);
    // a replacement gets room to grow.
    const uint64_t size = map_.size() == 0 ? std::max(kMinArena, (n + kRound - 1) / kRound * kRound) : grown(n);
    // Sealed against shrinking: the daemon's mapping never loses a page.
    // Pre-faulted for writing: every page exists before the daemon checks.
    auto shm = make_fixed_shared("procam-outputs", size, "the output arena");
    if (!shm) return shm.status();
    map_ = std::move(shm->map);
    fd_ = std::move(shm->fd);
    out.new_fd = fd_.get();
  }
  Writer w(reinterpret_cast<char*>(map_.mutable_data()), map_.size());
  encode(w);
  if (w.overflowed() || w.size() != n)
    return Error(Code::internal, "outputs: the encoder wrote " + std::to_string(w.size()) + " bytes after counting " +
                                     std::to_string(n));
  out.used = n;
  return out;
}

Status OutputSnapshot::adopt(int fd) {
  const int seals = ::fcntl(fd, F_GET_SEALS);
  if (seals < 0 || (seals & F_SEAL_SHRINK) == 0)
    return Error(Code::corrupt_data, "an output arena that is not a memfd sealed against shrinking");
  struct stat st {};
  if (::fstat(fd, &st) != 0 || st.st_size <= 0 || static_cast<uint64_t>(st.st_size) > kMaxBlob)
    return Error(Code::corrupt_data, "an output arena of " + std::to_string(st.st_size) + " bytes (1.." +
                                         std::to_string(kMaxBlob) + " allowed)");
  // Fully written, as a sealed blob must be: the sender paid for every page
  // this process will read.
  PROCAM_TRY(check_fully_written(st, "an output arena"));
  void* p = ::mmap(nullptr, static_cast<size_t>(st.st_size), PROT_READ, MAP_SHARED | MAP_POPULATE, fd, 0);
  if (p == MAP_FAILED) return Error(Code::unavailable, std::string("mmap of the output arena: ") + std::strerror(errno));
  arena_ = Mapping(p, static_cast<size_t>(st.st_size));
  return {};
}

namespace {
Status check_used(const Mapping& arena, uint64_t used) {
  if (arena.size() == 0) return Error(Code::corrupt_data, "outputs announced before any output arena was sent");
  if (used == 0 || used > arena.size())
    return Error(Code::corrupt_data, "outputs of " + std::to_string(used) + " bytes in an arena of " +
                                         std::to_string(arena.size()));
  return {};
}
}  // namespace

Status OutputSnapshot::adopt_heap(int fd) {
  const int seals = ::fcntl(fd, F_GET_SEALS);
  if (seals < 0 || (seals & (F_SEAL_SHRINK | F_SEAL_GROW)) != (F_SEAL_SHRINK | F_SEAL_GROW))
    return Error(Code::corrupt_data, "a shared heap that is not a memfd sealed against resizing");
  struct stat st {};
  if (::fstat(fd, &st) != 0 || st.st_size <= 0 || static_cast<uint64_t>(st.st_size) > kMaxBlob)
    return Error(Code::corrupt_data, "a shared heap of " + std::to_string(st.st_size) + " bytes (1.." +
                                         std::to_string(kMaxBlob) + " allowed)");
  UniqueFd own(::fcntl(fd, F_DUPFD_CLOEXEC, 0));
  if (!own) return Error(Code::unavailable, std::string("dup of the shared heap: ") + std::strerror(errno));
  void* p = ::mmap(nullptr, static_cast<size_t>(st.st_size), PROT_READ, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) return Error(Code::unavailable, std::string("mmap of the shared heap: ") + std::strerror(errno));
  heap_ = Mapping(p, static_cast<size_t>(st.st_size));
  heap_fd_ = std::move(own);
  return {};
}

const uint8_t* OutputSnapshot::heap_range(uint64_t offset, uint64_t bytes, std::string& why) {
  if (heap_.size() == 0) {
    why = "no shared heap was sent";
    return nullptr;
  }
  if (offset > heap_.size() || bytes > heap_.size() - offset) {
    why = std::to_string(bytes) + " bytes at offset " + std::to_string(offset) + " of a " +
          std::to_string(heap_.size()) + "-byte shared heap";
    return nullptr;
  }
  if (bytes == 0) return heap_.data() + offset;
  // Every page of the range written. mincore() answers from this mapping's
  // page tables and the memfd's page cache, without touching the pages:
  // ~0.1 ms for 32 MB. SEEK_HOLE, which also sees swapped-out pages, walks
  // the file from the offset to its next hole (the rest of the heap: 2-10
  // ms on the project's VM), so it only settles the pages mincore()
  // reports absent, one at a time (a swapped-out page has data there).
  const uint64_t first = offset / kPage * kPage, last = (offset + bytes + kPage - 1) / kPage * kPage;
  if (populated_.size() != heap_.size() / kPage) populated_.assign(heap_.size() / kPage, 0);
  // Pages checked before stay written where the worker cannot remove them.
  if (pages_stay_ && std::all_of(populated_.begin() + static_cast<ptrdiff_t>(first / kPage),
                                 populated_.begin() + static_cast<ptrdiff_t>(last / kPage),
                                 [](uint8_t p) { return p != 0; }))
    return heap_.data() + offset;
  std::vector<unsigned char> resident((last - first) / kPage);
  if (::mincore(const_cast<uint8_t*>(heap_.data()) + first, last - first, resident.data()) != 0) {
    why = std::string("mincore on the shared heap: ") + std::strerror(errno);
    return nullptr;
  }
  for (size_t i = 0; i < resident.size(); ++i) {
    if (resident[i] & 1) continue;
    const off_t at = static_cast<off_t>(first + i * kPage);
    if (::lseek(heap_fd_.get(), at, SEEK_DATA) != at) {
      why = "unwritten pages in the shared heap at offset " + std::to_string(at);
      return nullptr;
    }
  }
  // Map the checked pages into this process, once each (no allocation:
  // they are written): the next scan's check then answers from page tables
  // (~0.02 ms instead of ~1 ms for 32 MB) and a client reading the maps
  // takes no page faults. The plugin's maps come back to the same heap
  // blocks scan after scan (the SDK's map cache), so this is paid once per
  // worker; populating again costs ~0.08 ms per MB even when mapped, hence
  // the record. Best effort: kernels before 5.14 lack MADV_POPULATE_READ.
  for (size_t i = 0; i < resident.size();) {
    const size_t page = first / kPage + i;
    if (populated_[page]) {
      ++i;
      continue;
    }
    size_t run = 0;
    while (i + run < resident.size() && !populated_[page + run]) populated_[page + run++] = 1;
    (void)::madvise(const_cast<uint8_t*>(heap_.data()) + page * kPage, run * kPage, kPopulateRead);
    i += run;
  }
  return heap_.data() + offset;
}

HeapResolver OutputSnapshot::heap_in_place() {
  return [this](uint64_t offset, uint64_t bytes, std::string& why) { return heap_range(offset, bytes, why); };
}

HeapResolver OutputSnapshot::heap_copied() {
  return [this](uint64_t offset, uint64_t bytes, std::string& why) -> const uint8_t* {
    const uint8_t* src = heap_range(offset, bytes, why);
    if (src == nullptr || bytes == 0) return src;
    void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) {
      why = std::string("mmap for a copy of the outputs: ") + std::strerror(errno);
      return nullptr;
    }
    std::memcpy(p, src, bytes);
    heap_copies_.emplace_back(p, bytes);
    return static_cast<const uint8_t*>(p);
  };
}

Status OutputSnapshot::view(uint64_t used) {
  heap_copies_.clear();
  used_ = 0;
  data_ = nullptr;
  PROCAM_TRY(check_used(arena_, used));
  data_ = arena_.data();
  used_ = used;
  return {};
}

Status OutputSnapshot::take(uint64_t used) {
  heap_copies_.clear();
  used_ = 0;
  data_ = nullptr;
  PROCAM_TRY(check_used(arena_, used));
  if (copy_.size() < used) {
    give_spare(std::move(copy_));
    copy_ = take_spare(used);
    if (copy_.size() < used) {
      const uint64_t size = grown(used);
      void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_POPULATE, -1, 0);
      if (p == MAP_FAILED) return Error(Code::unavailable, std::string("mmap for the outputs: ") + std::strerror(errno));
      copy_ = Mapping(p, size);
    }
  }
  // The one read of shared memory: everything after works on the copy.
  std::memcpy(copy_.mutable_data(), arena_.data(), used);
  data_ = copy_.data();
  used_ = used;
  return {};
}

OutputSnapshot::~OutputSnapshot() { give_spare(std::move(copy_)); }

}  // namespace procam::host::wire
