// SampleScreen: the service's entrance check drops exactly the samples the
// estimator's input contract rejects, per stream, and keeps everything else.
#include "rilod/sample_screen.h"

#include <gtest/gtest.h>

#include <limits>

namespace rilo {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

Sample imu(std::int64_t t_ns) {
  ImuSample s;
  s.t_ns = t_ns;
  s.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.81);
  return s;
}

Sample range(std::int64_t t_ns, std::uint32_t anchor, double range_m = 3.0, std::uint32_t tag = 0) {
  RangeSample s;
  s.t_ns = t_ns;
  s.anchor_id = anchor;
  s.tag_id = tag;
  s.range_m = range_m;
  return s;  // rssi and first-path power stay NaN ("unknown"): not a fault
}

TEST(SampleScreen, AcceptsIncreasingTimesPerStream) {
  SampleScreen screen;
  EXPECT_EQ(screen.check(imu(10)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(range(5, 1)), SampleVerdict::kAccept);  // older than the IMU: another stream
  EXPECT_EQ(screen.check(imu(11)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(range(12, 2)), SampleVerdict::kAccept);
}

TEST(SampleScreen, NonFiniteValuesAreDroppedButUnknownSignalPowerIsNot) {
  SampleScreen screen;
  ImuSample bad_gyro = std::get<ImuSample>(imu(1));
  bad_gyro.gyro_rad_s.y() = kNan;
  EXPECT_EQ(screen.check(bad_gyro), SampleVerdict::kNonFinite);
  ImuSample bad_accel = std::get<ImuSample>(imu(1));
  bad_accel.accel_m_s2.z() = kInf;
  EXPECT_EQ(screen.check(bad_accel), SampleVerdict::kNonFinite);
  EXPECT_EQ(screen.check(imu(1)), SampleVerdict::kAccept);  // the dropped ones did not count as "previous"
  EXPECT_EQ(screen.check(range(1, 0, kNan)), SampleVerdict::kNonFinite);
  EXPECT_EQ(screen.check(range(1, 0, -kInf)), SampleVerdict::kNonFinite);
  EXPECT_EQ(screen.check(range(1, 0)), SampleVerdict::kAccept);
  TdoaSample tdoa;
  tdoa.diff_m = kNan;
  EXPECT_EQ(screen.check(tdoa), SampleVerdict::kNonFinite);
  UltrasonicSample us;
  us.range_m = kInf;
  EXPECT_EQ(screen.check(us), SampleVerdict::kNonFinite);
}

TEST(SampleScreen, ImuAtTheSameTimeIsADuplicateAndOlderIsOutOfOrder) {
  SampleScreen screen;
  EXPECT_EQ(screen.check(imu(100)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(imu(100)), SampleVerdict::kDuplicate);
  EXPECT_EQ(screen.check(imu(99)), SampleVerdict::kOutOfOrder);
  EXPECT_EQ(screen.check(imu(101)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(imu(100)), SampleVerdict::kOutOfOrder);  // against the last accepted one
}

TEST(SampleScreen, RangesMayShareATimeWithDifferentAnchorsOrTags) {
  SampleScreen screen;
  EXPECT_EQ(screen.check(range(100, 1)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(range(100, 2)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(range(100, 2, 3.0, 1)), SampleVerdict::kAccept);  // other antenna
  EXPECT_EQ(screen.check(range(100, 2, 3.0, 1)), SampleVerdict::kDuplicate);
  EXPECT_EQ(screen.check(range(99, 3)), SampleVerdict::kOutOfOrder);
  EXPECT_EQ(screen.check(range(101, 2)), SampleVerdict::kAccept);
}

TEST(SampleScreen, TdoaAndUltrasonicHaveTheirOwnOrder) {
  SampleScreen screen;
  TdoaSample t;
  t.t_ns = 50;
  t.anchor_a = 0;
  t.anchor_b = 1;
  EXPECT_EQ(screen.check(t), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(t), SampleVerdict::kDuplicate);
  t.anchor_b = 2;
  EXPECT_EQ(screen.check(t), SampleVerdict::kAccept);
  t.t_ns = 40;
  EXPECT_EQ(screen.check(t), SampleVerdict::kOutOfOrder);
  UltrasonicSample u;
  u.t_ns = 10;  // older than the TDoA: another stream
  u.anchor_id = 4;
  u.range_m = 2.0;  // a distance (0 m is out of the screen's bounds)
  EXPECT_EQ(screen.check(u), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(u), SampleVerdict::kDuplicate);
}

TEST(SampleScreen, ImpossibleValuesStopAtTheEntranceBeforeTheOdometry) {
  // Issue 37: the estimator's screen alone let a 1e30 m/s^2 sample reach the
  // odometry publisher. The entrance applies the same bounds.
  SampleScreen screen;
  Sample huge = imu(10);
  std::get<ImuSample>(huge).accel_m_s2.x() = 1e30;
  EXPECT_EQ(screen.check(huge), SampleVerdict::kBeyondFullScale);
  EXPECT_EQ(screen.check(imu(10)), SampleVerdict::kAccept);  // the screened one was not remembered
  EXPECT_EQ(screen.check(range(11, 1, -5.0)), SampleVerdict::kOutOfBounds);
  EXPECT_EQ(screen.check(range(11, 1, 1e9)), SampleVerdict::kOutOfBounds);
  EXPECT_EQ(screen.check(range(11, 1, 0.0)), SampleVerdict::kOutOfBounds);
  EXPECT_EQ(screen.check(range(11, 1, 3.0)), SampleVerdict::kAccept);
  InputScreenParams narrow;
  narrow.max_accel_m_s2 = 40.0;  // e.g. the BMI263 at 4 g
  SampleScreen four_g(narrow);
  Sample hard = imu(10);
  std::get<ImuSample>(hard).accel_m_s2.x() = 45.0;
  EXPECT_EQ(four_g.check(hard), SampleVerdict::kBeyondFullScale);
}

TEST(SampleScreen, ALoneFarFutureStampIsHeldAndTheStreamGoesOn) {
  // It used to become the stream's last stamp: every real sample after it
  // was then "out of order" for as long as the bad stamp was ahead.
  SampleScreen screen;
  const std::int64_t ms = 1'000'000;
  for (std::int64_t t = 1; t <= 5; ++t) ASSERT_EQ(screen.check(imu(t * ms)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(imu(900'000'000'000'000'000)), SampleVerdict::kFarFuture);
  for (std::int64_t t = 6; t <= 10; ++t) EXPECT_EQ(screen.check(imu(t * ms)), SampleVerdict::kAccept) << t;
  EXPECT_EQ(screen.check(range(5 * ms, 1)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(range(900'000'000'000'000'000, 1)), SampleVerdict::kFarFuture);
  EXPECT_EQ(screen.check(range(6 * ms, 2)), SampleVerdict::kAccept);
}

TEST(SampleScreen, AJumpTheNextSamplesConfirmIsTaken) {
  SampleScreen screen;  // three confirmations
  const std::int64_t ms = 1'000'000, later = 3'600'000 * ms;
  ASSERT_EQ(screen.check(imu(1 * ms)), SampleVerdict::kAccept);
  for (int i = 1; i <= 3; ++i) EXPECT_EQ(screen.check(imu(later + i * ms)), SampleVerdict::kFarFuture) << i;
  EXPECT_EQ(screen.check(imu(later + 4 * ms)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(imu(later + 5 * ms)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(imu(2 * ms)), SampleVerdict::kOutOfOrder);  // the old timeline is behind now
}

TEST(SampleScreen, ARangingBlackoutIsNotAJumpWhileTheImuLeads) {
  // Ranges 30 s after the previous one, with the IMU running all along: the
  // first is taken at once (judged against the newest IMU stamp, not its own
  // stream); one far ahead of the IMU is far-future, whatever its stream says.
  SampleScreen screen;
  const std::int64_t s = 1'000'000'000;
  ASSERT_EQ(screen.check(range(1 * s, 1), 1 * s), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(range(31 * s, 1), 31 * s), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(range(40 * s, 2), 31 * s), SampleVerdict::kFarFuture);
  EXPECT_EQ(screen.check(range(32 * s, 2), 32 * s), SampleVerdict::kAccept);
}

TEST(SampleScreen, StampsNudgedPastABadOneDoNotConfirmIt) {
  // A driver forcing increasing times wrote last + 1 ns after one bad stamp
  // (the review of the first version): those are not samples continuing a
  // new timeline, and the jump stays held.
  SampleScreen screen;
  const std::int64_t ms = 1'000'000, bad = 300'000 * ms;
  ASSERT_EQ(screen.check(imu(1 * ms)), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(imu(bad)), SampleVerdict::kFarFuture);
  for (int k = 1; k <= 5; ++k) EXPECT_EQ(screen.check(imu(bad + k)), SampleVerdict::kFarFuture) << k;
  EXPECT_EQ(screen.check(imu(2 * ms)), SampleVerdict::kAccept);  // real time again
}

}  // namespace
}  // namespace rilo
