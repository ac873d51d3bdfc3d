// SPDX-License-Identifier: MIT
// StripeCode construction: validate the words and build the decode table.
#include "stripe_code.hpp"

#include <stdexcept>
#include <utility>

namespace procam::sl {

StripeCode make_stripe_code(std::string name, uint32_t bits, std::vector<uint32_t> words) {
  if (bits == 0 || bits > StripeCode::kMaxBits)
    throw std::invalid_argument("stripe code '" + name + "': bits must be 1.." +
                                std::to_string(StripeCode::kMaxBits));
  if (words.empty()) throw std::invalid_argument("stripe code '" + name + "': no coordinates");
  StripeCode code;
  code.lut.assign(size_t{1} << bits, StripeCode::kInvalid);
  for (size_t c = 0; c < words.size(); ++c) {
    const uint32_t w = words[c];
    if (w >= code.lut.size())
      throw std::invalid_argument("stripe code '" + name + "': word of coordinate " +
                                  std::to_string(c) + " needs more than " + std::to_string(bits) +
                                  " bits");
    if (code.lut[w] != StripeCode::kInvalid)
      throw std::invalid_argument("stripe code '" + name + "': coordinates " +
                                  std::to_string(code.lut[w]) + " and " + std::to_string(c) +
                                  " share a word");
    code.lut[w] = static_cast<uint32_t>(c);
  }
  code.name = std::move(name);
  code.length = static_cast<uint32_t>(words.size());
  code.bits = bits;
  code.words = std::move(words);
  return code;
}

}  // namespace procam::sl
