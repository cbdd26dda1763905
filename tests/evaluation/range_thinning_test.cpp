#include "evaluation/range_thinning.h"

#include <gtest/gtest.h>

#include <map>
#include <stdexcept>

namespace rilo {
namespace {

// 40 Hz in cycles of four: the strongest anchor (0) always reported first.
std::vector<RangeSample> strongestFirst(int cycles) {
  std::vector<RangeSample> out;
  for (int c = 0; c < cycles; ++c) {
    for (std::uint32_t k = 0; k < 4; ++k) {
      RangeSample r;
      r.t_ns = 1'000'000'000 + c * 100'000'000LL + k * 25'000'000LL;
      r.anchor_id = k;
      r.range_m = 1.0 + k;
      out.push_back(r);
    }
  }
  return out;
}

TEST(RangeThinning, ZeroRateKeepsEverything) {
  const auto all = strongestFirst(10);
  EXPECT_EQ(thinRanges(all, {}).size(), all.size());
}

TEST(RangeThinning, FirstKeepsTheFirstRangeOfEachSlot) {
  RangeThinningOptions o;
  o.rate_hz = 1.0;
  o.mode = RangeThinning::kFirst;
  const auto kept = thinRanges(strongestFirst(100), o);  // 10 s
  ASSERT_EQ(kept.size(), 10u);
  for (std::size_t i = 0; i < kept.size(); ++i) {
    EXPECT_EQ(kept[i].anchor_id, 0u) << "the receiver's first report is always the strongest anchor";
    if (i > 0) {
      EXPECT_GE(kept[i].t_ns - kept[i - 1].t_ns, 1'000'000'000);
    }
  }
}

TEST(RangeThinning, RotateCyclesThroughTheAnchors) {
  RangeThinningOptions o;
  o.rate_hz = 1.0;
  const auto kept = thinRanges(strongestFirst(100), o);
  ASSERT_GE(kept.size(), 9u);
  std::map<std::uint32_t, int> per_anchor;
  for (std::size_t i = 0; i < kept.size(); ++i) {
    ++per_anchor[kept[i].anchor_id];
    if (i > 0) {
      EXPECT_GE(kept[i].t_ns - kept[i - 1].t_ns, 1'000'000'000) << "never faster than the rate";
      EXPECT_NE(kept[i].anchor_id, kept[i - 1].anchor_id);
    }
    if (i >= 4) {
      EXPECT_EQ(kept[i].anchor_id, kept[i - 4].anchor_id) << "round robin over the four anchors heard";
    }
  }
  EXPECT_EQ(per_anchor.size(), 4u);
}

TEST(RangeThinning, RotateOnlyPicksAmongTheNextCycle) {
  // Anchor 9 is heard once, 0.5 s after the slot opens: beyond one cycle, so
  // the slot does not wait for it.
  auto ranges = strongestFirst(3);
  RangeSample late;
  late.t_ns = ranges.front().t_ns + 150'000'000;
  late.anchor_id = 9;
  ranges.insert(ranges.begin() + 6, late);
  RangeThinningOptions o;
  o.rate_hz = 0.5;
  const auto kept = thinRanges(ranges, o);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].anchor_id, 0u);
}

TEST(RangeThinning, BadOptionsAreRejected) {
  RangeThinningOptions o;
  o.rate_hz = -1.0;
  EXPECT_THROW(thinRanges({}, o), std::invalid_argument);
  o.rate_hz = 1.0;
  o.cycle_ns = 0;
  EXPECT_THROW(thinRanges({}, o), std::invalid_argument);
  EXPECT_EQ(rangeThinningFromName("first"), RangeThinning::kFirst);
  EXPECT_EQ(rangeThinningFromName("rotate"), RangeThinning::kRotate);
  EXPECT_THROW(rangeThinningFromName("random"), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
