// The physical screen in front of the estimator (issue 37): each reason a
// row is dropped, the IMU time-jump confirmation, and that what passes is
// untouched.
#include "estimation/measurements/input_screen.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kS = 1'000'000'000;

ImuSample imu(std::int64_t t_ns, double ax = 0.0, double wz = 0.0) {
  ImuSample s;
  s.t_ns = t_ns;
  s.accel_m_s2 = Eigen::Vector3d(ax, 0.0, 9.81);
  s.gyro_rad_s = Eigen::Vector3d(0.0, 0.0, wz);
  return s;
}

RangeSample range(std::int64_t t_ns, double m) {
  RangeSample s;
  s.t_ns = t_ns;
  s.range_m = m;
  return s;
}

TEST(InputScreen, ImpossibleRangesAreDroppedByReason) {
  InputScreen screen;
  ASSERT_TRUE(screen.admit(imu(0)));
  EXPECT_TRUE(screen.admit(range(1 * kMs, 3.0)));
  EXPECT_FALSE(screen.admit(range(2 * kMs, -5.0)));
  EXPECT_FALSE(screen.admit(range(3 * kMs, 0.0)));
  EXPECT_FALSE(screen.admit(range(4 * kMs, 1e9)));
  EXPECT_FALSE(screen.admit(range(5 * kMs, std::numeric_limits<double>::quiet_NaN())));
  EXPECT_TRUE(screen.admit(range(6 * kMs, 300.0)));  // the bound itself passes
  EXPECT_EQ(screen.dropped()[InputDrop::kOutOfBounds], 3u);
  EXPECT_EQ(screen.dropped()[InputDrop::kNotFinite], 1u);
  EXPECT_EQ(screen.dropped().total(), 4u);

  TdoaSample t;
  t.t_ns = 7 * kMs;
  t.diff_m = -301.0;
  EXPECT_FALSE(screen.admit(t));
  t.diff_m = -2.0;  // a TDoA difference may be negative
  EXPECT_TRUE(screen.admit(t));
  UltrasonicSample u;
  u.t_ns = 7 * kMs;
  u.range_m = -0.1;
  EXPECT_FALSE(screen.admit(u));
  EXPECT_EQ(screen.dropped()[InputDrop::kOutOfBounds], 5u);
}

TEST(InputScreen, ImuBeyondFullScaleOrNotFiniteIsDropped) {
  InputScreenParams p;
  p.max_accel_m_s2 = 80.0;
  p.max_gyro_rad_s = 35.0;
  InputScreen screen(p);
  EXPECT_TRUE(screen.admit(imu(1 * kMs, 79.0, -34.0)));
  EXPECT_FALSE(screen.admit(imu(2 * kMs, 1e30)));
  EXPECT_FALSE(screen.admit(imu(3 * kMs, 0.0, -36.0)));
  EXPECT_FALSE(screen.admit(imu(4 * kMs, std::numeric_limits<double>::infinity())));
  EXPECT_TRUE(screen.admit(imu(5 * kMs)));
  EXPECT_EQ(screen.dropped()[InputDrop::kBeyondFullScale], 2u);
  EXPECT_EQ(screen.dropped()[InputDrop::kNotFinite], 1u);
}

TEST(InputScreen, StampsBehindTheirStreamAreNonMonotonic) {
  InputScreen screen;
  ASSERT_TRUE(screen.admit(imu(10 * kMs)));
  EXPECT_FALSE(screen.admit(imu(10 * kMs)));  // a repeated IMU stamp
  EXPECT_FALSE(screen.admit(imu(9 * kMs)));
  EXPECT_TRUE(screen.admit(range(10 * kMs, 2.0)));
  EXPECT_TRUE(screen.admit(range(10 * kMs, 2.5)));  // another anchor at the same time
  EXPECT_FALSE(screen.admit(range(8 * kMs, 2.0)));
  EXPECT_EQ(screen.dropped()[InputDrop::kNonMonotonic], 3u);
}

TEST(InputScreen, AMeasurementFarAheadOfTheImuIsDropped) {
  // The row that planned a state every 0.5 s for 28 years.
  InputScreen screen;
  ASSERT_TRUE(screen.admit(imu(1 * kS)));
  EXPECT_FALSE(screen.admit(range(900'000'000'000'000'000, 3.0)));
  EXPECT_TRUE(screen.admit(range(1 * kS + 4 * kS, 3.0)));  // within max_time_jump_s (5 s) of the IMU
  EXPECT_TRUE(screen.admit(range(1 * kS + 5 * kS, 3.0)));  // at the bound
  EXPECT_FALSE(screen.admit(range(1 * kS + 5 * kS + 1, 3.0)));
  EXPECT_EQ(screen.dropped()[InputDrop::kFarFuture], 2u);
  // Before any IMU, a range is judged against its own stream.
  InputScreen no_imu;
  EXPECT_TRUE(no_imu.admit(range(1 * kS, 3.0)));
  EXPECT_FALSE(no_imu.admit(range(100 * kS, 3.0)));
  EXPECT_TRUE(no_imu.admit(range(2 * kS, 3.0)));
}

TEST(InputScreen, ALoneImuStampFarAheadIsDroppedAndTheStreamGoesOn) {
  InputScreen screen;
  std::int64_t t = 0;
  for (int i = 0; i < 10; ++i) ASSERT_TRUE(screen.admit(imu(t += 5 * kMs)));
  EXPECT_FALSE(screen.admit(imu(t + 3600 * kS)));  // one bad stamp, an hour ahead
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(screen.admit(imu(t += 5 * kMs)));
  EXPECT_EQ(screen.dropped()[InputDrop::kFarFuture], 1u);
  EXPECT_EQ(screen.dropped().time_jumps, 0u);
}

TEST(InputScreen, AShortBadImuStepIsHeldToo) {
  // 3 s ahead: past the localizer's 1 s IMU gap (which would end tracking)
  // but within max_time_jump_s. Held like any jump; the stream goes on.
  InputScreen screen;
  std::int64_t t = 0;
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(screen.admit(imu(t += 5 * kMs)));
  EXPECT_FALSE(screen.admit(imu(t + 3 * kS)));
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(screen.admit(imu(t += 5 * kMs)));
  EXPECT_EQ(screen.dropped()[InputDrop::kFarFuture], 1u);
  EXPECT_EQ(screen.dropped().time_jumps, 0u);
}

TEST(InputScreen, BeforeAnyImuAMeasurementJumpIsConfirmedByItsOwnStream) {
  InputScreen screen;
  ASSERT_TRUE(screen.admit(range(1 * kS, 3.0)));
  for (int i = 1; i <= 3; ++i) EXPECT_FALSE(screen.admit(range(100 * kS + i * kMs, 3.0))) << i;
  EXPECT_TRUE(screen.admit(range(100 * kS + 4 * kMs, 3.0)));  // the fourth continues it: taken
  EXPECT_TRUE(screen.admit(range(100 * kS + 5 * kMs, 3.0)));
  EXPECT_EQ(screen.dropped()[InputDrop::kFarFuture], 3u);
}

TEST(InputScreen, AnImuJumpConfirmedBySamplesThatContinueItIsTaken) {
  // A paused device: the clock moved on and every sample after it agrees.
  InputScreenParams p;
  p.jump_confirmations = 3;
  InputScreen screen(p);
  std::int64_t t = 0;
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(screen.admit(imu(t += 5 * kMs)));
  t += 3600 * kS;
  for (int i = 0; i < 3; ++i) EXPECT_FALSE(screen.admit(imu(t += 5 * kMs))) << i;  // awaiting confirmation
  EXPECT_TRUE(screen.admit(imu(t += 5 * kMs)));                                   // the fourth on the new timeline
  EXPECT_TRUE(screen.admit(imu(t += 5 * kMs)));
  EXPECT_EQ(screen.dropped().time_jumps, 1u);
  EXPECT_EQ(screen.dropped()[InputDrop::kFarFuture], 3u);
  EXPECT_TRUE(screen.admit(range(t, 4.0)));  // ranges on the new timeline pass
}

TEST(InputScreen, AJumpThatDoesNotContinueRestartsItsConfirmation) {
  InputScreenParams p;
  p.jump_confirmations = 2;
  InputScreen screen(p);
  ASSERT_TRUE(screen.admit(imu(1 * kS)));
  EXPECT_FALSE(screen.admit(imu(100 * kS)));
  EXPECT_FALSE(screen.admit(imu(500 * kS)));  // far from the first candidate: a new candidate
  EXPECT_FALSE(screen.admit(imu(500 * kS + kMs)));
  EXPECT_TRUE(screen.admit(imu(500 * kS + 2 * kMs)));  // two confirmations of the 500 s timeline
  EXPECT_EQ(screen.dropped().time_jumps, 1u);
  EXPECT_EQ(screen.dropped()[InputDrop::kFarFuture], 3u);
}

TEST(InputScreen, ParametersAreCheckedByName) {
  auto refused = [](auto change) -> std::string {
    InputScreenParams p;
    change(p);
    try {
      InputScreen screen(p);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(refused([](InputScreenParams& p) { p.max_range_m = 0.0; }).find("max_range_m"), std::string::npos);
  EXPECT_NE(refused([](InputScreenParams& p) { p.max_accel_m_s2 = -1.0; }).find("max_accel_m_s2"), std::string::npos);
  EXPECT_NE(refused([](InputScreenParams& p) { p.max_gyro_rad_s = std::nan(""); }).find("max_gyro_rad_s"), std::string::npos);
  EXPECT_NE(refused([](InputScreenParams& p) { p.max_time_jump_s = 0.0; }).find("max_time_jump_s"), std::string::npos);
  EXPECT_NE(refused([](InputScreenParams& p) { p.jump_confirmations = -1; }).find("jump_confirmations"), std::string::npos);
  EXPECT_NE(refused([](InputScreenParams& p) { p.max_imu_jump_s = -1.0; }).find("max_imu_jump_s"), std::string::npos);
  EXPECT_EQ(refused([](InputScreenParams& p) { p.jump_confirmations = 0; }), "");  // rilod's Localizer, behind its entrance
  EXPECT_EQ(inputDropName(InputDrop::kFarFuture), "far_future");
}

}  // namespace
}  // namespace rilo
