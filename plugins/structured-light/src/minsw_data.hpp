// SPDX-License-Identifier: MIT
// The embedded 10-bit max-min-SW Gray code (thesis §3.3.2, docs/techniques.md C3;
// Goddyn & Gvozdjak 2003), generated at configure time from
// data/maxminsw-gray-10bit.txt. Provenance and integrity: data/PROVENANCE.md.
// Thread-safety: immutable static data.
#pragma once

#include <cstdint>
#include <span>

namespace procam::sl {

// 1024 words; word j belongs to code column j; bit 9 is the first plane.
std::span<const uint32_t> minsw_words_10bit();
// The words joined with ',' exactly as CMake hashed them.
const char* minsw_joined_10bit();
// MD5 of minsw_joined_10bit(), computed by CMake (string(MD5)).
const char* minsw_md5_10bit();

}  // namespace procam::sl
