// SPDX-License-Identifier: MIT
// The worker's shared heap (shared_heap.hpp). Nothing here may allocate
// with operator new or malloc: it is called from inside operator new.
#include "shared_heap.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstring>

namespace procam::worker::heap {
namespace {

constexpr uint64_t kMagic = 0x50434d48454150ull;  // "PAEHMCP"
constexpr size_t kMaxFree = 4096;                 // free ranges tracked; beyond, a freed block is leaked

struct Range {
  size_t off, len;
};
struct Header {
  uint64_t magic;
  uint64_t total;  // bytes of the block, header page included
};

int g_fd = -1;
uint8_t* g_base = nullptr;
size_t g_size = 0;
pthread_mutex_t g_mu = PTHREAD_MUTEX_INITIALIZER;
size_t g_top = 0;   // bytes [0, g_top) have been handed out at some point
size_t g_used = 0;  // live blocks
Range g_free[kMaxFree];  // sorted by offset, none touching another or g_top
size_t g_nfree = 0;

struct Lock {
  Lock() { pthread_mutex_lock(&g_mu); }
  ~Lock() { pthread_mutex_unlock(&g_mu); }
};

void erase_free(size_t i) {
  std::memmove(&g_free[i], &g_free[i + 1], (g_nfree - i - 1) * sizeof(Range));
  --g_nfree;
}

}  // namespace

bool init(size_t size) {
  size = size / kPage * kPage;
  if (g_base != nullptr || size < 2 * kMinBlock) return false;
  const int fd = ::memfd_create("procam-outputs-heap", MFD_CLOEXEC | MFD_ALLOW_SEALING);
  if (fd < 0) return false;
  void* p = MAP_FAILED;
  if (::ftruncate(fd, static_cast<off_t>(size)) == 0 &&
      ::fcntl(fd, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL) == 0)
    p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) {
    ::close(fd);
    return false;
  }
  g_fd = fd;
  g_base = static_cast<uint8_t*>(p);
  g_size = size;
  return true;
}

int fd() { return g_fd; }

void close_fd() {
  if (g_fd >= 0) ::close(g_fd);
  g_fd = -1;
}

const uint8_t* base() { return g_base; }
size_t size() { return g_size; }

bool owns(const void* p) {
  const auto* b = static_cast<const uint8_t*>(p);
  return g_base != nullptr && b >= g_base && b < g_base + g_size;
}

void* allocate(size_t n, size_t align) {
  if (g_base == nullptr || n < kMinBlock || align > kPage || n > g_size) return nullptr;
  const size_t total = (n + kPage - 1) / kPage * kPage + kPage;
  size_t off = 0;
  {
    Lock lock;
    // Best fit among the freed blocks: a scan's maps come back in the same
    // sizes, so they land where the last scan's were (pages already there).
    size_t best = g_nfree;
    for (size_t i = 0; i < g_nfree; ++i)
      if (g_free[i].len >= total && (best == g_nfree || g_free[i].len < g_free[best].len)) best = i;
    size_t got = total;
    if (best < g_nfree) {
      off = g_free[best].off;
      if (g_free[best].len - total >= kMinBlock + kPage) {
        g_free[best].off += total;
        g_free[best].len -= total;
      } else {
        got = g_free[best].len;  // the rest is too small to serve anyone: keep it with the block
        erase_free(best);
      }
    } else {
      if (g_size - g_top < total) return nullptr;
      off = g_top;
      g_top += total;
    }
    g_used += got;
    auto* h = reinterpret_cast<Header*>(g_base + off);
    h->magic = kMagic;
    h->total = got;
  }
  return g_base + off + kPage;
}

void release(void* p) noexcept {
  const auto* b = static_cast<uint8_t*>(p);
  const size_t at = static_cast<size_t>(b - g_base);
  if (at < kPage || at % kPage != 0) return;  // not a block start: leak rather than corrupt
  const size_t off = at - kPage;
  auto* h = reinterpret_cast<Header*>(g_base + off);
  Lock lock;
  if (h->magic != kMagic || h->total < 2 * kPage || h->total > g_top - off) return;  // double free or overwritten
  h->magic = 0;
  Range r{off, static_cast<size_t>(h->total)};
  g_used -= r.len;
  size_t i = 0;
  while (i < g_nfree && g_free[i].off < r.off) ++i;
  if (i > 0 && g_free[i - 1].off + g_free[i - 1].len == r.off) {  // merge with the one below
    r.off = g_free[i - 1].off;
    r.len += g_free[i - 1].len;
    erase_free(--i);
  }
  if (i < g_nfree && r.off + r.len == g_free[i].off) {  // and the one above
    r.len += g_free[i].len;
    erase_free(i);
  }
  if (r.off + r.len == g_top) {
    g_top = r.off;
    return;
  }
  if (g_nfree == kMaxFree) return;  // leaked: at most the heap's size, never handed out twice
  std::memmove(&g_free[i + 1], &g_free[i], (g_nfree - i) * sizeof(Range));
  g_free[i] = r;
  ++g_nfree;
}

size_t used_bytes() {
  Lock lock;
  return g_used;
}

}  // namespace procam::worker::heap
