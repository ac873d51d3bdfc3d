// SPDX-License-Identifier: MIT
// Gray code as a StripeCode (thesis §3.2).
#include "gray_code.hpp"

#include <stdexcept>
#include <utility>
#include <vector>

namespace procam::sl {

StripeCode make_gray_code(uint32_t length) {
  if (length == 0 || length > (1u << StripeCode::kMaxBits))
    throw std::invalid_argument("Gray code length must be 1..65536, got " +
                                std::to_string(length));
  std::vector<uint32_t> words(length);
  for (uint32_t c = 0; c < length; ++c) words[c] = gray_encode(c);
  return make_stripe_code("binary-reflected Gray", code_bits(length), std::move(words));
}

}  // namespace procam::sl
