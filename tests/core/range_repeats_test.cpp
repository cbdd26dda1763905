// How many of an anchor's ranges share one error (estimation/measurements/
// range_repeats.h): the rate an antenna ranges an anchor times the
// correlation time, 1 where an anchor is heard less often than that, off,
// unknown or beyond the antennas followed; a pause counts as one window.
#include "estimation/measurements/range_repeats.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

constexpr std::int64_t kMs = 1'000'000;

RangeRepeats oneSecond(std::size_t anchors = 3) { return RangeRepeats(anchors, RangeRepeatsParams{1.0}); }

TEST(RangeRepeats, TheRateTimesTheCorrelationTime) {
  RangeRepeats r = oneSecond();
  EXPECT_DOUBLE_EQ(r.repeats(0, 0), 1.0) << "nothing heard";
  r.add(0, 0, 0);
  EXPECT_DOUBLE_EQ(r.repeats(0, 0), 1.0) << "one range: no rate yet";
  for (int k = 1; k <= 50; ++k) r.add(0, 0, k * 200 * kMs);  // 5 Hz
  EXPECT_NEAR(r.repeats(0, 0), 5.0, 1e-9);
  // Another antenna of the same anchor, and another anchor, have their own.
  for (int k = 0; k <= 50; ++k) r.add(0, 7, k * 100 * kMs);  // 10 Hz
  EXPECT_NEAR(r.repeats(0, 7), 10.0, 1e-9);
  EXPECT_NEAR(r.repeats(0, 0), 5.0, 1e-9);
  EXPECT_DOUBLE_EQ(r.repeats(1, 0), 1.0);
  // The rate follows a change within about ten ranges.
  for (int k = 1; k <= 30; ++k) r.add(0, 0, 10'000 * kMs + k * 100 * kMs);
  EXPECT_NEAR(r.repeats(0, 0), 10.0, 0.5);
}

TEST(RangeRepeats, AnAnchorHeardLessOftenThanTheWindowCountsAlone) {
  RangeRepeats r = oneSecond();
  for (int k = 0; k < 20; ++k) r.add(2, 0, k * 8000 * kMs);  // every 8 s, as at ~1 Hz over 8 anchors
  EXPECT_DOUBLE_EQ(r.repeats(2, 0), 1.0);
  // A pause is worth one window: ranging at 5 Hz again is back at 5 soon.
  RangeRepeats p = oneSecond();
  for (int k = 0; k <= 20; ++k) p.add(1, 0, k * 200 * kMs);
  p.add(1, 0, 600'000 * kMs);  // ten minutes later
  EXPECT_NEAR(p.repeats(1, 0), 1.0 / (0.9 * 0.2 + 0.1 * 1.0), 1e-9);
  for (int k = 1; k <= 20; ++k) p.add(1, 0, 600'000 * kMs + k * 200 * kMs);
  EXPECT_GT(p.repeats(1, 0), 4.0);
  // Ranges stamped alike count a millisecond apart: k stays finite.
  RangeRepeats same = oneSecond();
  for (int k = 0; k < 30; ++k) same.add(0, 0, 5 * kMs);
  EXPECT_NEAR(same.repeats(0, 0), 1000.0, 1e-6);
}

TEST(RangeRepeats, OffUnknownOrBeyondTheAntennasFollowedCountsAlone) {
  RangeRepeats off(3, RangeRepeatsParams{});
  EXPECT_FALSE(off.enabled());
  for (int k = 0; k < 20; ++k) off.add(0, 0, k * 25 * kMs);
  EXPECT_DOUBLE_EQ(off.repeats(0, 0), 1.0);

  RangeRepeats r = oneSecond();
  EXPECT_TRUE(r.enabled());
  for (int k = 0; k < 20; ++k) r.add(9, 0, k * 25 * kMs);  // no anchor 9
  EXPECT_DOUBLE_EQ(r.repeats(9, 0), 1.0);
  for (std::uint32_t tag = 0; tag < RangeRepeats::kTagsPerAnchor + 1; ++tag) {
    for (int k = 0; k < 20; ++k) r.add(1, tag, k * 100 * kMs);
  }
  for (std::uint32_t tag = 0; tag < RangeRepeats::kTagsPerAnchor; ++tag) EXPECT_NEAR(r.repeats(1, tag), 10.0, 1e-9);
  EXPECT_DOUBLE_EQ(r.repeats(1, RangeRepeats::kTagsPerAnchor), 1.0) << "a fifth antenna is not followed";
  r.reset();
  EXPECT_DOUBLE_EQ(r.repeats(1, 0), 1.0);
}

TEST(RangeRepeats, ParamsAreChecked) {
  EXPECT_NO_THROW(RangeRepeatsParams{0.0}.validate());
  EXPECT_NO_THROW(RangeRepeatsParams{60.0}.validate());
  for (double bad : {-0.1, 60.5, std::numeric_limits<double>::quiet_NaN()}) {
    try {
      RangeRepeatsParams{bad}.validate();
      ADD_FAILURE() << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("error_correlation_s"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(RangeRepeats(2, RangeRepeatsParams{-1.0}), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
