// SPDX-License-Identifier: MIT
// Process-wide cache of output-map storage (F32 and U8 maps of a scan).
//
// Why: a 1920x1200 Gray col+row round hands the host ~40 MB of fresh maps;
// the kernel faults and zeroes every page on first touch, which was about a
// quarter of the whole decode (perf, BM_GrayColRowDecode). The daemon runs
// scan after scan of the same size, so the storage of the last scan's maps,
// given back when its session is destroyed (sdk::Outputs::set_release), is
// reused as is by the next decoder: no page faults, no zeroing.
//
// Contract: take_map(v, n) leaves v with n elements — recycled storage with
// STALE contents when the cache holds a vector of that type and size, else a
// fresh vector touched now (allocate_map). Callers must write every element
// before reading it (the decoders do; test MapCache.RecycledMapsGiveTheSameResults
// in sessions_test.cpp checks a decode after a different one). give_map keeps
// at most map_cache_limit() bytes (default 192 MiB, the maps of about three
// 1920x1200 ensemble scans) and frees the rest; it never throws.
// Thread-safety: all functions may be called from any thread (one mutex).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace procam::sl {

void take_map(std::vector<float>& v, size_t n);
void take_map(std::vector<uint8_t>& v, size_t n);
void give_map(std::vector<float>&& v) noexcept;
void give_map(std::vector<uint8_t>&& v) noexcept;

// Bytes the cache may keep; 0 disables it (and frees what it holds).
void set_map_cache_limit(size_t bytes);
size_t map_cache_limit();
size_t map_cache_bytes();  // held now

}  // namespace procam::sl
