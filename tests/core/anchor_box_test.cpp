// AnchorBox: the anchors' horizontal bounding box and the distance beyond it.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "estimation/measurements/anchor_box.h"

namespace rilo {
namespace {

TEST(AnchorBox, DistanceBeyondTheHorizontalBox) {
  const AnchorBox box({Vec3(0, 0, 2.5), Vec3(10, 0, 0.5), Vec3(10, 6, 2.0), Vec3(0, 6, 3.0)});
  EXPECT_EQ(box.outside(Vec3(5, 3, 1.2)), 0.0);
  EXPECT_EQ(box.outside(Vec3(10, 6, -4.0)), 0.0);   // on the edge, any height
  EXPECT_DOUBLE_EQ(box.outside(Vec3(-1.5, 3, 1.2)), 1.5);
  EXPECT_DOUBLE_EQ(box.outside(Vec3(5, 8, 1.2)), 2.0);
  EXPECT_DOUBLE_EQ(box.outside(Vec3(13, -4, 1.2)), 5.0);  // beyond a corner: 3-4-5
}

TEST(AnchorBox, PlaceholdersAreLeftOutAndNoAnchorMeansNoBox) {
  // Unused ids carry placeholders far away; they must not stretch the box.
  const AnchorBox box({Vec3(0, 0, 2), Vec3(1e5, 1e5, 0), Vec3(4, 4, 2), Vec3(-2e5, 0, 0)});
  EXPECT_DOUBLE_EQ(box.outside(Vec3(6, 2, 1)), 2.0);
  EXPECT_EQ(AnchorBox({}).outside(Vec3(100, 100, 0)), 0.0);
  EXPECT_EQ(AnchorBox({Vec3(1e6, 0, 0)}).outside(Vec3(100, 100, 0)), 0.0);
  EXPECT_EQ(AnchorBox({Vec3(std::nan(""), 0, 0)}).outside(Vec3(100, 100, 0)), 0.0);
}

}  // namespace
}  // namespace rilo
