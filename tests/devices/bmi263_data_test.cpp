// Data path: SI values within quantization of the emulator's truth for every
// range setting, saturation, temperature.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "bmi263_test_util.h"

namespace rilo::bmi263 {
namespace {

using testing::RecordingSink;
using testing::Rig;
using testing::smoothMotion;

struct RangeCase {
  AccelRange accel;
  GyroRange gyro;
  Odr odr;
  InterruptMode mode;
};

class Bmi263DataTest : public ::testing::TestWithParam<RangeCase> {};

TEST_P(Bmi263DataTest, SiWithinQuantizationOfTheTruth) {
  const RangeCase c = GetParam();
  Rig rig;
  rig.config.accel_range = c.accel;
  rig.config.gyro_range = c.gyro;
  rig.config.odr = c.odr;
  rig.config.interrupt_mode = c.mode;
  RecordingSink sink;
  const std::int64_t duration_ns = 1'500'000'000;
  EXPECT_EQ(rig.runFor(duration_ns, sink), SourceEnd::kStopped);
  EXPECT_TRUE(sink.faults.empty()) << sink.allFaults();

  // Half an LSB (plus rounding slack) in SI.
  const double accel_tol = 0.5 * kStandardGravity / accelLsbPerG(c.accel) * (1.0 + 1e-9);
  const double gyro_tol = 0.5 * (std::numbers::pi / 180.0) / gyroLsbPerDps(c.gyro) * (1.0 + 1e-9);
  const double period_ns = 1e9 / odrHz(c.odr);
  ASSERT_GT(sink.samples.size(), static_cast<std::size_t>(1.2 * odrHz(c.odr)));
  std::int64_t last_t = 0;
  for (const ImuSample& s : sink.samples) {
    const std::int64_t t_true = rig.emulator->nearestSampleTimeNs(s.t_ns);
    ASSERT_LT(std::abs(static_cast<double>(s.t_ns - t_true)), period_ns / 4);
    ASSERT_GT(s.t_ns, last_t);
    last_t = s.t_ns;
    const emu::ImuTruth truth = smoothMotion(t_true);
    for (int axis = 0; axis < 3; ++axis) {
      ASSERT_NEAR(s.accel_m_s2[axis], truth.accel_m_s2[axis], accel_tol) << "axis " << axis;
      ASSERT_NEAR(s.gyro_rad_s[axis], truth.gyro_rad_s[axis], gyro_tol) << "axis " << axis;
    }
  }
  const Bmi263Counters counters = rig.source->counters();
  EXPECT_EQ(counters.missed_samples, 0u);
  EXPECT_EQ(counters.samples, sink.samples.size());
  // No gaps: one sample per period from the first to the last.
  const double span_periods =
      static_cast<double>(sink.samples.back().t_ns - sink.samples.front().t_ns) / period_ns;
  EXPECT_NEAR(span_periods, static_cast<double>(sink.samples.size() - 1), 0.5);
  EXPECT_LE(rig.emulator->samplesProduced() - counters.samples, 0.06 * odrHz(c.odr) + 8);  // start-up wait
}

INSTANTIATE_TEST_SUITE_P(
    AllRanges, Bmi263DataTest,
    ::testing::Values(RangeCase{AccelRange::k2g, GyroRange::k125dps, Odr::k800Hz, InterruptMode::kDataReady},
                      RangeCase{AccelRange::k4g, GyroRange::k250dps, Odr::k1600Hz, InterruptMode::kDataReady},
                      RangeCase{AccelRange::k8g, GyroRange::k500dps, Odr::k800Hz, InterruptMode::kDataReady},
                      RangeCase{AccelRange::k16g, GyroRange::k1000dps, Odr::k1600Hz, InterruptMode::kDataReady},
                      RangeCase{AccelRange::k16g, GyroRange::k2000dps, Odr::k800Hz, InterruptMode::kDataReady},
                      RangeCase{AccelRange::k2g, GyroRange::k125dps, Odr::k800Hz, InterruptMode::kFifoWatermark},
                      RangeCase{AccelRange::k8g, GyroRange::k2000dps, Odr::k1600Hz, InterruptMode::kFifoWatermark}));

TEST(Bmi263Data, SaturatesAtTheRangeLimit) {
  auto violent = [](std::int64_t) {
    emu::ImuTruth truth;
    truth.accel_m_s2 = Eigen::Vector3d(40.0, -40.0, 9.8);
    truth.gyro_rad_s = Eigen::Vector3d(5.0, -5.0, 0.1);
    return truth;
  };
  Rig rig({}, violent);
  rig.config.accel_range = AccelRange::k2g;
  rig.config.gyro_range = GyroRange::k125dps;
  RecordingSink sink;
  rig.runFor(300'000'000, sink);
  ASSERT_FALSE(sink.samples.empty());
  const ImuSample& s = sink.samples.back();
  EXPECT_NEAR(s.accel_m_s2.x(), 32767.0 / 16384.0 * kStandardGravity, 1e-9);
  EXPECT_NEAR(s.accel_m_s2.y(), -2.0 * kStandardGravity, 1e-9);
  EXPECT_NEAR(s.gyro_rad_s.x(), 32767.0 / 262.144 * std::numbers::pi / 180.0, 1e-9);
  EXPECT_NEAR(s.gyro_rad_s.y(), -125.0 * std::numbers::pi / 180.0, 1e-9);
}

// Gyro cross-axis sensitivity (Bosch's BMI2 API: x -= GYR_CAS * z / 512): a
// part with the factor reads z into x; the driver reads the factor from the
// part after its configuration and takes it out of every sample, in both
// interrupt modes. Off, the coupling stays.
TEST(Bmi263Data, TheCrossAxisFactorIsReadFromThePartAndTakenOut) {
  auto spin_about_z = [](std::int64_t) {
    emu::ImuTruth truth;
    truth.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, kStandardGravity);
    truth.gyro_rad_s = Eigen::Vector3d(0.05, -0.02, 3.0);
    return truth;
  };
  const double lsb_rad_s = (std::numbers::pi / 180.0) / gyroLsbPerDps(GyroRange::k2000dps);
  for (const InterruptMode mode : {InterruptMode::kDataReady, InterruptMode::kFifoWatermark}) {
    for (const GyroCrossAxis setting : {GyroCrossAxis::kAuto, GyroCrossAxis::kOff}) {
      SCOPED_TRACE(std::string(toString(mode)) + " " + toString(setting));
      emu::Bmi263EmulatorConfig part;
      part.gyro_cas = -37;  // x reads 37/512 of z too little: -0.217 rad/s at 3 rad/s
      Rig rig(part, spin_about_z);
      rig.config.interrupt_mode = mode;
      rig.config.gyro_cross_axis = setting;
      RecordingSink sink;
      rig.runFor(300'000'000, sink);
      ASSERT_FALSE(sink.samples.empty()) << sink.allFaults();
      const bool corrected = setting == GyroCrossAxis::kAuto;  // the emulator is a BMI270 by id
      const double expected_x = corrected ? 0.05 : 0.05 - 37.0 / 512.0 * 3.0;
      for (const ImuSample& s : sink.samples) {
        // Two LSB: the part's rounding plus the correction's integer division.
        ASSERT_NEAR(s.gyro_rad_s.x(), expected_x, 2.0 * lsb_rad_s);
        ASSERT_NEAR(s.gyro_rad_s.z(), 3.0, 0.5 * lsb_rad_s * (1.0 + 1e-9));
      }
    }
  }
}

TEST(Bmi263Data, TheCrossAxisCorrectionFollowsBoschsArithmetic) {
  EXPECT_EQ(Bmi263Config{}.gyro_cross_axis, GyroCrossAxis::kOff);  // unverified on the BMI263
  EXPECT_EQ(decodeGyrCas(0x00), 0);
  EXPECT_EQ(decodeGyrCas(0x3F), 63);
  EXPECT_EQ(decodeGyrCas(0x40), -64);
  EXPECT_EQ(decodeGyrCas(0x7F), -1);
  EXPECT_EQ(decodeGyrCas(0xDB), -37);  // bit 7 is not part of the field
  std::array<std::int16_t, 3> g{1000, -5, 20000};
  correctGyroCrossAxis(g, 10);  // 10 * 20000 / 512 = 390.6 -> 390 (truncated)
  EXPECT_EQ(g[0], 610);
  EXPECT_EQ(g[1], -5);
  EXPECT_EQ(g[2], 20000);
  g = {-1000, 0, -20001};
  correctGyroCrossAxis(g, 10);  // -390.6 -> -390: truncated towards zero, as C's division
  EXPECT_EQ(g[0], -610);
  g = {32700, 0, -32768};
  correctGyroCrossAxis(g, 63);  // +4032: saturates
  EXPECT_EQ(g[0], 32767);
}

TEST(Bmi263Data, AutoCorrectsOnlyTheBmi270sIdAndOnReadsTheFactorFromAnyPart) {
  emu::Bmi263EmulatorConfig part;
  part.chip_id = kChipIdBmi260;
  part.gyro_cas = 20;
  Rig rig(part);
  rig.config.accepted_chip_ids = {kChipIdBmi260};
  rig.config.gyro_cross_axis = GyroCrossAxis::kAuto;
  Bmi263Driver driver(*rig.emulator, rig.clock, rig.config);
  const BringUpResult automatic = driver.bringUp();
  ASSERT_TRUE(automatic.ok) << automatic.error;
  EXPECT_FALSE(automatic.gyro_cross_axis);
  EXPECT_FALSE(driver.gyroCrossAxis());
  rig.config.gyro_cross_axis = GyroCrossAxis::kOn;  // a part known to carry the factor there
  const BringUpResult forced = driver.bringUp();
  ASSERT_TRUE(forced.ok) << forced.error;
  EXPECT_TRUE(forced.gyro_cross_axis);
  EXPECT_EQ(forced.gyro_cas, 20);
  EXPECT_EQ(driver.gyroCas(), 20);
}

TEST(Bmi263Data, TemperatureIsReadOccasionally) {
  Rig rig;
  rig.config.temperature_period_ns = 500'000'000;
  RecordingSink sink;
  rig.runFor(3'000'000'000, sink);
  const Bmi263Counters c = rig.source->counters();
  EXPECT_GE(c.temperature_reads, 5u);
  EXPECT_LE(c.temperature_reads, 7u);
  EXPECT_NEAR(c.temperature_degc, 31.5, 1.0 / 512.0);
}

}  // namespace
}  // namespace rilo::bmi263
