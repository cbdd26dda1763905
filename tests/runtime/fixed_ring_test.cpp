#include "runtime/fixed_ring.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace rilo {
namespace {

TEST(FixedRing, KeepsTheLastCapacityValuesOldestFirst) {
  FixedRing<int> ring(3);
  EXPECT_TRUE(ring.empty());
  EXPECT_FALSE(ring.push(1));
  EXPECT_FALSE(ring.push(2));
  EXPECT_FALSE(ring.push(3));
  EXPECT_TRUE(ring.full());
  EXPECT_TRUE(ring.push(4));  // drops 1
  EXPECT_TRUE(ring.push(5));  // drops 2
  ASSERT_EQ(ring.size(), 3u);
  EXPECT_EQ(ring[0], 3);
  EXPECT_EQ(ring[1], 4);
  EXPECT_EQ(ring[2], 5);
  EXPECT_EQ(ring.oldest(), 3);
  EXPECT_EQ(ring.newest(), 5);
  for (int v = 6; v < 100; ++v) ring.push(v);
  EXPECT_EQ(ring[0], 97);
  EXPECT_EQ(ring.newest(), 99);
  ring.clear();
  EXPECT_TRUE(ring.empty());
  ring.push(7);
  EXPECT_EQ(ring.oldest(), 7);
  EXPECT_EQ(ring.newest(), 7);
}

TEST(FixedRing, ZeroCapacityThrows) { EXPECT_THROW(FixedRing<int>(0), std::invalid_argument); }

}  // namespace
}  // namespace rilo
