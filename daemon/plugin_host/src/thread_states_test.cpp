// SPDX-License-Identifier: MIT
// ThreadStates (worker_proxy.hpp): the check that every thread of a stopped
// worker stopped, which keeps /proc files open between calls. It must read
// each thread's state anew on every call, see threads that were born after
// the files were kept, and not be fooled by kept files of threads that are
// gone.
#include <gtest/gtest.h>

#include <pthread.h>
#include <signal.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "worker_proxy.hpp"

using namespace std::chrono_literals;
using procam::host::detail::ThreadStates;

namespace {

using Clock = std::chrono::steady_clock;

void spin(std::chrono::microseconds d) {
  const auto t0 = Clock::now();
  while (Clock::now() - t0 < d) {
  }
}

// A thread that spins for 3 ms, starts its successor, spins 2 ms more beside
// it and ends: the child's threads are new ones every few milliseconds, and
// one is always running.
void* relay(void*) {
  spin(3ms);
  pthread_t next;
  if (pthread_create(&next, nullptr, relay, nullptr) == 0) pthread_detach(next);
  spin(2ms);
  return nullptr;
}

void* sleeper(void*) {
  for (;;) ::pause();
  return nullptr;
}

// Stops `pid` and waits for the kernel's report (consumed), at most 2 s.
bool stop_and_wait(pid_t pid) {
  if (::kill(pid, SIGSTOP) != 0) return false;
  siginfo_t info{};
  return ::waitid(P_PID, static_cast<id_t>(pid), &info, WSTOPPED) == 0 && info.si_code == CLD_STOPPED;
}

bool resume(pid_t pid) {
  if (::kill(pid, SIGCONT) != 0) return false;
  siginfo_t info{};
  return ::waitid(P_PID, static_cast<id_t>(pid), &info, WCONTINUED) == 0;
}

// settled() polled until true, as WorkerProxy::stop_wait does (a thread that
// was exiting when the stop came may need a moment to go).
bool settles(ThreadStates& states, pid_t pid) {
  const auto until = Clock::now() + 1s;
  while (Clock::now() < until)
    if (states.settled(pid)) return true;
  return false;
}

void end(pid_t pid) {
  ::kill(pid, SIGKILL);
  ::waitpid(pid, nullptr, 0);
}

}  // namespace

// The leader leaves (a zombie, which counts as settled) and a relay of
// short-lived threads runs on: each call while the child runs must find a
// running thread the kept files do not cover, and each stop must settle.
TEST(ThreadStatesTest, NewThreadsAreSeenAndGoneOnesDoNotCount) {
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    pthread_t first;
    if (pthread_create(&first, nullptr, relay, nullptr) != 0) ::_exit(1);
    pthread_detach(first);
    // The leader thread alone ends (SYS_exit, not exit_group; no unwinding
    // through the test framework, which pthread_exit would do).
    ::syscall(SYS_exit, 0);
  }
  ThreadStates states;
  int running_seen = 0, stops = 0;
  for (int i = 0; i < 40; ++i) {
    std::this_thread::sleep_for(2ms);  // a new thread or two since the last call
    running_seen += states.settled(pid) ? 0 : 1;
    if (i % 5 == 4) {
      ASSERT_TRUE(stop_and_wait(pid));
      EXPECT_TRUE(settles(states, pid)) << "stop " << stops;
      ++stops;
      ASSERT_TRUE(resume(pid));
    }
  }
  end(pid);
  // The calls on the running child saw a thread that was not stopped. Not
  // every one need: on a running process a thread listed and gone before
  // its file is read, with its successor born after the listing, leaves
  // nothing running to see (a CI run under load hit that once in 40; on a
  // stopped worker no thread is born). One that skips threads it did not
  // keep sees ~1 in 40.
  EXPECT_GE(running_seen, 34);
  EXPECT_EQ(stops, 8);
}

// More threads than the files it keeps open (kMaxOpen): the rest are read
// by name on each call, with the same answers.
TEST(ThreadStatesTest, MoreThreadsThanKeptFiles) {
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    for (size_t i = 0; i < ThreadStates::kMaxOpen + 8; ++i) {
      pthread_t t;
      if (pthread_create(&t, nullptr, sleeper, nullptr) != 0) ::_exit(1);
    }
    for (;;) ::pause();
  }
  std::this_thread::sleep_for(50ms);  // the threads exist
  ThreadStates states;
  for (int round = 0; round < 3; ++round) {
    EXPECT_FALSE(states.settled(pid)) << "round " << round << ": sleeping threads are not stopped";
    ASSERT_TRUE(stop_and_wait(pid));
    EXPECT_TRUE(settles(states, pid)) << "round " << round;
    ASSERT_TRUE(resume(pid));
    std::this_thread::sleep_for(5ms);
  }
  end(pid);
  // Another process through the same object: nothing of the first is used.
  EXPECT_FALSE(states.settled(pid)) << "a reaped process has no threads to be settled";
}
