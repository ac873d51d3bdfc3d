// SPDX-License-Identifier: MIT
// The worker's shared heap (README.md "Speed", WORKER_PROTOCOL.md "Shared
// heap"): large allocations of the plugin (>= 1 MiB: its output maps) are
// served from one memfd that the daemon maps read-only once, so the
// outputs reply can name where a map lies instead of copying it into the
// output arena. Only procam-plugin-worker uses it: its global operator new
// (shared_heap_new.cpp) asks here first; plugins are unchanged (they call
// operator new as before; the C ABI is the same).
//
// Layout: the memfd is `size` bytes, sealed against growing and shrinking
// (the daemon's mapping never loses a page: no SIGBUS), sparse until used.
// Each block is one header page (the block's size, a magic) followed by the
// caller's bytes, page-aligned. Freed blocks keep their pages (the next
// scan's maps land in memory already faulted, as the tuned glibc heap did,
// tune_allocator in worker_main.cpp); adjacent free blocks merge, and the
// top of the heap moves down when its last block is freed.
//
// Trust: the daemon trusts nothing here. It reads a block only while the
// worker is frozen, checks every reference against the heap's size and
// checks that the pages are written (no holes), worker_proxy.cpp.
// Threads: every function is thread-safe (one mutex, taken for large
// blocks only). Errors: allocate() returns nullptr when it does not serve
// a request (too small, no heap, full); the caller falls back to malloc.
#pragma once

#include <cstddef>
#include <cstdint>

namespace procam::worker::heap {

inline constexpr size_t kMinBlock = size_t{1} << 20;  // smaller requests go to malloc
inline constexpr size_t kPage = 4096;

// Creates the heap (memfd "procam-outputs-heap", `size` bytes rounded to
// pages, sealed, mapped read-write). Call once, before plugin code runs;
// false (and no heap) if the kernel refuses. Not thread-safe with allocate().
bool init(size_t size);
int fd();  // the memfd (for hello), -1 without a heap
void close_fd();  // after hello: the worker needs only its mapping
const uint8_t* base();
size_t size();
bool owns(const void* p);

// A block of at least `n` bytes aligned to `align` (<= kPage), or nullptr.
void* allocate(size_t n, size_t align);
// Gives back a block allocate() returned (owns(p) must hold).
void release(void* p) noexcept;

// Bytes in use by live blocks (headers included), for tests.
size_t used_bytes();

}  // namespace procam::worker::heap
