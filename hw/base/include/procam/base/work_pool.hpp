// SPDX-License-Identifier: MIT
// WorkPool: persistent worker threads for per-pixel row loops, and
// parallel_bands(), the one thread-split helper of the project (the plugin
// SDK's sdk::parallel_rows and the simulator's sim::detail::parallel_rows are
// thin wrappers over it). Header-only, bottom layer (procam::base).
//
// Why a pool: starting and joining std::threads costs tens of microseconds per
// call; a streaming decoder folds 41 frames per round and the simulator runs a
// dozen row loops per frame, so both keep threads alive between jobs. Between
// jobs a worker spins briefly (kSpin pauses), then keeps offering its CPU
// with sched_yield() for kYieldSpin, and only then sleeps on a condition
// variable; run() spins briefly before waiting, so a job does not pay two
// futex wake-ups.
//
// Why the yield phase: a worker that sleeps lets its (virtual) CPU halt, and
// the next job pays a wake-up of that CPU -- 0.07-0.3 ms on the project's
// 2-core VM, where the pause phase is ~0.3 ms (18 ns per pause). A plugin
// running in a worker process (daemon/plugin_host) gets its calls one
// control round trip apart, 0.2-0.6 ms, so its helpers slept between every
// call of a scan while in-process they never did: the isolated 41-frame
// ensemble scan measured 1.24x in-process with the pause phase alone and
// 1.09-1.15x with a 2 ms yield phase (docs/benchmarks.md, "Plugin
// isolation"). sched_yield() hands the CPU to any runnable thread first, so
// the phase burns only CPU time nobody else wants; it ends after kYieldSpin
// at the latest, so an idle pool sleeps ~2.3 ms after its last job.
//
// Contract of WorkPool::for_each_band(bands, fn): fn(i) is called exactly once
// for every band index i in [0, bands), at most threads() at a time (the
// calling thread takes bands too; bands are taken dynamically from a shared
// ticket, so a worker that is not scheduled delays only the band it holds).
// It returns after every band finished; if bands threw, the first exception
// caught is rethrown on the calling thread (later bands still run: fn must
// tolerate that). WorkPool::run(rows, fn) splits [0, rows) into
// min(rows, 8 * threads) disjoint bands [y0, y1) and calls fn(y0, y1) for each.
// A pool is owned by one thread at a time: for_each_band/run must not be
// called concurrently or from inside fn (parallel_bands below handles both).
// Errors: the constructor throws std::system_error when a thread cannot be
// started (threads already started are joined) and std::bad_alloc.
#pragma once

#include <algorithm>
#include <sched.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace procam {

class WorkPool {
 public:
  explicit WorkPool(uint32_t threads) : threads_(std::max(1u, threads)) {
    workers_.reserve(threads_ - 1);
    try {
      for (uint32_t i = 1; i < threads_; ++i) workers_.emplace_back([this] { loop(); });
    } catch (...) {
      stop_and_join();
      throw;
    }
  }
  ~WorkPool() { stop_and_join(); }
  WorkPool(const WorkPool&) = delete;
  WorkPool& operator=(const WorkPool&) = delete;

  uint32_t threads() const { return threads_; }

  // fn(i) for every i in [0, bands); see the contract above.
  template <class Fn>
  void for_each_band(uint32_t bands, Fn&& fn) {
    if (bands == 0) return;
    if (threads_ == 1 || bands == 1) {
      for (uint32_t i = 0; i < bands; ++i) fn(i);
      return;
    }
    std::function<void(uint32_t)> job = [&fn](uint32_t i) { fn(i); };
    Job j{&job, bands, 0};
    {
      std::lock_guard<std::mutex> lock(mutex_);
      j.generation = generation_.load(std::memory_order_relaxed) + 1;
      job_ = j;
      first_ = nullptr;
      done_count_.store(0, std::memory_order_relaxed);
      ticket_.store(j.generation << 32, std::memory_order_release);
      generation_.store(j.generation, std::memory_order_release);
    }
    wake_.notify_all();
    work(j);  // the calling thread takes bands too
    for (int i = 0; i < kSpin && done_count_.load(std::memory_order_acquire) != j.bands; ++i) pause();
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return done_count_.load(std::memory_order_acquire) == j.bands; });
    job_ = Job{};
    if (first_) {
      std::exception_ptr e = first_;
      first_ = nullptr;
      std::rethrow_exception(e);
    }
  }

  // fn(y0, y1) over min(rows, 8 * threads) disjoint bands covering [0, rows).
  template <class Fn>
  void run(uint32_t rows, Fn&& fn) {
    if (rows == 0) return;
    if (threads_ == 1 || rows == 1) {
      fn(uint32_t{0}, rows);
      return;
    }
    const uint32_t bands = std::min(rows, threads_ * kChunksPerThread);
    for_each_band(bands, [&](uint32_t c) {
      fn(static_cast<uint32_t>(uint64_t{rows} * c / bands),
         static_cast<uint32_t>(uint64_t{rows} * (c + 1) / bands));
    });
  }

 private:
  static constexpr uint32_t kChunksPerThread = 8;
  static constexpr int kSpin = 1 << 14;  // 0.1-0.5 ms of pause instructions (CPU dependent)
  static constexpr std::chrono::microseconds kYieldSpin{2000};  // then offering the CPU (see above)
  struct Job {
    const std::function<void(uint32_t)>* fn = nullptr;
    uint32_t bands = 0;
    uint64_t generation = 0;
  };
  static void pause() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }
  void stop_and_join() noexcept {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
      generation_.fetch_add(1, std::memory_order_acq_rel);
    }
    wake_.notify_all();
    for (std::thread& t : workers_) t.join();
    workers_.clear();
  }
  // Takes bands of job j (ticket = generation << 32 | next band) until none
  // is left; a ticket of another generation means j is over.
  void work(const Job& j) {
    for (;;) {
      uint64_t t = ticket_.load(std::memory_order_acquire);
      uint32_t c = 0;
      do {
        c = static_cast<uint32_t>(t & 0xFFFFFFFFu);
        if ((t >> 32) != j.generation || c >= j.bands) return;
      } while (!ticket_.compare_exchange_weak(t, t + 1, std::memory_order_acq_rel));
      try {
        (*j.fn)(c);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!first_) first_ = std::current_exception();
      }
      if (done_count_.fetch_add(1, std::memory_order_acq_rel) + 1 == j.bands) {
        std::lock_guard<std::mutex> lock(mutex_);
        done_.notify_one();
      }
    }
  }
  void loop() {
    uint64_t seen = 0;
    for (;;) {
      uint64_t g = generation_.load(std::memory_order_acquire);
      for (int i = 0; i < kSpin && g == seen; ++i) {
        pause();
        g = generation_.load(std::memory_order_acquire);
      }
      if (g == seen) {
        const auto until = std::chrono::steady_clock::now() + kYieldSpin;
        while (g == seen && std::chrono::steady_clock::now() < until) {
          sched_yield();
          g = generation_.load(std::memory_order_acquire);
        }
      }
      Job j;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return generation_.load(std::memory_order_acquire) != seen; });
        seen = generation_.load(std::memory_order_acquire);
        if (stop_) return;
        j = job_;  // a copy: the owner may start the next job while this one drains
      }
      if (j.fn != nullptr && j.generation == seen) work(j);
    }
  }

  uint32_t threads_;
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  Job job_;
  std::atomic<uint64_t> ticket_{0};
  std::atomic<uint32_t> done_count_{0};
  std::atomic<uint64_t> generation_{0};
  bool stop_ = false;
  std::exception_ptr first_;
};

namespace detail {

// True while this thread runs a band of parallel_bands (caller or worker).
inline thread_local bool in_parallel_band = false;

// Marks the current thread as inside a band for the lifetime of the guard.
class BandScope {
 public:
  BandScope() noexcept : was_(in_parallel_band) { in_parallel_band = true; }
  ~BandScope() { in_parallel_band = was_; }
  BandScope(const BandScope&) = delete;
  BandScope& operator=(const BandScope&) = delete;

 private:
  bool was_;
};

// The pool of `threads` threads owned by the calling thread, created on first
// use; nullptr when its threads cannot be started.
//
// Why one pool per calling thread (thread_local) and not one process-wide
// pool: callers run concurrently (several scans' sessions in the daemon, the
// simulator rendering while a plugin decodes), and a shared pool would
// serialise them or need a lease protocol; a thread-local pool needs no lock
// at all. Its workers are joined when the owning thread exits, and because
// the pool is a thread_local with a destructor, a plugin library that created
// one stays mapped until then even if the host dlclose()s it (glibc defers
// the unload), so no worker ever runs unmapped code. A thread keeps at most
// kMaxPools pools (distinct thread counts), dropping the oldest.
inline WorkPool* thread_pool(uint32_t threads) {
  constexpr size_t kMaxPools = 4;
  thread_local std::vector<std::unique_ptr<WorkPool>> pools;
  for (const std::unique_ptr<WorkPool>& p : pools)
    if (p->threads() == threads) return p.get();
  std::unique_ptr<WorkPool> pool;
  try {
    pool = std::make_unique<WorkPool>(threads);
  } catch (const std::system_error&) {
    return nullptr;
  }
  if (pools.size() >= kMaxPools) pools.erase(pools.begin());
  pools.push_back(std::move(pool));
  return pools.back().get();
}

}  // namespace detail

// fn(i) for every band index i in [0, bands), on up to `threads` threads
// (the calling thread included), through the calling thread's persistent pool
// of `threads` threads (detail::thread_pool). Returns after every band
// finished; the first exception a band threw is rethrown on the calling
// thread. A call made from inside a band (nested), with one thread or one
// band, or when the pool's threads cannot be started, runs its bands one after
// another on the calling thread instead (the first exception then ends the
// loop): same bands, no thread explosion, no deadlock.
// Thread-safety: any thread may call it, concurrently with other threads.
template <class Fn>
void parallel_bands(uint32_t bands, uint32_t threads, Fn&& fn) {
  if (bands == 0) return;
  // The pool is chosen by `threads` alone, not min(threads, bands): callers
  // whose band count varies call after call (the simulator's row loops) keep
  // one pool; idle workers of a job with fewer bands find no ticket and sleep.
  threads = std::max(1u, threads);
  WorkPool* pool = (threads == 1 || bands == 1 || detail::in_parallel_band)
                       ? nullptr
                       : detail::thread_pool(threads);
  if (pool == nullptr) {
    const detail::BandScope scope;
    for (uint32_t i = 0; i < bands; ++i) fn(i);
    return;
  }
  pool->for_each_band(bands, [&fn](uint32_t i) {
    const detail::BandScope scope;
    fn(i);
  });
}

}  // namespace procam
