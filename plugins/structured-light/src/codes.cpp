// SPDX-License-Identifier: MIT
// Construction of the projected codes (thesis §3.2–3.3; see codes.hpp).
#include "codes.hpp"

#include <algorithm>
#include <stdexcept>

#include "gray_code.hpp"
#include "minsw_data.hpp"

namespace procam::sl {

namespace {

ProjectedCode identity(std::string id, StripeCode code) {
  ProjectedCode p;
  p.id = std::move(id);
  const uint32_t n = code.length;
  p.code = std::move(code);
  p.index_of.resize(n);
  p.coord_of.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    p.index_of[i] = i;
    p.coord_of[i] = static_cast<float>(i);
  }
  return p;
}

// §3.3.1: w(c) = g(c) ^ (bit_base(g(c)) ? mask of positions above base : 0).
StripeCode make_xor_code(uint32_t length, uint32_t base_position, const std::string& name) {
  const uint32_t bits = code_bits(length);
  if (bits <= base_position)
    throw std::invalid_argument(name + " needs at least " + std::to_string(base_position + 2) +
                                " bits (length " + std::to_string(length) + " is too short)");
  const uint32_t all = (bits >= 32 ? 0xFFFFFFFFu : (1u << bits) - 1u);
  const uint32_t high = all & ~((2u << base_position) - 1u);  // positions > base
  std::vector<uint32_t> words(length);
  for (uint32_t c = 0; c < length; ++c) {
    const uint32_t g = gray_encode(c);
    words[c] = ((g >> base_position) & 1u) != 0 ? g ^ high : g;
  }
  return make_stripe_code(name, bits, std::move(words));
}

}  // namespace

ProjectedCode make_projected_code(const std::string& id, uint32_t length) {
  if (length == 0 || length > (1u << 16))
    throw std::invalid_argument("code '" + id + "': length must be 1..65536, got " +
                                std::to_string(length));
  if (id == "gray") return identity(id, make_gray_code(length));
  if (id == "xor02") {
    if (length < 4) throw std::invalid_argument("xor02 needs at least 4 projector columns");
    return identity(id, make_xor_code(length, 0, "XOR-02 (base: Gray bit 0, stripe width 2)"));
  }
  if (id == "xor04") {
    if (length < 8) throw std::invalid_argument("xor04 needs at least 8 projector columns");
    return identity(id, make_xor_code(length, 1, "XOR-04 (base: Gray bit 1, stripe width 4)"));
  }
  if (id == "minsw") {
    const std::span<const uint32_t> all = minsw_words_10bit();
    const auto n_codes = static_cast<uint32_t>(all.size());  // 1024
    if (length <= n_codes) {
      std::vector<uint32_t> words(all.begin(), all.begin() + length);
      return identity(id, make_stripe_code("max-min-SW Gray (10 bit, Goddyn & Gvozdjak)", 10,
                                           std::move(words)));
    }
    ProjectedCode p;
    p.id = id;
    p.code = make_stripe_code("max-min-SW Gray (10 bit, Goddyn & Gvozdjak), stretched", 10,
                              std::vector<uint32_t>(all.begin(), all.end()));
    p.index_of.resize(length);
    std::vector<uint32_t> first(n_codes, length), last(n_codes, 0);
    for (uint32_t x = 0; x < length; ++x) {
      const auto k = static_cast<uint32_t>(uint64_t{x} * n_codes / length);
      p.index_of[x] = k;
      first[k] = std::min(first[k], x);
      last[k] = std::max(last[k], x);
    }
    p.coord_of.resize(n_codes);
    for (uint32_t k = 0; k < n_codes; ++k) {
      p.coord_of[k] = 0.5f * static_cast<float>(first[k] + last[k]);  // every k has a span (length > n_codes)
      p.max_span = std::max(p.max_span, last[k] - first[k] + 1);
    }
    return p;
  }
  throw std::invalid_argument("unknown code '" + id + "' (gray, xor02, xor04, minsw)");
}

RunLengths interior_runs(const ProjectedCode& code, uint32_t plane) {
  std::vector<uint32_t> runs;
  uint32_t run = 1;
  for (uint32_t x = 1; x < code.length(); ++x) {
    if (code.bit(plane, x) == code.bit(plane, x - 1)) {
      ++run;
    } else {
      runs.push_back(run);
      run = 1;
    }
  }
  runs.push_back(run);
  if (runs.size() < 3) return {};
  RunLengths r{runs[1], runs[1]};
  for (size_t i = 1; i + 1 < runs.size(); ++i) {
    r.min_run = std::min(r.min_run, runs[i]);
    r.max_run = std::max(r.max_run, runs[i]);
  }
  return r;
}

}  // namespace procam::sl
