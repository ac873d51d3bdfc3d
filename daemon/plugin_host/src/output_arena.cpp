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

Status OutputSnapshot::view(uint64_t used) {
  used_ = 0;
  data_ = nullptr;
  PROCAM_TRY(check_used(arena_, used));
  data_ = arena_.data();
  used_ = used;
  return {};
}

Status OutputSnapshot::take(uint64_t used) {
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
