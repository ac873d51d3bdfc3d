// SPDX-License-Identifier: MIT
// StripeCode: a binary bit-plane code over projector columns (or rows) — the
// common form of every binary structured-light code (Gray, XOR-02/04, min-SW).
//
// A code assigns each coordinate c < length a `bits`-bit word; plane p (the
// p-th projected, p = 0 first) shows bit position bits-1-p of word(c), i.e.
// planes go from most to least significant bit. Decoding a binarized word is
// one table lookup, so any code — whatever its construction — decodes the
// same way, and codes can be compared or voted on per pixel (thesis §3.3.3).
// Thread-safety: immutable after construction; share freely between threads.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace procam::sl {

struct StripeCode {
  static constexpr uint32_t kInvalid = 0xFFFFFFFFu;  // decode(): word names no coordinate
  static constexpr uint32_t kMaxBits = 16;           // lookup table of 2^16 entries at most

  std::string name;                 // e.g. "binary-reflected Gray"
  uint32_t length = 0;              // coordinates 0..length-1 (projector columns or rows)
  uint32_t bits = 0;                // planes
  std::vector<uint32_t> words;      // words[c] for c < length
  std::vector<uint32_t> lut;        // 2^bits entries: word -> coordinate or kInvalid

  // Bit position in the word that plane p carries (planes: MSB first).
  uint32_t position(uint32_t plane) const { return bits - 1 - plane; }
  // Value (0/1) of plane p at coordinate c (c < length).
  bool bit(uint32_t plane, uint32_t c) const { return ((words[c] >> position(plane)) & 1u) != 0; }
  // Coordinate whose word is `word`, or kInvalid (an unused word).
  uint32_t decode(uint32_t word) const { return word < lut.size() ? lut[word] : kInvalid; }
};

// Builds the lookup table for `words`. Throws std::invalid_argument when bits
// is 0 or above kMaxBits, a word does not fit in `bits`, or two coordinates
// share a word (not decodable).
StripeCode make_stripe_code(std::string name, uint32_t bits, std::vector<uint32_t> words);

}  // namespace procam::sl
