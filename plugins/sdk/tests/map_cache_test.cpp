// SPDX-License-Identifier: MIT
// Tests of the output-map cache (procam/sdk/map_cache.hpp): storage given back
// is handed out again for the same type and size only, the byte limit holds,
// and a limit of 0 empties the cache.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "procam/sdk/map_cache.hpp"

namespace sdk = procam::sdk;

namespace {

// Each test starts from an empty cache with the default limit and restores it.
class MapCache : public ::testing::Test {
 protected:
  void SetUp() override {
    limit_ = sdk::map_cache_limit();
    sdk::set_map_cache_limit(0);
    sdk::set_map_cache_limit(limit_);
  }
  void TearDown() override {
    sdk::set_map_cache_limit(0);
    sdk::set_map_cache_limit(limit_);
  }
  size_t limit_ = 0;
};

TEST_F(MapCache, DefaultLimitIs192MiB) { EXPECT_EQ(limit_, size_t{192} << 20); }

TEST_F(MapCache, FreshMapsAreZeroedAndSized) {
  std::vector<float> f;
  sdk::take_map(f, 1000);
  ASSERT_EQ(f.size(), 1000u);
  for (float v : f) ASSERT_EQ(v, 0.0f);
  std::vector<uint8_t> u{1, 2, 3};
  sdk::take_map(u, 3);  // already the right size: left as it is
  EXPECT_EQ(u, (std::vector<uint8_t>{1, 2, 3}));
  EXPECT_EQ(sdk::map_cache_bytes(), 0u);
}

TEST_F(MapCache, GivenStorageComesBackForTheSameTypeAndSizeOnly) {
  std::vector<float> a(4096, 7.0f);
  const float* storage = a.data();
  sdk::give_map(std::move(a));
  EXPECT_EQ(sdk::map_cache_bytes(), 4096u * sizeof(float));
  std::vector<float> other_size;
  sdk::take_map(other_size, 4095);  // different size: fresh storage, cache untouched
  EXPECT_NE(other_size.data(), storage);
  EXPECT_EQ(sdk::map_cache_bytes(), 4096u * sizeof(float));
  std::vector<uint8_t> other_type;
  sdk::take_map(other_type, 4096 * sizeof(float));  // same bytes, other type: not shared
  EXPECT_EQ(sdk::map_cache_bytes(), 4096u * sizeof(float));
  std::vector<float> b;
  sdk::take_map(b, 4096);
  EXPECT_EQ(b.data(), storage);  // the very same pages
  EXPECT_EQ(b[17], 7.0f);        // stale contents, as documented
  EXPECT_EQ(sdk::map_cache_bytes(), 0u);
}

TEST_F(MapCache, NewestOfEqualSizesIsTakenFirst) {
  std::vector<uint8_t> a(100, 1), b(100, 2);
  const uint8_t* pb = b.data();
  sdk::give_map(std::move(a));
  sdk::give_map(std::move(b));
  std::vector<uint8_t> c;
  sdk::take_map(c, 100);
  EXPECT_EQ(c.data(), pb);
  EXPECT_EQ(sdk::map_cache_bytes(), 100u);
}

TEST_F(MapCache, LimitBoundsTheBytesKept) {
  sdk::set_map_cache_limit(250);
  sdk::give_map(std::vector<uint8_t>(100));
  sdk::give_map(std::vector<uint8_t>(100));
  EXPECT_EQ(sdk::map_cache_bytes(), 200u);
  sdk::give_map(std::vector<uint8_t>(100));  // 300 > 250: freed instead
  EXPECT_EQ(sdk::map_cache_bytes(), 200u);
  sdk::give_map(std::vector<uint8_t>(50));  // exactly at the limit: kept
  EXPECT_EQ(sdk::map_cache_bytes(), 250u);
  sdk::give_map(std::vector<float>());  // empty: nothing to keep
  EXPECT_EQ(sdk::map_cache_bytes(), 250u);
  sdk::set_map_cache_limit(0);  // disables and frees
  EXPECT_EQ(sdk::map_cache_bytes(), 0u);
  sdk::give_map(std::vector<uint8_t>(1));
  EXPECT_EQ(sdk::map_cache_bytes(), 0u);
}

TEST_F(MapCache, AllocateMapValueInitialisesAndKeepsRightSizedMaps) {
  std::vector<uint16_t> v(5, 9);
  sdk::allocate_map(v, 5);
  EXPECT_EQ(v, std::vector<uint16_t>(5, 9));
  sdk::allocate_map(v, 3u << 20);  // > 2 MiB: huge-page advice path
  ASSERT_EQ(v.size(), 3u << 20);
  EXPECT_EQ(v.front(), 0);
  EXPECT_EQ(v.back(), 0);
}

}  // namespace
