// SPDX-License-Identifier: MIT
// Scan request de-duplication for ScanService (internal): a retried `scan`
// request (same request id, same content) is answered with the scan it
// already queued instead of queueing a second one.
//
// Threads: not thread-safe; ScanService calls it with its mutex held.
// Memory: at most `max_entries` keys (plus the one being added) are kept.
#pragma once

#include <chrono>
#include <cstddef>
#include <deque>
#include <map>
#include <string>
#include <utility>

namespace procam::engine {

// The key under which a scan request is remembered: its id and a digest of
// its content (two different 64-bit hashes and the length).
std::string request_key(const std::string& id, const std::string& content);

class RequestMemory {
public:
  using Clock = std::chrono::steady_clock;

  // Keys are forgotten `window` after they were remembered, or (oldest
  // first) while more than `max_entries` are kept.
  RequestMemory(std::chrono::seconds window, size_t max_entries)
      : window_(window), max_(max_entries) {}

  // Forgets the keys that are too old or too many at time `now`.
  void forget_old(Clock::time_point now);
  // The scan id remembered for `key`, or nullptr (valid until the next call).
  const std::string* find(const std::string& key) const;
  // Remembers key -> scan_id at `now` (a key remembered again is renewed).
  void remember(const std::string& key, std::string scan_id, Clock::time_point now);
  size_t size() const { return requests_.size(); }

private:
  struct Remembered {
    std::string scan_id;
    Clock::time_point at;
  };
  std::chrono::seconds window_;
  size_t max_;
  std::map<std::string, Remembered> requests_;  // request id + content digest -> scan
  std::deque<std::pair<Clock::time_point, std::string>> order_;
};

}  // namespace procam::engine
