// SPDX-License-Identifier: MIT
// Status and Result<T>: error values that cross thread, plugin and protocol
// boundaries instead of exceptions.
//
// Contract: a failed Status always carries a message that says what was wrong
// and, where possible, what to do ("hint"). Functions that can fail return
// Status or Result<T>; they never throw across a component boundary.
#pragma once

#include <cassert>
#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace procam {

// Error codes shared by the engine and the wire protocol (proto/ maps them 1:1
// to the protocol's string codes; see proto/PROTOCOL.md "Errors").
enum class Code {
  ok = 0,
  invalid_argument,   // caller gave a bad value (parameter, config field, request)
  not_found,          // named thing does not exist (plugin, method, scan, file, camera)
  unavailable,        // resource exists but cannot be used now (busy, hardware absent)
  failed_precondition,// operation not allowed in the current state
  io_error,           // file or device I/O failed
  corrupt_data,       // input data malformed (frame, image file, plugin binary)
  abi_mismatch,       // plugin built for another ABI
  plugin_error,       // a plugin reported failure
  timeout,            // deadline passed
  cancelled,          // cancelled by request or shutdown
  internal,           // a bug in procam: please report
  // Protocol-level errors (only produced by proto/ decoding):
  bad_message,        // not JSON, not an object, or a field of the wrong type
  unsupported_version,// "procam" version the daemon does not speak
  unknown_type,       // request "type" not in the protocol
  too_large,          // message or field over its size limit
};

const char* code_name(Code c) noexcept;

class Status {
public:
  Status() = default;  // ok
  Status(Code code, std::string message, std::string hint = {})
      : code_(code), message_(std::move(message)), hint_(std::move(hint)) {}

  static Status Ok() { return {}; }

  bool ok() const noexcept { return code_ == Code::ok; }
  explicit operator bool() const noexcept { return ok(); }
  Code code() const noexcept { return code_; }
  const std::string& message() const noexcept { return message_; }
  const std::string& hint() const noexcept { return hint_; }

  // "not_found: plugin 'x' is not loaded (hint: run `procam plugins`)".
  std::string to_string() const;

  // Prefix the message with context, e.g. "loading rig config: ".
  Status with_context(const std::string& context) const {
    if (ok()) return *this;
    return Status(code_, context + ": " + message_, hint_);
  }

private:
  Code code_ = Code::ok;
  std::string message_;
  std::string hint_;
};

inline Status Error(Code code, std::string message, std::string hint = {}) {
  return Status(code, std::move(message), std::move(hint));
}

// Result<T>: a value or a failed Status (std::expected is C++23).
template <typename T>
class Result {
public:
  Result(T value) : v_(std::move(value)) {}                // NOLINT(implicit)
  Result(Status status) : v_(std::move(status)) {          // NOLINT(implicit)
    assert(!std::get<Status>(v_).ok() && "Result built from an ok Status");
  }

  bool ok() const noexcept { return std::holds_alternative<T>(v_); }
  explicit operator bool() const noexcept { return ok(); }

  T& value() & { assert(ok()); return std::get<T>(v_); }
  const T& value() const& { assert(ok()); return std::get<T>(v_); }
  T&& value() && { assert(ok()); return std::get<T>(std::move(v_)); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

  // The error; Status::Ok() when this holds a value.
  Status status() const { return ok() ? Status::Ok() : std::get<Status>(v_); }

private:
  std::variant<T, Status> v_;
};

inline Status status_of(const Status& s) { return s; }
template <typename T>
Status status_of(const Result<T>& r) { return r.status(); }

}  // namespace procam

// Propagate a failed Status (or the error of a Result) from the current function.
#define PROCAM_TRY(expr)                                          \
  do {                                                            \
    auto&& procam_try_v_ = (expr);                                \
    if (!procam_try_v_.ok()) return ::procam::status_of(procam_try_v_); \
  } while (0)
