// SPDX-License-Identifier: MIT
// Process-wide cache of output-map storage (F32 and U8 maps of a scan), and
// allocate_map() for maps whose pages should be mapped before they are written.
// Part of procam_plugin_toolkit (src/map_cache.cpp); linked through
// procam::plugin_sdk.
//
// Why: a 1920x1200 Gray col+row round hands the host ~40 MB of fresh maps;
// the kernel faults and zeroes every page on first touch, which was about a
// quarter of the whole decode (structured-light's BM_GrayColRowDecode). A
// daemon runs scan after scan of the same size, so the storage of the last
// scan's maps, given back when its session is destroyed
// (sdk::Outputs::set_release(give_map, give_map)), is reused as is by the next
// decoder: no page faults, no zeroing.
//
// Contract: take_map(v, n) leaves v with n elements — v itself when it already
// has n; else recycled storage with STALE contents when the cache holds a
// vector of that type and size; else a fresh vector touched now
// (allocate_map). Callers must write every element before reading it.
// give_map keeps at most map_cache_limit() bytes (default 192 MiB, the maps
// of about three 1920x1200 ensemble scans) and frees the rest; it never throws.
// Each plugin library has its own cache (the toolkit is linked with hidden
// visibility).
// Thread-safety: all functions may be called from any thread (one mutex).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace procam::sdk {

void take_map(std::vector<float>& v, size_t n);
void take_map(std::vector<uint8_t>& v, size_t n);
void give_map(std::vector<float>&& v) noexcept;
void give_map(std::vector<uint8_t>&& v) noexcept;

// Bytes the cache may keep; 0 disables it (and frees what it holds).
void set_map_cache_limit(size_t bytes);
size_t map_cache_limit();
size_t map_cache_bytes();  // held now

// Advises the 2 MiB-aligned part of [p, p + bytes) for transparent huge pages
// (a hint; call before the pages are first written). No-op where unsupported.
void advise_huge_pages(const void* p, size_t bytes) noexcept;

// Output map of n elements, allocated (huge pages advised) and every page
// written (value-initialised) now; a map that already has n elements is left
// as it is. Throws std::bad_alloc.
template <class T>
void allocate_map(std::vector<T>& v, size_t n) {
  if (v.size() == n) return;
  std::vector<T>().swap(v);
  v.reserve(n);
  advise_huge_pages(v.data(), n * sizeof(T));
  v.assign(n, T{});
}

}  // namespace procam::sdk
