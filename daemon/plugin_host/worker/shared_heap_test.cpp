// SPDX-License-Identifier: MIT
// The worker's shared heap allocator (shared_heap.hpp), here without the
// worker's operator new: large blocks only, page-aligned, in one sealed
// memfd; freed blocks are reused (best fit) and merged, and the heap's top
// comes down when its last block goes; what it does not serve it refuses
// (nullptr) so the caller falls back to malloc.
#include "shared_heap.hpp"

#include <gtest/gtest.h>
#include <fcntl.h>

#include <cstdint>
#include <cstring>
#include <vector>

namespace procam::worker::heap {
namespace {

constexpr size_t kMiB = size_t{1} << 20;

bool inside(const void* p, size_t n) {
  const auto* b = static_cast<const uint8_t*>(p);
  return b >= base() && b + n <= base() + size();
}

// One test: the heap is per process and created once.
TEST(SharedHeapTest, ServesLargeBlocksReusesAndMergesFreedOnesAndRefusesTheRest) {
  ASSERT_TRUE(init(64 * kMiB + 123));
  EXPECT_FALSE(init(64 * kMiB)) << "a second heap";
  EXPECT_EQ(size(), 64 * kMiB);  // rounded down to pages
  ASSERT_GE(fd(), 0);
  const int seals = ::fcntl(fd(), F_GET_SEALS);
  EXPECT_EQ(seals & (F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL), F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL);

  EXPECT_EQ(allocate(kMinBlock - 1, 1), nullptr) << "small blocks are malloc's";
  EXPECT_EQ(allocate(8 * kMiB, 2 * kPage), nullptr) << "alignment beyond a page";
  EXPECT_EQ(allocate(65 * kMiB, 1), nullptr) << "bigger than the heap";

  void* a = allocate(8 * kMiB, 64);
  void* b = allocate(8 * kMiB + 1, 1);
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_TRUE(owns(a) && owns(b));
  EXPECT_TRUE(inside(a, 8 * kMiB) && inside(b, 8 * kMiB + 1));
  EXPECT_EQ(reinterpret_cast<uintptr_t>(a) % kPage, 0u);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(b) % kPage, 0u);
  EXPECT_GE(static_cast<uint8_t*>(b) - static_cast<uint8_t*>(a), static_cast<ptrdiff_t>(8 * kMiB)) << "overlap";
  std::memset(a, 1, 8 * kMiB);  // writable, the whole block
  std::memset(b, 2, 8 * kMiB + 1);
  EXPECT_EQ(used_bytes(), (8 * kMiB + kPage) + (8 * kMiB + 2 * kPage));

  // A freed block is where the next block of its size goes (its pages are
  // already there), and b is untouched by that.
  release(a);
  void* c = allocate(8 * kMiB, 1);
  EXPECT_EQ(c, a);
  EXPECT_EQ(static_cast<uint8_t*>(b)[8 * kMiB], 2);

  // Not a block start, or freed twice: ignored (leaked), never reused twice.
  const size_t before = used_bytes();
  release(static_cast<uint8_t*>(b) + kPage);
  release(c);
  release(c);
  EXPECT_EQ(used_bytes(), before - (8 * kMiB + kPage));

  // Fill the heap; it refuses what does not fit, then, all freed, the
  // blocks merge and the top comes down: one block of nearly all of it fits.
  std::vector<void*> blocks{b};
  while (void* p = allocate(4 * kMiB, 1)) blocks.push_back(p);
  EXPECT_GE(blocks.size(), 12u);
  EXPECT_EQ(allocate(4 * kMiB, 1), nullptr);
  for (void* p : blocks) release(p);
  EXPECT_EQ(used_bytes(), 0u);
  void* big = allocate(64 * kMiB - kPage, 1);
  EXPECT_EQ(big, base() + kPage);
  release(big);
  close_fd();
  EXPECT_EQ(fd(), -1);
}

}  // namespace
}  // namespace procam::worker::heap
