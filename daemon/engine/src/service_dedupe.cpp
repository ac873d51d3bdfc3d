// SPDX-License-Identifier: MIT
// Scan request de-duplication (see service_dedupe.hpp).
#include "service_dedupe.hpp"

#include <cstdint>
#include <cstdio>
#include <functional>

namespace procam::engine {

// The key under which a scan request is remembered: its id and a digest of
// its content (two different 64-bit hashes and the length).
std::string request_key(const std::string& id, const std::string& content) {
  uint64_t fnv = 1469598103934665603ull;
  for (char ch : content) fnv = (fnv ^ static_cast<unsigned char>(ch)) * 1099511628211ull;
  const uint64_t h = std::hash<std::string>{}(content);
  char buf[64];
  std::snprintf(buf, sizeof buf, "\n%016llx%016llx-%zu", static_cast<unsigned long long>(fnv),
                static_cast<unsigned long long>(h), content.size());
  return id + buf;
}

void RequestMemory::forget_old(Clock::time_point now) {
  while (!order_.empty() && (now - order_.front().first > window_ || order_.size() > max_)) {
    auto it = requests_.find(order_.front().second);
    if (it != requests_.end() && it->second.at == order_.front().first) requests_.erase(it);
    order_.pop_front();
  }
}

const std::string* RequestMemory::find(const std::string& key) const {
  auto it = requests_.find(key);
  return it == requests_.end() ? nullptr : &it->second.scan_id;
}

void RequestMemory::remember(const std::string& key, std::string scan_id, Clock::time_point now) {
  requests_[key] = {std::move(scan_id), now};
  order_.emplace_back(now, key);
}

}  // namespace procam::engine
