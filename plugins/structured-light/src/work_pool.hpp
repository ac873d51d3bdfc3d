// SPDX-License-Identifier: MIT
// WorkPool: persistent worker threads for the per-frame row loops of the
// streaming decoders. sdk::parallel_rows starts and joins std::threads on
// every call; a round of 41 frames would pay that 41+ times, so a decoder
// keeps one pool for its lifetime (threads started in the constructor, joined
// in the destructor). Between jobs a worker spins briefly (kSpin pauses)
// before sleeping on a condition variable, and run() spins briefly before
// waiting, so a frame's fold does not pay two futex wake-ups.
//
// Contract of run(): like sdk::parallel_rows — fn(y0, y1) is called for
// disjoint bands [y0, y1) covering [0, rows) exactly once each, at most
// `threads` at a time (the calling thread takes bands too; bands are up to
// 8 per thread, taken dynamically); returns after every band finished; the
// first exception thrown by a band is rethrown on the calling thread. run()
// must not be called concurrently or from inside fn.
// Thread-safety: one owner thread calls run(); the workers only run bands.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace procam::sl {

class WorkPool {
 public:
  explicit WorkPool(uint32_t threads) : threads_(std::max(1u, threads)) {
    workers_.reserve(threads_ - 1);
    for (uint32_t i = 1; i < threads_; ++i) workers_.emplace_back([this] { loop(); });
  }
  ~WorkPool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
      generation_.fetch_add(1, std::memory_order_acq_rel);
    }
    wake_.notify_all();
    for (std::thread& t : workers_) t.join();
  }
  WorkPool(const WorkPool&) = delete;
  WorkPool& operator=(const WorkPool&) = delete;

  uint32_t threads() const { return threads_; }

  template <class Fn>
  void run(uint32_t rows, Fn&& fn) {
    if (rows == 0) return;
    if (threads_ == 1 || rows == 1) {
      fn(uint32_t{0}, rows);
      return;
    }
    std::function<void(uint32_t, uint32_t)> job = [&fn](uint32_t a, uint32_t b) { fn(a, b); };
    Job j{&job, rows, std::min(rows, threads_ * kChunksPerThread), 0};
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
    work(j);  // the calling thread takes chunks too
    for (int i = 0; i < kSpin && done_count_.load(std::memory_order_acquire) != j.chunks; ++i) pause();
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return done_count_.load(std::memory_order_acquire) == j.chunks; });
    job_ = Job{};
    if (first_) {
      std::exception_ptr e = first_;
      first_ = nullptr;
      std::rethrow_exception(e);
    }
  }

 private:
  // Rows are split into chunks that threads take from a shared ticket, so a
  // worker that is not scheduled (a busy machine) delays only the chunk it
  // holds, not a fixed half of the rows.
  static constexpr uint32_t kChunksPerThread = 8;
  static constexpr int kSpin = 1 << 14;  // 0.1-0.5 ms of pause instructions (CPU dependent)
  struct Job {
    const std::function<void(uint32_t, uint32_t)>* fn = nullptr;
    uint32_t rows = 0, chunks = 0;
    uint64_t generation = 0;
  };
  static void pause() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }
  // Takes chunks of job j (ticket = generation << 32 | next chunk) until none
  // is left; a ticket of another generation means j is over.
  void work(const Job& j) {
    for (;;) {
      uint64_t t = ticket_.load(std::memory_order_acquire);
      uint32_t c = 0;
      do {
        c = static_cast<uint32_t>(t & 0xFFFFFFFFu);
        if ((t >> 32) != j.generation || c >= j.chunks) return;
      } while (!ticket_.compare_exchange_weak(t, t + 1, std::memory_order_acq_rel));
      const auto y0 = static_cast<uint32_t>(uint64_t{j.rows} * c / j.chunks);
      const auto y1 = static_cast<uint32_t>(uint64_t{j.rows} * (c + 1) / j.chunks);
      try {
        (*j.fn)(y0, y1);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!first_) first_ = std::current_exception();
      }
      if (done_count_.fetch_add(1, std::memory_order_acq_rel) + 1 == j.chunks) {
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
      Job j;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return generation_.load(std::memory_order_acquire) != seen; });
        seen = generation_.load(std::memory_order_acquire);
        if (stop_) return;
        j = job_;  // a copy: run() may start the next job while this one drains
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

}  // namespace procam::sl
