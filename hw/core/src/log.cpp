// SPDX-License-Identifier: MIT
// Category logger writing whole lines to stderr with a UTC timestamp.
#include "procam/core/log.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <map>
#include <mutex>
#include <shared_mutex>

namespace procam::log {
namespace {

struct State {
  std::shared_mutex mu;
  Level default_level = Level::info;
  std::map<std::string, Level, std::less<>> per_category;
  std::mutex write_mu;
  State() {
    if (const char* env = std::getenv("PROCAM_LOG")) configure_locked(env);
  }
  bool configure_locked(std::string_view spec) {
    Level def = default_level;
    std::map<std::string, Level, std::less<>> cats;
    size_t pos = 0;
    while (pos <= spec.size()) {
      size_t end = spec.find(',', pos);
      if (end == std::string_view::npos) end = spec.size();
      std::string_view item = spec.substr(pos, end - pos);
      if (!item.empty()) {
        size_t eq = item.find('=');
        Level lv;
        if (eq == std::string_view::npos) {
          if (!parse_level(item, lv)) return false;
          def = lv;
        } else {
          if (eq == 0 || !parse_level(item.substr(eq + 1), lv)) return false;
          cats[std::string(item.substr(0, eq))] = lv;
        }
      }
      pos = end + 1;
    }
    default_level = def;
    per_category = std::move(cats);
    return true;
  }
};

State& state() {
  static State s;
  return s;
}

const char* level_name(Level l) {
  switch (l) {
    case Level::debug: return "DEBUG";
    case Level::info: return "INFO";
    case Level::warn: return "WARN";
    case Level::error: return "ERROR";
    case Level::off: return "OFF";
  }
  return "?";
}

}  // namespace

bool parse_level(std::string_view t, Level& out) {
  if (t == "debug") out = Level::debug;
  else if (t == "info") out = Level::info;
  else if (t == "warn" || t == "warning") out = Level::warn;
  else if (t == "error") out = Level::error;
  else if (t == "off") out = Level::off;
  else return false;
  return true;
}

bool configure(std::string_view spec) {
  State& s = state();
  std::unique_lock lock(s.mu);
  return s.configure_locked(spec);
}

bool enabled(std::string_view category, Level level) {
  State& s = state();
  std::shared_lock lock(s.mu);
  auto it = s.per_category.find(category);
  Level threshold = it == s.per_category.end() ? s.default_level : it->second;
  return level >= threshold && level != Level::off;
}

namespace {
// Length of the valid UTF-8 sequence starting at s[i] (RFC 3629 ranges), or 0.
size_t utf8_sequence(std::string_view s, size_t i) {
  const auto b = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = b(i);
  size_t n = 0;
  unsigned char lo = 0x80, hi = 0xBF;  // allowed range of the 2nd byte
  if (c >= 0xC2 && c <= 0xDF) n = 2;
  else if (c == 0xE0) { n = 3; lo = 0xA0; }
  else if ((c >= 0xE1 && c <= 0xEC) || c == 0xEE || c == 0xEF) n = 3;
  else if (c == 0xED) { n = 3; hi = 0x9F; }  // no UTF-16 surrogates
  else if (c == 0xF0) { n = 4; lo = 0x90; }
  else if (c >= 0xF1 && c <= 0xF3) n = 4;
  else if (c == 0xF4) { n = 4; hi = 0x8F; }  // <= U+10FFFF
  else return 0;
  if (i + n > s.size()) return 0;
  if (b(i + 1) < lo || b(i + 1) > hi) return 0;
  for (size_t k = 2; k < n; ++k)
    if (b(i + k) < 0x80 || b(i + k) > 0xBF) return 0;
  return n;
}
}  // namespace

std::string escape(std::string_view bytes) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(bytes.size());
  for (size_t i = 0; i < bytes.size();) {
    const auto c = static_cast<unsigned char>(bytes[i]);
    if (c >= 0x20 && c < 0x7F) {
      if (c == '\\') out += "\\\\";
      else out += static_cast<char>(c);
      ++i;
      continue;
    }
    if (c >= 0x80) {
      if (const size_t n = utf8_sequence(bytes, i); n > 0) {
        out.append(bytes.substr(i, n));
        i += n;
        continue;
      }
    }
    if (c == '\n') out += "\\n";
    else if (c == '\r') out += "\\r";
    else if (c == '\t') out += "\\t";
    else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
    ++i;
  }
  return out;
}

void write(std::string_view category, Level level, const std::string& raw_message) {
  const std::string message = escape(raw_message);
  using namespace std::chrono;
  auto now = system_clock::now();
  std::time_t t = system_clock::to_time_t(now);
  auto ms = duration_cast<milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  char ts[32];
  std::strftime(ts, sizeof ts, "%Y-%m-%dT%H:%M:%S", &tm);
  State& s = state();
  std::lock_guard lock(s.write_mu);
  std::fprintf(stderr, "%s.%03dZ %-5s [%.*s] %s\n", ts, static_cast<int>(ms), level_name(level),
               static_cast<int>(category.size()), category.data(), message.c_str());
  std::fflush(stderr);
}

}  // namespace procam::log
