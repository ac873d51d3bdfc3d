// SPDX-License-Identifier: MIT
// Tests of the projected codes (thesis §3.3.1–3.3.2): data integrity of the
// embedded max-min-SW code, its Gray and stripe-width properties, the XOR
// codes' stripe widths and their decoding by the thesis's rule (XOR each
// binarized plane with the binarized base, then Gray-decode) computed here
// independently of codes.cpp, and the stretched min-SW columns for W > 1024.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "codes.hpp"
#include "gray_code.hpp"
#include "minsw_data.hpp"

namespace procam::sl {
namespace {

TEST(MinSwData, Md5AndJoinedWordsMatchProvenance) {
  // data/PROVENANCE.md and /work/shared/data/README.md.
  EXPECT_STREQ(minsw_md5_10bit(), "2246c8482b72dbee65c1f92355e1faa2");
  std::string joined;
  for (uint32_t w : minsw_words_10bit()) {
    if (!joined.empty()) joined += ',';
    joined += std::to_string(w);
  }
  EXPECT_EQ(joined, std::string(minsw_joined_10bit()));
}

TEST(MinSwData, EmbeddedWordsEqualTheDataFile) {
  std::ifstream in(std::string(PROCAM_SOURCE_DIR) +
                   "/plugins/structured-light/data/maxminsw-gray-10bit.txt");
  ASSERT_TRUE(in.good());
  std::vector<uint32_t> file;
  for (uint32_t w = 0; in >> w;) file.push_back(w);
  const auto words = minsw_words_10bit();
  ASSERT_EQ(file.size(), 1024u);
  ASSERT_EQ(words.size(), 1024u);
  for (size_t i = 0; i < file.size(); ++i) EXPECT_EQ(file[i], words[i]) << i;
}

TEST(MinSwData, CyclicGrayWithMinStripeWidth8) {
  const auto w = minsw_words_10bit();
  std::set<uint32_t> distinct(w.begin(), w.end());
  EXPECT_EQ(distinct.size(), 1024u);
  for (size_t i = 0; i < w.size(); ++i) {
    EXPECT_LT(w[i], 1024u);
    EXPECT_EQ(std::popcount(w[i] ^ w[(i + 1) % w.size()]), 1) << "words " << i << ", next";
  }
  uint32_t overall = 1024;
  for (uint32_t bit = 0; bit < 10; ++bit) {  // cyclic runs
    size_t start = 0;
    while (((w[start] >> bit) & 1u) == ((w[(start + w.size() - 1) % w.size()] >> bit) & 1u)) ++start;
    uint32_t run = 0, min_run = 1024;
    for (size_t k = 0; k < w.size(); ++k) {
      const size_t i = (start + k) % w.size(), j = (i + 1) % w.size();
      ++run;
      if (((w[i] >> bit) & 1u) != ((w[j] >> bit) & 1u)) {
        min_run = std::min(min_run, run);
        run = 0;
      }
    }
    EXPECT_GE(min_run, 8u) << "bit " << bit;  // 8 in bits 2-9, 16 in the two lowest-frequency
    overall = std::min(overall, min_run);
  }
  EXPECT_EQ(overall, 8u);  // the code's min-SW (thesis §3.3.2: 8, vs 2 for Gray)
}

// Thesis §3.3.1 decode, written independently: projected plane (bit k) of an
// XOR code = Gray bit k XOR Gray bit `base` for k > base, Gray bit k else.
uint32_t xor_projected_bit(uint32_t c, uint32_t k, uint32_t base) {
  const uint32_t g = gray_encode(c);
  const uint32_t b = (g >> k) & 1u;
  return k > base ? b ^ ((g >> base) & 1u) : b;
}

class XorCode : public ::testing::TestWithParam<std::tuple<const char*, uint32_t, uint32_t>> {};

TEST_P(XorCode, PatternsMatchDefinitionAndDecodeByXorWithBase) {
  const auto [id, base, length] = GetParam();
  const ProjectedCode code = make_projected_code(id, length);
  const uint32_t bits = code_bits(length);
  ASSERT_EQ(code.bits(), bits);
  for (uint32_t c = 0; c < length; ++c) {
    uint32_t binarized = 0;  // what a perfect camera would read, plane by plane
    for (uint32_t p = 0; p < bits; ++p) {
      const uint32_t k = bits - 1 - p;
      ASSERT_EQ(code.bit(p, c) ? 1u : 0u, xor_projected_bit(c, k, base)) << c << " plane " << p;
      binarized |= (code.bit(p, c) ? 1u : 0u) << k;
    }
    // Decoder of the thesis: XOR the planes above the base with the base -> Gray word.
    const uint32_t base_bit = (binarized >> base) & 1u;
    uint32_t g = binarized;
    for (uint32_t k = base + 1; k < bits; ++k) g ^= base_bit << k;
    ASSERT_EQ(gray_decode(g), c);
    ASSERT_EQ(code.code.decode(code.code.words[c]), c);  // the lookup table agrees
  }
  // Only high frequencies: interior stripes at most the base width (2 or 4).
  const uint32_t max_width = 2u << base;
  for (uint32_t p = 0; p < bits; ++p) {
    const RunLengths r = interior_runs(code, p);
    EXPECT_LE(r.max_run, max_width) << id << " plane " << p;
    EXPECT_GE(r.min_run, 1u);
  }
}

INSTANTIATE_TEST_SUITE_P(Widths, XorCode,
                         ::testing::Values(std::make_tuple("xor02", 0u, 1024u),
                                           std::make_tuple("xor02", 0u, 1280u),
                                           std::make_tuple("xor04", 1u, 1024u),
                                           std::make_tuple("xor04", 1u, 1280u),
                                           std::make_tuple("xor04", 1u, 1920u),
                                           std::make_tuple("xor02", 0u, 37u)));

TEST(MinSwCode, IdentityUpTo1024Columns) {
  for (uint32_t length : {1u, 100u, 800u, 1024u}) {
    const ProjectedCode c = make_projected_code("minsw", length);
    EXPECT_EQ(c.bits(), 10u);
    EXPECT_EQ(c.max_span, 1u);
    for (uint32_t x = 0; x < length; ++x) {
      ASSERT_EQ(c.index_of[x], x);
      ASSERT_EQ(c.code.decode(c.code.words[x]), x);
    }
  }
}

// W > 1024 (README "W > 1024"): stretched code columns. Every projector column
// decodes to within 0.5 px for W <= 2048 and stripes only get wider.
TEST(MinSwCode, StretchedColumnsForWideProjectors) {
  for (uint32_t length : {1025u, 1280u, 1920u, 2048u, 4096u}) {
    const ProjectedCode c = make_projected_code("minsw", length);
    EXPECT_EQ(c.code.length, 1024u);
    EXPECT_EQ(c.max_span, (length + 1023) / 1024) << length;
    const double tol = 0.5 * (c.max_span - 1) + 1e-6;
    for (uint32_t x = 0; x < length; ++x) {
      const uint32_t k = c.index_of[x];
      const uint32_t decoded = c.code.decode(c.code.words[k]);
      ASSERT_EQ(decoded, k);
      ASSERT_LE(std::fabs(static_cast<double>(c.coord_of[k]) - x), tol) << length << " x " << x;
    }
    if (length <= 2048) { EXPECT_LE(tol, 0.5 + 1e-6); }
    for (uint32_t p = 0; p < 10; ++p) {
      const RunLengths r = interior_runs(c, p);
      EXPECT_GE(r.min_run, 8u * length / 1024u) << length << " plane " << p;
    }
  }
}

TEST(ProjectedCode, RejectsBadInput) {
  EXPECT_THROW(make_projected_code("nope", 100), std::invalid_argument);
  EXPECT_THROW(make_projected_code("gray", 0), std::invalid_argument);
  EXPECT_THROW(make_projected_code("xor04", 7), std::invalid_argument);
  EXPECT_THROW(make_projected_code("xor02", 3), std::invalid_argument);
  EXPECT_NO_THROW(make_projected_code("minsw", 65536));
}

}  // namespace
}  // namespace procam::sl
