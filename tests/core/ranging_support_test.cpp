// RangingSupport: when a check of where the estimate is may judge it
// (LocalizerParams::max_outside_anchors_m).
#include "estimation/tracking/ranging_support.h"

#include <gtest/gtest.h>

#include <cstdint>

namespace rilo {
namespace {

constexpr std::int64_t kS = 1'000'000'000;

TEST(RangingSupport, NothingHeardSupportsNothing) {
  const RangingSupport support;
  EXPECT_FALSE(support.supports(0));
  EXPECT_FALSE(support.supports(100 * kS));
}

TEST(RangingSupport, SupportsAfterTheGraceAndUntilAGap) {
  RangingSupport support(3 * kS, 5 * kS);
  for (std::int64_t t = 10 * kS; t <= 20 * kS; t += kS / 40) {
    support.note(t);
    EXPECT_EQ(support.supports(t), t - 10 * kS >= 5 * kS) << "t = " << t;
  }
  // Ranging stops at 20 s: supported for 3 s more, then dead reckoning.
  EXPECT_TRUE(support.supports(23 * kS));
  EXPECT_FALSE(support.supports(23 * kS + 1));
  // Back after 10 s of silence: a new grace from the first measurement.
  support.note(30 * kS);
  EXPECT_FALSE(support.supports(30 * kS));
  support.note(34 * kS);  // 4 s later: a second gap, the grace starts again
  EXPECT_FALSE(support.supports(38 * kS));
  for (std::int64_t t = 35 * kS; t <= 39 * kS; t += kS) support.note(t);
  EXPECT_TRUE(support.supports(39 * kS)) << "5 s since 34 s without a gap";
}

TEST(RangingSupport, OneHertzRangingWithJitterIsNoGap) {
  // A 1 Hz tag (or --range-hz 1 with rotate thinning) has 1.0-1.1 s between
  // ranges; with a 1 s gap threshold the grace restarted on nearly every one.
  RangingSupport support;
  std::int64_t t = 0;
  for (int k = 0; k < 10; ++k) {
    support.note(t);
    t += kS + (k % 2) * kS / 10;
  }
  EXPECT_TRUE(support.supports(t - kS));
}

TEST(RangingSupport, OutOfOrderMeasurementsDoNotRestartTheGrace) {
  RangingSupport support(3 * kS, 5 * kS);
  for (std::int64_t t = 0; t <= 6 * kS; t += kS / 2) support.note(t);
  support.note(2 * kS);  // a late measurement from another source
  EXPECT_TRUE(support.supports(6 * kS));
  support.reset();
  EXPECT_FALSE(support.supports(6 * kS)) << "reset forgets";
}

}  // namespace
}  // namespace rilo
