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
  EXPECT_EQ(screen.check(u), SampleVerdict::kAccept);
  EXPECT_EQ(screen.check(u), SampleVerdict::kDuplicate);
}

}  // namespace
}  // namespace rilo
