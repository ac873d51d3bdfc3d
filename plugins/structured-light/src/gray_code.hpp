// SPDX-License-Identifier: MIT
// Binary-reflected Gray code (thesis §3.2, docs/techniques.md C1): consecutive
// coordinates differ in exactly one bit, so a one-pixel blur across a stripe
// edge corrupts at most one bit and the error stays within one column.
// Thread-safety: pure functions.
#pragma once

#include <cstdint>

#include "stripe_code.hpp"

namespace procam::sl {

// Bits needed for `count` distinct words: ceil(log2 count), at least 1
// (count 1 -> 1, 2 -> 1, 3 -> 2, 1024 -> 10, 1280 -> 11). count must be > 0.
constexpr uint32_t code_bits(uint32_t count) {
  uint32_t bits = 1;
  while (bits < 32 && (uint64_t{1} << bits) < count) ++bits;
  return bits;
}

// g = v xor (v >> 1).
constexpr uint32_t gray_encode(uint32_t v) { return v ^ (v >> 1); }

// Inverse of gray_encode: v = g xor (g >> 1) xor (g >> 2) xor ... (prefix xor).
constexpr uint32_t gray_decode(uint32_t g) {
  for (uint32_t shift = 1; shift < 32; shift <<= 1) g ^= g >> shift;
  return g;
}

// The Gray code over `length` coordinates with code_bits(length) planes.
// Words >= length are unused (decode to StripeCode::kInvalid). Throws
// std::invalid_argument for length 0 or above 2^16.
StripeCode make_gray_code(uint32_t length);

}  // namespace procam::sl
