// SPDX-License-Identifier: MIT
// Status helpers.
#include "procam/core/status.hpp"

namespace procam {

const char* code_name(Code c) noexcept {
  switch (c) {
    case Code::ok: return "ok";
    case Code::invalid_argument: return "invalid_argument";
    case Code::not_found: return "not_found";
    case Code::unavailable: return "unavailable";
    case Code::failed_precondition: return "failed_precondition";
    case Code::io_error: return "io_error";
    case Code::corrupt_data: return "corrupt_data";
    case Code::abi_mismatch: return "abi_mismatch";
    case Code::plugin_error: return "plugin_error";
    case Code::timeout: return "timeout";
    case Code::cancelled: return "cancelled";
    case Code::internal: return "internal";
    case Code::bad_message: return "bad_message";
    case Code::unsupported_version: return "unsupported_version";
    case Code::unknown_type: return "unknown_type";
    case Code::too_large: return "too_large";
  }
  return "internal";
}

std::string Status::to_string() const {
  if (ok()) return "ok";
  std::string s = std::string(code_name(code_)) + ": " + message_;
  if (!hint_.empty()) s += " (hint: " + hint_ + ")";
  return s;
}

}  // namespace procam
