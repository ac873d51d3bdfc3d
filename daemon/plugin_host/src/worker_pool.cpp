// SPDX-License-Identifier: MIT
// Idle workers kept between sessions of one plugin (worker_proxy.hpp
// IdlePool; README.md "Worker reuse").
#include <algorithm>

#include "worker_proxy.hpp"

namespace procam::host::detail {
using Clock = std::chrono::steady_clock;

IdlePool::IdlePool(IsolationOptions o) : options(std::move(o)), reaper_([this] { reaper(); }) {}

IdlePool::~IdlePool() {
  {
    std::lock_guard lock(mu);
    stop_ = true;
  }
  wake_.notify_all();
  reaper_.join();
  // `idle` goes with the members: every idle worker is killed and reaped.
}

void IdlePool::reaper() {
  std::unique_lock lock(mu);
  while (!stop_) {
    std::vector<std::unique_ptr<WorkerProxy>> expired;
    expire_locked(expired);
    if (!expired.empty()) {
      lock.unlock();
      expired.clear();  // killed and reaped unlocked
      lock.lock();
      continue;
    }
    if (idle.empty()) {
      wake_.wait(lock);
    } else {
      auto first = idle.front().since;
      for (const Entry& e : idle) first = std::min(first, e.since);
      wake_.wait_until(lock, first + options.idle_timeout);
    }
  }
}

void IdlePool::expire_locked(std::vector<std::unique_ptr<WorkerProxy>>& out) {
  const auto now = Clock::now();
  for (auto it = idle.begin(); it != idle.end();) {
    if (now - it->since >= options.idle_timeout) {
      out.push_back(std::move(it->worker));
      it = idle.erase(it);
    } else {
      ++it;
    }
  }
}

std::unique_ptr<WorkerProxy> IdlePool::take(const std::string& plugin) {
  std::vector<std::unique_ptr<WorkerProxy>> expired;  // killed after the lock is released
  std::unique_ptr<WorkerProxy> found;
  {
    std::lock_guard lock(mu);
    expire_locked(expired);
    // The most recently used one: its memory is the warmest.
    for (auto it = idle.rbegin(); it != idle.rend(); ++it)
      if (it->worker->plugin() == plugin) {
        found = std::move(it->worker);
        idle.erase(std::next(it).base());
        break;
      }
  }
  return found;
}

void IdlePool::give(std::unique_ptr<WorkerProxy> worker, bool session_clean) {
  if (!worker) return;
  std::vector<std::unique_ptr<WorkerProxy>> dropped;
  // The round trip to the worker runs unlocked: sessions of other plugins
  // may end at the same time.
  if (!session_clean || options.max_idle_workers == 0 || !worker->end_session_for_reuse()) {
    dropped.push_back(std::move(worker));
    return;
  }
  std::lock_guard lock(mu);
  expire_locked(dropped);
  const auto same = std::count_if(idle.begin(), idle.end(),
                                  [&](const Entry& e) { return e.worker->plugin() == worker->plugin(); });
  if (static_cast<uint32_t>(same) >= options.max_idle_workers)
    dropped.push_back(std::move(worker));
  else
    idle.push_back({std::move(worker), Clock::now()});
  wake_.notify_all();  // the reaper learns the new deadline
}
// (`dropped` is destroyed after the lock_guard: reverse declaration order.)

size_t IdlePool::idle_count() {
  std::vector<std::unique_ptr<WorkerProxy>> expired;
  std::lock_guard lock(mu);
  expire_locked(expired);
  return idle.size();
}

}  // namespace procam::host::detail
