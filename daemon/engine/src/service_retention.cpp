// SPDX-License-Identifier: MIT
// ScanService retention: deletes the oldest finished scans while a limit of
// RetentionPolicy is exceeded (see service.hpp).
#include <algorithm>
#include <ctime>
#include <filesystem>
#include <tuple>
#include <vector>

#include "procam/core/log.hpp"
#include "service_internal.hpp"

namespace procam::engine {
namespace fs = std::filesystem;
using service_detail::is_final;

size_t ScanService::apply_retention() {
  const auto& pol = cfg_.retention;
  struct Cand { std::string finished, id; uint64_t bytes; };
  std::vector<Cand> cands;
  uint64_t total = 0;
  const auto now = std::chrono::steady_clock::now();
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, r] : scans_) {
      if (!is_final(r->state)) continue;
      total += r->bytes;
      if (r->last_download && now - *r->last_download < pol.download_grace) continue;  // being downloaded
      cands.push_back({r->finished_utc, id, r->bytes});
    }
    results_bytes_ = total;
  }
  if (pol.max_age_days <= 0 && pol.max_scans == 0 && pol.min_free_mb == 0) return 0;
  std::sort(cands.begin(), cands.end(),
            [](const Cand& a, const Cand& b) { return std::tie(a.finished, a.id) < std::tie(b.finished, b.id); });
  size_t stored = 0;
  {
    std::lock_guard lock(mu_);
    for (const auto& [id, r] : scans_) stored += is_final(r->state);
  }
  const std::time_t cutoff =
      std::time(nullptr) - static_cast<std::time_t>(pol.max_age_days * 86400.0);
  char cutoff_utc[32] = "";
  if (pol.max_age_days > 0) {
    std::tm tm{};
    gmtime_r(&cutoff, &tm);
    std::strftime(cutoff_utc, sizeof cutoff_utc, "%Y-%m-%dT%H:%M:%S", &tm);
  }
  auto low_disk = [&] {
    if (pol.min_free_mb == 0) return false;
    std::error_code ec;
    auto sp = fs::space(cfg_.results_dir, ec);
    return !ec && sp.available < pol.min_free_mb * 1024 * 1024;
  };
  size_t deleted = 0;
  for (const auto& c : cands) {
    const bool too_old = pol.max_age_days > 0 && !c.finished.empty() && c.finished < std::string(cutoff_utc);
    const bool too_many = pol.max_scans > 0 && stored > pol.max_scans;
    if (!too_old && !too_many && !low_disk()) continue;
    {
      std::lock_guard lock(mu_);
      auto it = scans_.find(c.id);
      if (it == scans_.end()) continue;
      if (it->second->last_download && now - *it->second->last_download < pol.download_grace) continue;
      scans_.erase(it);
      results_bytes_ -= std::min(results_bytes_, c.bytes);
    }
    // Rename first so a half-deleted folder is never loaded as a scan.
    std::error_code ec;
    const fs::path dir = fs::path(cfg_.results_dir) / c.id;
    const fs::path doomed = fs::path(cfg_.results_dir) / ("." + c.id + ".deleting");
    fs::rename(dir, doomed, ec);
    fs::remove_all(ec ? dir : doomed, ec);
    --stored;
    ++deleted;
    PROCAM_LOG(engine, info) << "retention: deleted scan " << c.id << " (finished " << c.finished << ")"
                             << (too_old ? " [age]" : too_many ? " [count]" : " [disk]");
  }
  return deleted;
}

}  // namespace procam::engine
