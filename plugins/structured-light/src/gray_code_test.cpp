// SPDX-License-Identifier: MIT
// Tests of the Gray code and StripeCode: bit counts, round trip, the
// one-bit-change property, and agreement with the reflect-and-prefix
// construction (an independent definition of the binary-reflected Gray code).
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <vector>

#include "gray_code.hpp"
#include "stripe_code.hpp"

namespace procam::sl {
namespace {

const std::vector<uint32_t> kWidths = {1, 2, 3, 5, 1000, 1024, 1280, 1920};

// Binary-reflected Gray sequence by its definition: G1 = (0, 1);
// G(k+1) = G(k) followed by G(k) reversed with bit k set.
std::vector<uint32_t> reflected_sequence(uint32_t bits) {
  std::vector<uint32_t> g = {0, 1};
  for (uint32_t k = 1; k < bits; ++k) {
    const size_t n = g.size();
    for (size_t i = 0; i < n; ++i) g.push_back(g[n - 1 - i] | (1u << k));
  }
  return g;
}

TEST(GrayCode, BitsIsCeilLog2WithOneForOne) {
  for (uint32_t w : kWidths) {
    const uint32_t expected =
        w == 1 ? 1u : static_cast<uint32_t>(std::ceil(std::log2(static_cast<double>(w))));
    EXPECT_EQ(code_bits(w), expected) << "W=" << w;
    EXPECT_EQ(make_gray_code(w).bits, expected) << "W=" << w;
  }
  EXPECT_EQ(code_bits(1280), 11u);
  EXPECT_EQ(code_bits(1024), 10u);
  EXPECT_EQ(code_bits(1025), 11u);
  EXPECT_EQ(code_bits(65536), 16u);
}

TEST(GrayCode, MatchesReflectedConstruction) {
  const std::vector<uint32_t> ref = reflected_sequence(11);
  for (uint32_t v = 0; v < ref.size(); ++v) ASSERT_EQ(gray_encode(v), ref[v]) << "v=" << v;
}

TEST(GrayCode, RoundTripAndOneBitChange) {
  for (uint32_t w : kWidths) {
    const StripeCode code = make_gray_code(w);
    ASSERT_EQ(code.length, w);
    ASSERT_EQ(code.words.size(), w);
    ASSERT_EQ(code.lut.size(), size_t{1} << code.bits);
    for (uint32_t c = 0; c < w; ++c) {
      ASSERT_EQ(gray_decode(gray_encode(c)), c);
      ASSERT_EQ(code.words[c], gray_encode(c));
      ASSERT_LT(code.words[c], 1u << code.bits) << "word must fit in bits";
      ASSERT_EQ(code.decode(code.words[c]), c) << "W=" << w;
      if (c + 1 < w) {
        ASSERT_EQ(std::popcount(code.words[c] ^ code.words[c + 1]), 1)
            << "neighbours " << c << "," << c + 1 << " of W=" << w;
      }
    }
    // Every word that no column uses decodes to invalid (e.g. column >= W).
    uint32_t unused = 0;
    for (uint32_t word = 0; word < code.lut.size(); ++word)
      if (code.decode(word) == StripeCode::kInvalid) ++unused;
    EXPECT_EQ(unused, code.lut.size() - w) << "W=" << w;
    EXPECT_EQ(code.decode(static_cast<uint32_t>(code.lut.size())), StripeCode::kInvalid);
  }
}

TEST(GrayCode, PlaneBitsGoFromMostSignificant) {
  const StripeCode code = make_gray_code(1280);
  for (uint32_t c : {0u, 1u, 2u, 639u, 640u, 1279u})
    for (uint32_t p = 0; p < code.bits; ++p)
      EXPECT_EQ(code.bit(p, c), ((gray_encode(c) >> (code.bits - 1 - p)) & 1u) != 0);
  // The most significant Gray plane splits the code range in half: for W=1280
  // (11 bits, 2048 words) columns >= 1024 are lit.
  EXPECT_FALSE(code.bit(0, 1023));
  EXPECT_TRUE(code.bit(0, 1024));
}

TEST(GrayCode, RejectsBadSizes) {
  EXPECT_THROW(make_gray_code(0), std::invalid_argument);
  EXPECT_THROW(make_gray_code(65537), std::invalid_argument);
  EXPECT_EQ(make_gray_code(65536).bits, 16u);
}

TEST(StripeCode, RejectsUndecodableWords) {
  EXPECT_THROW(make_stripe_code("dup", 2, {0, 1, 1}), std::invalid_argument);
  EXPECT_THROW(make_stripe_code("wide", 2, {0, 4}), std::invalid_argument);
  EXPECT_THROW(make_stripe_code("none", 0, {0}), std::invalid_argument);
  const StripeCode c = make_stripe_code("custom", 2, {3, 0, 2});
  EXPECT_EQ(c.decode(3), 0u);
  EXPECT_EQ(c.decode(2), 2u);
  EXPECT_EQ(c.decode(1), StripeCode::kInvalid);
}

}  // namespace
}  // namespace procam::sl
