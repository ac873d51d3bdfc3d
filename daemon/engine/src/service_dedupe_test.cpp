// SPDX-License-Identifier: MIT
// Tests for scan request de-duplication (service_dedupe.hpp): keys, expiry,
// the entry limit and renewal of a key remembered twice.
#include "service_dedupe.hpp"

#include <gtest/gtest.h>

namespace procam::engine {
namespace {

using namespace std::chrono_literals;
using Clock = RequestMemory::Clock;

TEST(RequestKey, SameRequestSameKeyAndAnyDifferenceChangesIt) {
  const std::string a = request_key("req-1", R"({"plugin":"x"})");
  EXPECT_EQ(a, request_key("req-1", R"({"plugin":"x"})"));
  EXPECT_NE(a, request_key("req-2", R"({"plugin":"x"})"));
  EXPECT_NE(a, request_key("req-1", R"({"plugin":"y"})"));
  // An id that ends like another's digest must not collide: the id is
  // separated from the digest by a newline, which ids never contain.
  EXPECT_EQ(a.rfind("req-1\n", 0), 0u);
  // Content that differs only by a trailing NUL byte still differs.
  EXPECT_NE(request_key("r", "ab"), request_key("r", std::string("ab\0", 3)));
}

TEST(RequestMemory, FindsWithinTheWindowAndForgetsAfterIt) {
  RequestMemory m(10s, 100);
  const auto t0 = Clock::time_point{} + 1000s;
  m.remember("k", "scan-1", t0);
  m.forget_old(t0 + 9s);
  ASSERT_NE(m.find("k"), nullptr);
  EXPECT_EQ(*m.find("k"), "scan-1");
  EXPECT_EQ(m.find("other"), nullptr);
  m.forget_old(t0 + 10s);  // exactly the window: still kept (strictly older goes)
  EXPECT_NE(m.find("k"), nullptr);
  m.forget_old(t0 + 11s);
  EXPECT_EQ(m.find("k"), nullptr);
  EXPECT_EQ(m.size(), 0u);
}

TEST(RequestMemory, KeepsAtMostMaxEntriesDroppingTheOldest) {
  RequestMemory m(600s, 2);
  const auto t0 = Clock::time_point{} + 1000s;
  m.remember("a", "s-a", t0);
  m.remember("b", "s-b", t0 + 1s);
  m.remember("c", "s-c", t0 + 2s);
  m.forget_old(t0 + 3s);
  EXPECT_EQ(m.find("a"), nullptr);
  ASSERT_NE(m.find("b"), nullptr);
  ASSERT_NE(m.find("c"), nullptr);
  EXPECT_EQ(*m.find("c"), "s-c");
  EXPECT_EQ(m.size(), 2u);
}

TEST(RequestMemory, AKeyRememberedAgainLivesFromItsLastTime) {
  RequestMemory m(10s, 100);
  const auto t0 = Clock::time_point{} + 1000s;
  m.remember("k", "scan-1", t0);
  m.remember("k", "scan-2", t0 + 5s);
  m.forget_old(t0 + 12s);  // the first entry expired, the renewal has not
  ASSERT_NE(m.find("k"), nullptr);
  EXPECT_EQ(*m.find("k"), "scan-2");
  m.forget_old(t0 + 16s);
  EXPECT_EQ(m.find("k"), nullptr);
}

}  // namespace
}  // namespace procam::engine
