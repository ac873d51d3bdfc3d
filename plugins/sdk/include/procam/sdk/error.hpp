// SPDX-License-Identifier: MIT
// procam::sdk::Error — the code + message a plugin's C++ code returns instead of
// throwing; the SDK turns it into a PROCAM_ERR_* return and a procam_error.
//
// Contract: an Error whose code is PROCAM_OK means success and carries no
// message; every other Error carries a message that names the problem and,
// where possible, what to do ("frame 3 is 640x480, expected 1280x800").
// Thread-safety: a plain value type; no shared state.
#pragma once

#include <cstring>
#include <string>
#include <utility>

#include "procam/plugin_abi.h"

namespace procam::sdk {

struct Error {
  int code = PROCAM_OK;  // PROCAM_OK or a PROCAM_ERR_* value
  std::string message;

  bool ok() const noexcept { return code == PROCAM_OK; }
};

inline Error ok() { return {}; }
inline Error invalid_argument(std::string message) {
  return {PROCAM_ERR_INVALID_ARGUMENT, std::move(message)};
}
inline Error bad_frame(std::string message) { return {PROCAM_ERR_BAD_FRAME, std::move(message)}; }
inline Error state_error(std::string message) { return {PROCAM_ERR_STATE, std::move(message)}; }
inline Error no_memory(std::string message) { return {PROCAM_ERR_NO_MEMORY, std::move(message)}; }
inline Error internal_error(std::string message) {
  return {PROCAM_ERR_INTERNAL, std::move(message)};
}
// Something the method needs is missing from the rig or the request (ABI 2),
// e.g. "rig has no calibration table 'defocus.multi-focal': run `procam
// calibrate defocus/multi-focal` on a plane (docs/calibration.md)".
inline Error failed_precondition(std::string message) {
  return {PROCAM_ERR_FAILED_PRECONDITION, std::move(message)};
}

// "PROCAM_ERR_BAD_FRAME" etc., for messages and test output (procam_rc_name
// of plugin_abi.h, shared with the host).
inline const char* code_name(int code) noexcept {
  const char* name = procam_rc_name(code);
  return name != nullptr ? name : "PROCAM_ERR_(unknown)";
}

// Copy `message` into err->message, NUL-terminated. Longer messages are cut at
// a UTF-8 character boundary and end in "..." so a reader sees the cut.
// `err` may be NULL (the host did not ask for details). Never throws.
inline void write_error(procam_error* err, const char* message) noexcept {
  if (err == nullptr) return;
  if (message == nullptr) message = "";
  constexpr size_t cap = sizeof(err->message) - 1;  // room for the NUL
  size_t n = std::strlen(message);
  if (n <= cap) {
    std::memcpy(err->message, message, n);
    err->message[n] = '\0';
    return;
  }
  size_t keep = cap - 3;  // room for "..."
  // Step back over UTF-8 continuation bytes (10xxxxxx) so no character is split.
  while (keep > 0 && (static_cast<unsigned char>(message[keep]) & 0xC0u) == 0x80u) --keep;
  std::memcpy(err->message, message, keep);
  std::memcpy(err->message + keep, "...", 3);
  err->message[keep + 3] = '\0';
}

}  // namespace procam::sdk
