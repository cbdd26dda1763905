// RangeConsistencyMonitor: ranges much shorter than the estimate predicts
// flag an inconsistent estimate; long (NLOS) ranges never do.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "estimation/measurements/range_consistency.h"

namespace rilo {
namespace {

const std::vector<Vec3> kAnchors = {Vec3(0, 0, 2), Vec3(10, 0, 2), Vec3(0, 10, 2), Vec3(10, 10, 2)};

RangeSample rangeTo(std::uint32_t id, std::int64_t t_ns, const Vec3& p_w_tag, double error_m) {
  RangeSample r;
  r.t_ns = t_ns;
  r.anchor_id = id;
  r.range_m = (p_w_tag - kAnchors[id]).norm() + error_m;
  return r;
}

Pose3 at(const Vec3& p) {
  Pose3 T;
  T.p = p;
  return T;
}

RangeConsistencyParams smallWindow() {
  RangeConsistencyParams p;
  p.window = 10;
  p.min_judged = 8;
  p.max_short_share = 0.3;
  p.short_sigmas = 5.0;
  p.short_floor_m = 0.5;
  return p;
}

TEST(RangeConsistency, ResidualUsesTheLeverArmAndSign) {
  const Vec3 lever(0.0, 0.0, 0.1);
  RangeConsistencyMonitor m(kAnchors, lever, 0.1, 5'000'000, smallWindow());
  const Vec3 p_tag(5, 5, 1.1);
  const RangeSample r = rangeTo(1, 0, p_tag, -0.3);
  EXPECT_NEAR(m.residual(r, at(Vec3(5, 5, 1.0))), -0.3, 1e-12);  // body at 1.0 m, antenna 0.1 m above
}

// Ranges later than their state (its 50 ms window) are judged where the
// state's velocity takes the tag by their time, as their factors predict
// them. A fast mover (10 m/s, towards anchor 0) makes the difference plain:
// 40 ms later the tag is 0.4 m nearer, which the state's own pose would call
// 0.4 m short (0.5 m floor: use a lower floor here).
TEST(RangeConsistency, ALaterRangeOfTheStateIsJudgedWhereTheVelocityTakesTheTag) {
  RangeConsistencyParams params = smallWindow();
  params.short_floor_m = 0.2;
  params.short_sigmas = 2.0;
  RangeConsistencyMonitor with_velocity(kAnchors, Vec3::Zero(), 0.1, 50'000'000, params);
  RangeConsistencyMonitor without(kAnchors, Vec3::Zero(), 0.1, 50'000'000, params);
  const Vec3 v(-7.07, -7.07, 0.0);  // 10 m/s towards anchor 0 at (0, 0, 2)
  for (int k = 0; k < 10; ++k) {
    const std::int64_t t = k * 100'000'000;
    const Vec3 p(5.0 + 0.1 * k, 5.0, 1.0);
    const RangeSample r = rangeTo(0, t + 40'000'000, p + 0.04 * v, 0.0);
    with_velocity.onRange(r);
    without.onRange(r);
    EXPECT_TRUE(with_velocity.judge(t, at(p), v)) << k;
    without.judge(t, at(p));
  }
  EXPECT_EQ(with_velocity.shortShare(), 0.0);
  EXPECT_EQ(without.shortShare(), 1.0);
}

TEST(RangeConsistency, NlosLongRangesNeverFlagButShortOnesDo) {
  RangeConsistencyMonitor m(kAnchors, Vec3::Zero(), 0.1, 5'000'000, smallWindow());
  const Vec3 p(5, 5, 1);
  std::int64_t t = 0;
  // Heavy NLOS: every range 3 m too long. Consistent (the tail's business).
  for (int k = 0; k < 20; ++k, t += 25'000'000) {
    m.onRange(rangeTo(static_cast<std::uint32_t>(k % 4), t, p, 3.0));
    EXPECT_TRUE(m.judge(t, at(p))) << k;
  }
  EXPECT_EQ(m.shortShare(), 0.0);
  EXPECT_EQ(m.judgedInWindow(), 10);
  // The estimate is 4 m off: ranges to anchors on the far side are short.
  const Pose3 wrong = at(p + Vec3(4, 0, 0));
  int first_failure = -1;
  for (int k = 0; k < 20 && first_failure < 0; ++k, t += 25'000'000) {
    m.onRange(rangeTo(static_cast<std::uint32_t>(k % 4), t, p, 0.0));
    if (!m.judge(t, wrong)) first_failure = k;
  }
  ASSERT_GE(first_failure, 0) << "never flagged";
  EXPECT_GT(m.shortShare(), 0.3);
  // Half the anchors are short at this geometry: the share crosses 0.3 after
  // 4 of the 10 slots hold short ranges, i.e. within 8 ranges.
  EXPECT_LE(first_failure, 8);
  // Reset: a new start judges afresh.
  m.reset();
  EXPECT_EQ(m.judgedInWindow(), 0);
  EXPECT_EQ(m.shortShare(), 0.0);
}

TEST(RangeConsistency, NoVerdictBeforeMinJudgedAndOnlyTheNewestStatesRanges) {
  RangeConsistencyMonitor m(kAnchors, Vec3::Zero(), 0.1, 5'000'000, smallWindow());
  const Vec3 p(5, 5, 1);
  const Pose3 far = at(Vec3(-20, -20, 1));  // every range short
  for (int k = 0; k < 7; ++k) {
    m.onRange(rangeTo(static_cast<std::uint32_t>(k % 4), k * 25'000'000, p, 0.0));
    EXPECT_TRUE(m.judge(k * 25'000'000, far)) << "only " << k + 1 << " judged";
  }
  EXPECT_EQ(m.shortShare(), 1.0);
  // A range of a later state waits for that state's update.
  m.onRange(rangeTo(0, 1'000'000'000, p, 0.0));
  EXPECT_TRUE(m.judge(200'000'000, far));
  EXPECT_EQ(m.judgedInWindow(), 7);
  // Ranges older than max_age at the update are dropped unjudged.
  RangeConsistencyParams params = smallWindow();
  params.max_age_ns = 50'000'000;
  RangeConsistencyMonitor old(kAnchors, Vec3::Zero(), 0.1, 5'000'000, params);
  old.onRange(rangeTo(0, 0, p, 0.0));
  old.onRange(rangeTo(1, 100'000'000, p, 0.0));
  old.judge(100'000'000, at(p));
  EXPECT_EQ(old.judgedInWindow(), 1);
  // Unknown anchors are ignored.
  RangeSample unknown = rangeTo(0, 200'000'000, p, 0.0);
  unknown.anchor_id = 7;
  old.onRange(unknown);
  old.judge(200'000'000, at(p));
  EXPECT_EQ(old.judgedInWindow(), 1);
}

// The judged ranges feed the LOS-gap calibration: once ranges with gaps of
// 4 dB and more come out long at the tracked pose while those up to 3.5 dB
// do not, the threshold drops to 3.5 dB (bins are (lo, hi], the flag is
// gap > threshold), so the 4 dB ranges are flagged too (their residuals go
// to the flagged quantile); reset() restores 6 dB.
TEST(RangeConsistency, JudgedRangesCalibrateTheFlagThreshold) {
  RangeConsistencyMonitor m(kAnchors, Vec3::Zero(), 0.15, 5'000'000, RangeConsistencyParams(), 6.0);
  EXPECT_EQ(m.flagGapDb(), 6.0);
  const Vec3 p(5, 5, 1);
  std::int64_t t = 0;
  for (int k = 0; k < 2000; ++k, t += 25'000'000) {
    const double gap_db = 1.0 + 0.5 * (k % 12);  // 1.0 .. 6.5 dB
    RangeSample r = rangeTo(static_cast<std::uint32_t>(k % 4), t, p, gap_db >= 4.0 ? 0.3 : 0.0);
    r.rssi_dbm = -80.0;
    r.fp_power_dbm = -80.0 - gap_db;
    m.onRange(r);
    EXPECT_TRUE(m.judge(t, at(p)));
  }
  EXPECT_EQ(m.flagGapDb(), 3.5);
  // The flagged ring holds only the 0.3 m residuals of the ranges at 4 dB and above.
  EXPECT_NEAR(m.flaggedQuantile(0.0, 50), 0.3, 1e-9);
  // ... and each flagged bin below the configured 6 dB knows its own excess.
  EXPECT_NEAR(m.losGap().excessTable().at(4.0), 0.3, 1e-9);
  EXPECT_NEAR(m.losGap().excessTable().at(5.5), 0.3, 1e-9);
  EXPECT_NEAR(m.losGap().excessTable().at(3.5), 0.0, 1e-9);
  m.reset();
  EXPECT_EQ(m.flagGapDb(), 6.0);
  EXPECT_TRUE(std::isnan(m.losGap().excessTable().at(4.0)));
}

// Every judged range tells the NLOS memory its residual; a range the memory
// flagged (no first-path power) does not teach the gap calibration, which
// would otherwise learn from ranges that pulled weakly and flag more.
TEST(RangeConsistency, JudgedRangesFeedTheNlosMemoryAndItsFlagsNotTheCalibration) {
  NlosMemoryParams memory;
  memory.window_s = 0.5;
  RangeConsistencyMonitor m(kAnchors, Vec3::Zero(), 0.1, 5'000'000, RangeConsistencyParams(), 6.0, LosGapParams(), {},
                            NlosMemory(kAnchors.size(), 0.21, memory));
  const Vec3 p(5, 5, 1);
  std::int64_t t = 0;
  for (int k = 0; k < 2; ++k, t += 25'000'000) {
    m.onRange(rangeTo(2, t, p, 0.5));  // anchor 2 blocked
    m.onRange(rangeTo(1, t, p, 0.0));
    EXPECT_TRUE(m.judge(t, at(p)));
  }
  EXPECT_TRUE(m.nlosMemory().remembersNlos(2, 0, t));
  EXPECT_FALSE(m.nlosMemory().remembersNlos(1, 0, t));
  // 2000 ranges at a LOS gap with a 0.3 m residual: from the receiver they
  // teach the calibration that excess begins there; flagged by the memory
  // they teach nothing.
  RangeConsistencyMonitor taught(kAnchors, Vec3::Zero(), 0.15, 5'000'000, RangeConsistencyParams(), 6.0);
  RangeConsistencyMonitor untaught(kAnchors, Vec3::Zero(), 0.15, 5'000'000, RangeConsistencyParams(), 6.0);
  for (int k = 0; k < 2000; ++k, t += 25'000'000) {
    const double gap_db = 1.0 + 0.5 * (k % 12);  // 1.0 .. 6.5 dB
    RangeSample r = rangeTo(static_cast<std::uint32_t>(k % 4), t, p, gap_db >= 4.0 ? 0.3 : 0.0);
    r.rssi_dbm = -80.0;
    r.fp_power_dbm = -80.0 - gap_db;
    taught.onRange(r);
    r.nlos_from_memory = gap_db >= 4.0;
    untaught.onRange(r);
    EXPECT_TRUE(taught.judge(t, at(p)));
    EXPECT_TRUE(untaught.judge(t, at(p)));
  }
  EXPECT_EQ(taught.flagGapDb(), 3.5);
  EXPECT_EQ(untaught.flagGapDb(), 6.0);
  EXPECT_TRUE(std::isnan(untaught.losGap().excessTable().at(4.0)));
}

TEST(RangeConsistency, GapsFromTheRxLevelRaiseTheThresholdAndTheReceiversDoNot) {
  // LOS up to 7.5 dB, a 0.3 m excess above: stood in from the RX level, the
  // threshold follows the ranges past the configured 6 dB; the receiver's own
  // gaps stay bounded by it (los_gap_calibration.h).
  RangeConsistencyMonitor rx(kAnchors, Vec3::Zero(), 0.15, 5'000'000, RangeConsistencyParams(), 6.0);
  RangeConsistencyMonitor receiver(kAnchors, Vec3::Zero(), 0.15, 5'000'000, RangeConsistencyParams(), 6.0);
  const Vec3 p(5, 5, 1);
  std::int64_t t = 0;
  for (int k = 0; k < 4000; ++k, t += 25'000'000) {
    const double gap_db = 1.25 + 0.5 * (k % 18);  // 1.25 .. 9.75 dB, mid-bin
    RangeSample r = rangeTo(static_cast<std::uint32_t>(k % 4), t, p, gap_db > 7.5 ? 0.3 : 0.0);
    r.rssi_dbm = -80.0;
    r.fp_power_dbm = -80.0 - gap_db;
    receiver.onRange(r);
    r.fp_from_rx_level = true;
    rx.onRange(r);
    EXPECT_TRUE(receiver.judge(t, at(p)));
    EXPECT_TRUE(rx.judge(t, at(p)));
  }
  EXPECT_EQ(rx.flagGapDb(), 7.5);
  EXPECT_EQ(receiver.flagGapDb(), 6.0);
}

TEST(RangeConsistency, DisabledNeverFlags) {
  RangeConsistencyParams params = smallWindow();
  params.enabled = false;
  RangeConsistencyMonitor m(kAnchors, Vec3::Zero(), 0.1, 5'000'000, params);
  for (int k = 0; k < 20; ++k) {
    m.onRange(rangeTo(static_cast<std::uint32_t>(k % 4), k, Vec3(5, 5, 1), 0.0));
    EXPECT_TRUE(m.judge(k, at(Vec3(-20, -20, 1))));
  }
  EXPECT_EQ(m.judgedInWindow(), 0);
}

TEST(RangeConsistency, BadParamsNameTheField) {
  auto message = [](RangeConsistencyParams p) {
    try {
      p.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  RangeConsistencyParams p;
  p.window = 0;
  EXPECT_NE(message(p).find("window"), std::string::npos);
  p = {};
  p.min_judged = p.window + 1;
  EXPECT_NE(message(p).find("min_judged"), std::string::npos);
  p = {};
  p.max_short_share = 0.0;
  EXPECT_NE(message(p).find("max_short_share"), std::string::npos);
  p = {};
  p.short_floor_m = -1.0;
  EXPECT_NE(message(p).find("short_floor_m"), std::string::npos);
  EXPECT_EQ(message(RangeConsistencyParams{}), "");
}

TEST(FlaggedExcess, LowQuantileOfTheFlaggedRangesResidualsOnly) {
  // Flagged ranges (power gap 9 dB > 6) carry excesses 0.00, 0.01, ..., 0.99 m;
  // unflagged ones (2 dB) are 3 m long and must not count.
  RangeConsistencyMonitor m(kAnchors, Vec3::Zero(), 0.1, 5'000'000, smallWindow(), 6.0);
  const Vec3 p(5, 5, 1);
  EXPECT_TRUE(std::isnan(m.flaggedQuantile(0.35, 1))) << "nothing judged yet";
  for (int k = 0; k < 100; ++k) {
    const std::int64_t t = 1'000'000'000LL + k * 25'000'000LL;
    RangeSample flagged = rangeTo(static_cast<std::uint32_t>(k % 4), t, p, 0.01 * k);
    flagged.rssi_dbm = -80.0;
    flagged.fp_power_dbm = -89.0;
    RangeSample clear = rangeTo(static_cast<std::uint32_t>((k + 1) % 4), t, p, 3.0);
    clear.rssi_dbm = -80.0;
    clear.fp_power_dbm = -82.0;
    RangeSample unknown = rangeTo(static_cast<std::uint32_t>((k + 2) % 4), t, p, 3.0);  // no powers: NaN gap
    m.onRange(flagged);
    m.onRange(clear);
    m.onRange(unknown);
    m.judge(t, at(p));
  }
  EXPECT_NEAR(m.flaggedQuantile(0.35, 50), 0.34, 1e-9);  // element floor(0.35 * 99) = 34 of the sorted 0.00..0.99
  EXPECT_NEAR(m.flaggedQuantile(0.0, 50), 0.0, 1e-9);
  EXPECT_NEAR(m.flaggedQuantile(1.0, 50), 0.99, 1e-9);
  EXPECT_TRUE(std::isnan(m.flaggedQuantile(0.35, 101))) << "too few for the minimum";
  // A window of the last 200 flagged ranges.
  for (int k = 0; k < 300; ++k) {
    const std::int64_t t = 5'000'000'000LL + k * 25'000'000LL;
    RangeSample flagged = rangeTo(0, t, p, 0.5);
    flagged.rssi_dbm = -80.0;
    flagged.fp_power_dbm = -90.0;
    m.onRange(flagged);
    m.judge(t, at(p));
  }
  EXPECT_NEAR(m.flaggedQuantile(0.0, 50), 0.5, 1e-9);
  m.reset();
  EXPECT_TRUE(std::isnan(m.flaggedQuantile(0.35, 1))) << "reset forgets";
  // Without a flag threshold nothing is collected.
  RangeConsistencyMonitor none(kAnchors, Vec3::Zero(), 0.1, 5'000'000, smallWindow());
  RangeSample flagged = rangeTo(0, 1, p, 0.5);
  flagged.rssi_dbm = -80.0;
  flagged.fp_power_dbm = -99.0;
  none.onRange(flagged);
  none.judge(1, at(p));
  EXPECT_TRUE(std::isnan(none.flaggedQuantile(0.0, 1)));
}

TEST(FlaggedExcess, BadParamsNameTheField) {
  FlaggedExcessParams p;
  p.quantile = 1.5;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p = FlaggedExcessParams();
  p.min_ranges = 0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p = FlaggedExcessParams();
  p.max_m = -1.0;
  try {
    p.validate();
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_m"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rilo
