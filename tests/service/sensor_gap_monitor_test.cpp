// SensorGapMonitor: IMU gaps and ranging pauses in sample time, counted once each.
#include "rilod/sensor_gap_monitor.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace rilo {
namespace {

constexpr std::int64_t kMs = 1'000'000;

TEST(SensorGapMonitor, ImuIntervalsLongerThanTheTimeoutAreGaps) {
  SensorGapMonitor m(100 * kMs, 2000 * kMs);
  EXPECT_EQ(m.onImu(0), SensorGapMonitor::kNone);
  EXPECT_EQ(m.onImu(1 * kMs), SensorGapMonitor::kNone);
  EXPECT_EQ(m.onImu(101 * kMs), SensorGapMonitor::kNone);  // exactly the timeout: not yet
  EXPECT_EQ(m.onImu(402 * kMs), SensorGapMonitor::kImuGap);
  EXPECT_EQ(m.lastImuGapNs(), 301 * kMs);
  EXPECT_EQ(m.onImu(403 * kMs), SensorGapMonitor::kNone);
}

TEST(SensorGapMonitor, RangingPauseStartsOnceAndEndsWithTheNextRange) {
  SensorGapMonitor m(100 * kMs, 2000 * kMs);
  EXPECT_FALSE(m.rangingSilent());
  // No range yet: no pause however long the IMU runs (initialization reports that).
  for (std::int64_t t = 0; t <= 3000 * kMs; t += 10 * kMs) EXPECT_EQ(m.onImu(t) & SensorGapMonitor::kRangingGapStarted, 0u);
  EXPECT_EQ(m.onRange(3000 * kMs), 0);
  int started = 0;
  for (std::int64_t t = 3010 * kMs; t <= 8000 * kMs; t += 10 * kMs) {
    if ((m.onImu(t) & SensorGapMonitor::kRangingGapStarted) != 0) {
      ++started;
      EXPECT_EQ(t, 5010 * kMs);  // first IMU sample more than 2 s after the range
    }
  }
  EXPECT_EQ(started, 1);
  EXPECT_TRUE(m.rangingSilent());
  EXPECT_EQ(m.sinceLastRangeNs(), 5000 * kMs);
  EXPECT_EQ(m.onRange(8005 * kMs), 5005 * kMs);
  EXPECT_FALSE(m.rangingSilent());
  EXPECT_EQ(m.onRange(8030 * kMs), 0);  // no pause open
  // A second pause is counted again.
  EXPECT_EQ(m.onImu(10100 * kMs), SensorGapMonitor::kImuGap | SensorGapMonitor::kRangingGapStarted);
}

TEST(SensorGapMonitor, RejectsNonPositiveTimeouts) {
  EXPECT_THROW(SensorGapMonitor(0, 1), std::invalid_argument);
  EXPECT_THROW(SensorGapMonitor(1, -1), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
