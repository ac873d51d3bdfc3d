// SPDX-License-Identifier: MIT
// Output-map storage cache and huge-page advice (see procam/sdk/map_cache.hpp).
#include "procam/sdk/map_cache.hpp"

#include <sys/mman.h>

#include <mutex>
#include <utility>

namespace procam::sdk {
namespace {

constexpr size_t kHugePage = size_t{2} << 20;

struct Cache {
  std::mutex mu;
  std::vector<std::vector<float>> f32;
  std::vector<std::vector<uint8_t>> u8;
  size_t bytes = 0;
  size_t limit = size_t{192} << 20;
};

Cache& cache() {
  static Cache* c = new Cache;  // never destroyed: sessions may end during exit
  return *c;
}

template <class T>
std::vector<std::vector<T>>& shelf(Cache& c);
template <>
std::vector<std::vector<float>>& shelf<float>(Cache& c) { return c.f32; }
template <>
std::vector<std::vector<uint8_t>>& shelf<uint8_t>(Cache& c) { return c.u8; }

template <class T>
void take(std::vector<T>& v, size_t n) {
  if (v.size() == n) return;
  Cache& c = cache();
  {
    std::lock_guard<std::mutex> lock(c.mu);
    auto& s = shelf<T>(c);
    for (size_t i = s.size(); i-- > 0;) {  // newest first: likeliest in cache
      if (s[i].size() != n) continue;
      c.bytes -= n * sizeof(T);
      std::vector<T> hit = std::move(s[i]);
      s.erase(s.begin() + static_cast<std::ptrdiff_t>(i));
      v.swap(hit);
      break;
    }
  }
  if (v.size() != n) allocate_map(v, n);
}

template <class T>
void give(std::vector<T>&& v) noexcept {
  std::vector<T> mine = std::move(v);
  const size_t b = mine.size() * sizeof(T);
  if (b == 0) return;
  Cache& c = cache();
  try {
    std::lock_guard<std::mutex> lock(c.mu);
    if (c.bytes + b > c.limit) return;  // full: `mine` is freed on return
    shelf<T>(c).push_back(std::move(mine));
    c.bytes += b;
  } catch (...) {  // lock or push_back failed: free the storage instead
  }
}

}  // namespace

void take_map(std::vector<float>& v, size_t n) { take(v, n); }
void take_map(std::vector<uint8_t>& v, size_t n) { take(v, n); }
void give_map(std::vector<float>&& v) noexcept { give(std::move(v)); }
void give_map(std::vector<uint8_t>&& v) noexcept { give(std::move(v)); }

void set_map_cache_limit(size_t bytes) {
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mu);
  c.limit = bytes;
  if (c.bytes > bytes) {
    c.f32.clear();
    c.u8.clear();
    c.bytes = 0;
  }
}

size_t map_cache_limit() {
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mu);
  return c.limit;
}

size_t map_cache_bytes() {
  Cache& c = cache();
  std::lock_guard<std::mutex> lock(c.mu);
  return c.bytes;
}

void advise_huge_pages(const void* p, size_t bytes) noexcept {
#ifdef MADV_HUGEPAGE
  const auto a = reinterpret_cast<uintptr_t>(p);
  const uintptr_t begin = (a + kHugePage - 1) / kHugePage * kHugePage;
  const uintptr_t end = (a + bytes) / kHugePage * kHugePage;
  if (end > begin)  // a hint: failure only means 4 KiB pages
    (void)madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
  (void)kHugePage;
#endif
}

}  // namespace procam::sdk
