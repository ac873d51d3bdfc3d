// SPDX-License-Identifier: MIT
// procam-plugin-worker's global operator new and delete (linked into the
// worker executable only, never into the daemon or a library): blocks of
// >= 1 MiB come from the shared heap (shared_heap.hpp), everything else from
// malloc as before. The executable's definitions take precedence over
// libstdc++'s for every library loaded into the worker -- the plugins'
// `operator new` calls included -- so a plugin's output maps (std::vector
// storage in the SDK's map cache) are in shared memory from the start and
// the outputs reply names them instead of copying them (README.md "Speed").
// A plugin that allocates with malloc (C) is served as before.
//
// Under AddressSanitizer the sanitizer's own operator new stays (it checks
// new/delete pairing); there is then no shared heap either (worker_main.cpp).
#include <cstdlib>
#include <new>

#include "shared_heap.hpp"

#if !defined(__SANITIZE_ADDRESS__)

namespace {
namespace heap = procam::worker::heap;

void* from_malloc(std::size_t n, std::size_t align) {
  if (n == 0) n = 1;
  for (;;) {
    void* p = align <= alignof(std::max_align_t) ? std::malloc(n)
                                                 : std::aligned_alloc(align, (n + align - 1) / align * align);
    if (p != nullptr) return p;
    std::new_handler h = std::get_new_handler();
    if (h == nullptr) throw std::bad_alloc();
    h();
  }
}

void* allocate(std::size_t n, std::size_t align) {
  if (void* p = heap::allocate(n, align)) return p;
  return from_malloc(n, align);
}

void deallocate(void* p) noexcept {
  if (p == nullptr) return;
  if (heap::owns(p)) heap::release(p);
  else std::free(p);
}

}  // namespace

void* operator new(std::size_t n) { return allocate(n, 1); }
void* operator new[](std::size_t n) { return allocate(n, 1); }
void* operator new(std::size_t n, std::align_val_t a) { return allocate(n, static_cast<std::size_t>(a)); }
void* operator new[](std::size_t n, std::align_val_t a) { return allocate(n, static_cast<std::size_t>(a)); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return allocate(n, 1);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return allocate(n, 1);
  } catch (...) {
    return nullptr;
  }
}
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  try {
    return allocate(n, static_cast<std::size_t>(a));
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  try {
    return allocate(n, static_cast<std::size_t>(a));
  } catch (...) {
    return nullptr;
  }
}

void operator delete(void* p) noexcept { deallocate(p); }
void operator delete[](void* p) noexcept { deallocate(p); }
void operator delete(void* p, std::size_t) noexcept { deallocate(p); }
void operator delete[](void* p, std::size_t) noexcept { deallocate(p); }
void operator delete(void* p, std::align_val_t) noexcept { deallocate(p); }
void operator delete[](void* p, std::align_val_t) noexcept { deallocate(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { deallocate(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { deallocate(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { deallocate(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { deallocate(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { deallocate(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { deallocate(p); }

#endif
