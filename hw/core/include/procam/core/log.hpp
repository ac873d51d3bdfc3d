// SPDX-License-Identifier: MIT
// Logging: one category per component, levels set from config or the
// PROCAM_LOG environment variable ("info", "debug", or "daemon=debug,sim=warn").
//
// Thread-safety: all functions are thread-safe; each line is written whole.
#pragma once

#include <sstream>
#include <string>
#include <string_view>

namespace procam::log {

enum class Level { debug = 0, info = 1, warn = 2, error = 3, off = 4 };

// Parse "debug"/"info"/"warn"/"error"/"off"; false if unknown.
bool parse_level(std::string_view text, Level& out);

// Apply a spec: "info" sets the default; "daemon=debug,sim=warn" per category.
// Returns false (and changes nothing) if the spec is malformed.
bool configure(std::string_view spec);
bool enabled(std::string_view category, Level level);
// Writes one line. The message is passed through escape() first, so text
// that came from a client or a plugin cannot forge or split log lines.
void write(std::string_view category, Level level, const std::string& message);

// One-line, valid-UTF-8 rendering of arbitrary bytes for a log line: control
// characters become \n, \r, \t or \xNN; a backslash becomes \\; bytes
// that are not part of a valid UTF-8 sequence (overlong forms, surrogates,
// code points past U+10FFFF, truncated sequences) become \xNN; valid
// multi-byte UTF-8 passes through unchanged. Reentrant.
std::string escape(std::string_view bytes);

class Line {
public:
  Line(std::string_view category, Level level) : category_(category), level_(level) {}
  ~Line() { write(category_, level_, os_.str()); }
  Line(const Line&) = delete;
  Line& operator=(const Line&) = delete;
  template <typename T>
  Line& operator<<(const T& v) { os_ << v; return *this; }

private:
  std::string_view category_;
  Level level_;
  std::ostringstream os_;
};

}  // namespace procam::log

// PROCAM_LOG(daemon, info) << "listening on " << endpoint;
// The message is only formatted when the level is enabled. A one-shot `for`
// (not `if`) keeps the macro safe inside an unbraced if/else.
#define PROCAM_LOG(category, level)                                               \
  for (bool procam_log_on_ = ::procam::log::enabled(#category, ::procam::log::Level::level); \
       procam_log_on_; procam_log_on_ = false)                                    \
  ::procam::log::Line(#category, ::procam::log::Level::level)
