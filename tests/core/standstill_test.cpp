// StandstillDetector: a still, a turning and a walking body-worn IMU, the
// window's coverage, what dropBefore keeps, and malformed parameters.
#include "estimation/measurements/standstill.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include "support/new_counter.h"

namespace rilo {
namespace {

constexpr std::int64_t kDtNs = 1'250'000;  // 800 Hz
constexpr std::int64_t kS = 1'000'000'000;

/// 800 Hz samples from t0 to t1 (ns), accel/gyro given per time (s).
void feed(StandstillDetector& d, std::int64_t t0_ns, std::int64_t t1_ns, const std::function<Vec3(double)>& accel,
          const std::function<Vec3(double)>& gyro) {
  for (std::int64_t t = t0_ns; t <= t1_ns; t += kDtNs) {
    ImuSample s;
    s.t_ns = t;
    s.accel_m_s2 = accel(static_cast<double>(t) * 1e-9);
    s.gyro_rad_s = gyro(static_cast<double>(t) * 1e-9);
    d.add(s);
  }
}

/// A resting accelerometer: gravity, a bias, white noise of the BMI263's
/// density at 800 Hz (~0.045 m/s^2 per sample at 1.6e-3 m/s^2/sqrt(Hz)).
std::function<Vec3(double)> restingAccel(unsigned seed) {
  auto rng = std::make_shared<std::mt19937>(seed);
  return [rng](double) {
    std::normal_distribution<double> n(0.0, 0.045);
    return Vec3(0.02 + n(*rng), -0.03 + n(*rng), 9.81 + n(*rng));
  };
}

Vec3 noTurn(double) { return Vec3(0.001, -0.002, 0.0005); }

TEST(StandstillDetector, StillWhenResting) {
  StandstillDetector d;
  feed(d, 0, 2 * kS, restingAccel(1), noTurn);
  EXPECT_TRUE(d.stillOver(kS, kS + 25'000'000));  // a 40 Hz state interval, widened to 0.5 s
  EXPECT_TRUE(d.stillOver(kS / 2, 2 * kS));       // a long one
}

TEST(StandstillDetector, TurningOnTheSpotIsStillUnlessATurnTestIsSet) {
  // A wearer turning at 1.5 rad/s: the body's origin stays, the gyro does not.
  auto turn = [](double) { return Vec3(0.0, 0.0, 1.5); };
  StandstillDetector d;
  feed(d, 0, kS, restingAccel(2), turn);
  EXPECT_TRUE(d.stillOver(kS - 25'000'000, kS));
  StandstillParams p;
  p.gyro_rad_s = 0.03;  // the initializer's turn test
  StandstillDetector strict(p);
  feed(strict, 0, kS, restingAccel(2), turn);
  EXPECT_FALSE(strict.stillOver(kS - 25'000'000, kS));
  StandstillDetector strict_resting(p);
  feed(strict_resting, 0, kS, restingAccel(3), noTurn);
  EXPECT_TRUE(strict_resting.stillOver(kS - 25'000'000, kS));
}

TEST(StandstillDetector, WalkingIsNotStill) {
  // Gait: about 2 steps a second, a vertical bounce of ~1 m/s^2 and a
  // forward sway of 0.5 m/s^2 on top of the resting noise.
  auto still = restingAccel(4);
  auto walk = [still](double t) {
    return Vec3(still(t) + Vec3(0.5 * std::sin(2.0 * M_PI * 1.0 * t), 0.0, 1.0 * std::sin(2.0 * M_PI * 2.0 * t)));
  };
  StandstillDetector d;
  feed(d, 0, 2 * kS, walk, noTurn);
  EXPECT_FALSE(d.stillOver(kS, kS + 25'000'000));
  // A slow sideways sway of 0.3 m/s^2 amplitude (0.21 std-dev, the least the
  // office sims' walkers show) on one axis is motion too.
  auto sway = [still](double t) { return Vec3(still(t) + Vec3(0.0, 0.3 * std::sin(2.0 * M_PI * 0.7 * t), 0.0)); };
  StandstillDetector s;
  feed(s, 0, 2 * kS, sway, noTurn);
  EXPECT_FALSE(s.stillOver(kS, kS + 25'000'000));
}

TEST(StandstillDetector, AStopAfterWalkingIsStillOnceTheWindowHasPassedIt) {
  auto still = restingAccel(5);
  auto walk_then_stop = [still](double t) {
    return t < 1.0 ? Vec3(still(t) + Vec3(0.0, 0.0, 1.0 * std::sin(2.0 * M_PI * 2.0 * t))) : still(t);
  };
  StandstillDetector d;
  feed(d, 0, 2 * kS, walk_then_stop, noTurn);
  EXPECT_FALSE(d.stillOver(kS + 200'000'000, kS + 225'000'000)) << "the window still holds steps";
  EXPECT_TRUE(d.stillOver(kS + 600'000'000, kS + 625'000'000));
  // An interval that reaches back into the walk is not still, however short its end.
  EXPECT_FALSE(d.stillOver(kS / 2, kS + 625'000'000));
}

TEST(StandstillDetector, AStopNeedsASlowEstimateToo) {
  StandstillDetector d;
  feed(d, 0, kS, restingAccel(11), noTurn);
  EXPECT_TRUE(d.stillFor(kS - 25'000'000, kS, Vec3(0.3, 0.2, 0.0)));  // a stop the estimate drifts through
  EXPECT_FALSE(d.stillFor(kS - 25'000'000, kS, Vec3(0.9, 0.6, 0.0)));  // a glide (lift, cart)
  StandstillParams p;
  p.max_speed_m_s = std::numeric_limits<double>::infinity();
  StandstillDetector imu_only(p);
  feed(imu_only, 0, kS, restingAccel(11), noTurn);
  EXPECT_TRUE(imu_only.stillFor(kS - 25'000'000, kS, Vec3(3.0, 0.0, 0.0)));
}

TEST(StandstillDetector, NeedsSamplesOverTheWindow) {
  StandstillDetector d;
  EXPECT_FALSE(d.stillOver(0, kS)) << "no samples";
  feed(d, 0, 200'000'000, restingAccel(6), noTurn);  // 0.2 s of a 0.5 s window
  EXPECT_FALSE(d.stillOver(175'000'000, 200'000'000));
  // A gap (an IMU outage) in the window: not still either.
  StandstillDetector gap;
  feed(gap, 0, 300'000'000, restingAccel(7), noTurn);
  feed(gap, 900'000'000, kS, restingAccel(8), noTurn);
  EXPECT_FALSE(gap.stillOver(975'000'000, kS));
  // Samples after t_to do not count.
  StandstillDetector later;
  feed(later, 0, kS, restingAccel(9), noTurn);
  auto jolt = [](double) { return Vec3(5.0, 0.0, 9.81); };
  feed(later, kS + kDtNs, kS + 100 * kDtNs, jolt, noTurn);
  EXPECT_TRUE(later.stillOver(kS - 25'000'000, kS));
  EXPECT_FALSE(later.stillOver(kS + 100 * kDtNs - 25'000'000, kS + 100 * kDtNs));
}

TEST(StandstillDetector, DropBeforeKeepsOneWindow) {
  StandstillDetector d;
  feed(d, 0, 3 * kS, restingAccel(10), noTurn);
  const std::size_t all = d.size();
  d.dropBefore(2 * kS);
  EXPECT_LT(d.size(), all);
  EXPECT_NEAR(static_cast<double>(d.size()), 1.5 * 800.0, 2.0);  // [1.5 s, 3 s]
  EXPECT_TRUE(d.stillOver(2 * kS, 2 * kS + 25'000'000)) << "what later intervals need is kept";
  d.dropBefore(10 * kS);
  EXPECT_EQ(d.size(), 0u);
}

// On the IMU-rate path: once the ring has grown to a window and a state
// interval, adding, testing and dropping never allocate.
TEST(StandstillDetector, SteadyStateNeverAllocates) {
  StandstillDetector d(StandstillParams(), 16);
  ImuSample s;
  s.accel_m_s2 = Vec3(0.0, 0.0, 9.81);
  std::int64_t t = 0;
  auto state_interval = [&] {  // 40 Hz states: 20 samples, a test, a drop
    for (int k = 0; k < 20; ++k, t += kDtNs) {
      s.t_ns = t;
      s.accel_m_s2.x() = 0.01 * std::sin(static_cast<double>(k));
      d.add(s);
    }
    (void)d.stillOver(t - 25'000'000, t);
    d.dropBefore(t);
  };
  for (int i = 0; i < 40; ++i) state_interval();  // 1 s: grown
  std::uint64_t news = 0;
  {
    testing::NewCounter counter;
    for (int i = 0; i < 400; ++i) state_interval();
    news = counter.count();
  }
  EXPECT_EQ(news, 0u);
  EXPECT_LE(d.size(), 450u);
}

TEST(StandstillDetector, RejectsMalformedParameters) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  auto bad = [](StandstillParams p, const char* field) {
    try {
      StandstillDetector d(p);
      ADD_FAILURE() << field << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  StandstillParams p;
  p.window_s = 0.0;
  bad(p, "window_s");
  p.window_s = inf;
  bad(p, "window_s");
  p = StandstillParams();
  p.accel_std_m_s2 = -0.1;
  bad(p, "accel_std_m_s2");
  p.accel_std_m_s2 = nan;
  bad(p, "accel_std_m_s2");
  p = StandstillParams();
  p.gyro_rad_s = nan;
  bad(p, "gyro_rad_s");
  p.gyro_rad_s = -1.0;
  bad(p, "gyro_rad_s");
  p = StandstillParams();
  p.max_speed_m_s = 0.0;
  bad(p, "max_speed_m_s");
  p.max_speed_m_s = nan;
  bad(p, "max_speed_m_s");
  EXPECT_NO_THROW(StandstillDetector{StandstillParams{}});
}

}  // namespace
}  // namespace rilo
