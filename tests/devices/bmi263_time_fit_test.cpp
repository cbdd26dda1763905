// SensorTimeFit and SensorTimeUnwrapper on synthetic (tick, edge time) pairs,
// and the configuration checks.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "hal/bmi263/bmi263_config.h"
#include "hal/bmi263/bmi263_registers.h"
#include "hal/bmi263/sensor_time_fit.h"

namespace rilo::bmi263 {
namespace {

constexpr std::int64_t kPeriod = 32;  // ticks at 800 Hz

// True host time of tick `k` for an oscillator `ppm` fast, offset t0.
std::int64_t trueTime(std::int64_t tick, double ppm, std::int64_t t0_ns) {
  return t0_ns + std::llround(static_cast<double>(tick) * kSensorTimeTickNs / (1.0 + ppm * 1e-6));
}

TEST(SensorTimeUnwrapper, UnwrapsAcrossTheWrapAndLongGaps) {
  SensorTimeUnwrapper unwrapper;
  const std::int64_t tick_ns = std::llround(kSensorTimeTickNs);
  std::int64_t host_ns = 5'000'000'000;
  EXPECT_EQ(unwrapper.unwrap(0xFFFFF0, host_ns), 0xFFFFF0);
  host_ns += 32 * tick_ns;
  EXPECT_EQ(unwrapper.unwrap(0x000010, host_ns), 0x1000010);  // wrapped once
  // A gap of 700 s (more than one wrap of 655.36 s): the host clock resolves it.
  const std::int64_t gap_ticks = 700LL * 25'600;
  host_ns += gap_ticks * tick_ns;
  const auto raw = static_cast<std::uint32_t>((0x1000010 + gap_ticks) & kSensorTimeMask);
  EXPECT_EQ(unwrapper.unwrap(raw, host_ns), 0x1000010 + gap_ticks);
  // A small step back stays a step back (the caller detects it).
  EXPECT_EQ(unwrapper.unwrap(static_cast<std::uint32_t>((raw - 64) & kSensorTimeMask), host_ns),
            0x1000010 + gap_ticks - 64);
  unwrapper.reset();
  EXPECT_EQ(unwrapper.unwrap(0x123456, host_ns), 0x123456);
}

TEST(SensorTimeFit, LowerEnvelopeRemovesOneSidedJitterAndDrift) {
  SensorTimeFit fit;
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<std::int64_t> latency(0, 200'000);
  const double ppm = 50.0;
  const std::int64_t t0 = 2'000'000'000;
  double max_error_ns = 0.0;
  double sum_latency = 0.0;
  int n = 0;
  for (std::int64_t k = 0; k < 800 * 10; ++k) {
    const std::int64_t tick = 1000 + k * kPeriod;
    const std::int64_t lat = latency(rng);
    fit.add(tick, trueTime(tick, ppm, t0) + lat);
    if (k >= 800 * 2) {  // after 2 s
      const double error = static_cast<double>(fit.hostTimeNs(tick) - trueTime(tick, ppm, t0));
      max_error_ns = std::max(max_error_ns, std::abs(error));
      sum_latency += static_cast<double>(lat);
      ++n;
    }
  }
  EXPECT_TRUE(fit.slopeFitted());
  EXPECT_LT(max_error_ns, 10'000.0);  // 10 us, far below the 100 us mean latency
  EXPECT_GT(sum_latency / n, 90'000.0);
  EXPECT_NEAR(fit.ratePpm(), ppm, 3.0);
}

TEST(SensorTimeFit, NominalSlopeUntilTheWindowSpansEnough) {
  SensorTimeFitConfig config;
  config.min_span_ticks = 25'600;  // 1 s
  SensorTimeFit fit(config);
  const std::int64_t t0 = 1'000'000'000;
  for (std::int64_t k = 0; k < 100; ++k) fit.add(k * kPeriod, trueTime(k * kPeriod, 100.0, t0) + 5'000);
  EXPECT_TRUE(fit.hasEstimate());
  EXPECT_FALSE(fit.slopeFitted());
  EXPECT_DOUBLE_EQ(fit.ratePpm(), 0.0);
  // The offset is the lower envelope of h - b_nominal * tick: with the IMU
  // 100 ppm fast that is the newest point, right there up to the constant
  // 5 us latency (which no fit can see).
  const std::int64_t newest = 99 * kPeriod;
  EXPECT_NEAR(static_cast<double>(fit.hostTimeNs(newest) - trueTime(newest, 100.0, t0)), 5'000.0, 1.0);
}

TEST(SensorTimeFit, RejectsPointsBelowTheLineThenResetsIfTheyPersist) {
  SensorTimeFitConfig config;
  config.reset_after = 4;
  SensorTimeFit fit(config);
  const std::int64_t t0 = 1'000'000'000;
  std::int64_t k = 0;
  for (; k < 1600; ++k) ASSERT_EQ(fit.add(k * kPeriod, trueTime(k * kPeriod, 0.0, t0)), SensorTimeFit::AddResult::kAccepted);
  ASSERT_TRUE(fit.slopeFitted());
  // A glitch 2 ms early: rejected, the line does not move.
  EXPECT_EQ(fit.add(k * kPeriod, trueTime(k * kPeriod, 0.0, t0) - 2'000'000), SensorTimeFit::AddResult::kRejectedOutlier);
  ++k;
  EXPECT_NEAR(static_cast<double>(fit.hostTimeNs(k * kPeriod) - trueTime(k * kPeriod, 0.0, t0)), 0.0, 2.0);
  EXPECT_EQ(fit.add(k * kPeriod, trueTime(k * kPeriod, 0.0, t0)), SensorTimeFit::AddResult::kAccepted);
  ++k;
  // A persistent step back of 3 ms: after reset_after points the fit restarts.
  SensorTimeFit::AddResult last = SensorTimeFit::AddResult::kAccepted;
  for (int i = 0; i < 4; ++i, ++k) last = fit.add(k * kPeriod, trueTime(k * kPeriod, 0.0, t0) - 3'000'000);
  EXPECT_EQ(last, SensorTimeFit::AddResult::kReset);
  EXPECT_NEAR(static_cast<double>(fit.hostTimeNs((k - 1) * kPeriod) - trueTime((k - 1) * kPeriod, 0.0, t0)),
              -3'000'000.0, 1.0);
  // Out-of-order ticks are refused.
  EXPECT_EQ(fit.add(0, t0), SensorTimeFit::AddResult::kRejectedOrder);
}

TEST(SensorTimeFit, PersistentLateEdgesRestartTheFit) {
  SensorTimeFitConfig config;
  config.reset_after = 8;
  SensorTimeFit fit(config);
  const std::int64_t t0 = 1'000'000'000;
  std::int64_t k = 0;
  for (; k < 1600; ++k) fit.add(k * kPeriod, trueTime(k * kPeriod, 0.0, t0));
  SensorTimeFit::AddResult last = SensorTimeFit::AddResult::kAccepted;
  for (int i = 0; i < 8; ++i, ++k) last = fit.add(k * kPeriod, trueTime(k * kPeriod, 0.0, t0) + 20'000'000);
  EXPECT_EQ(last, SensorTimeFit::AddResult::kReset);
}

TEST(SensorTimeFit, ImplausibleRateKeepsTheNominalSlope) {
  SensorTimeFit fit;  // max_rate_error 2 %
  const std::int64_t t0 = 1'000'000'000;
  for (std::int64_t k = 0; k < 2000; ++k) fit.add(k * kPeriod, trueTime(k * kPeriod, 50'000.0, t0));  // 5 %
  EXPECT_TRUE(fit.rateOutOfBounds());
  EXPECT_FALSE(fit.slopeFitted());
}

TEST(Bmi263Config, ValidationNamesTheField) {
  auto message = [](const Bmi263Config& config) {
    try {
      config.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(valid)");
  };
  Bmi263Config config;
  EXPECT_NE(message(config).find("config_blob_path"), std::string::npos);
  config.config_blob_path = "/lib/firmware/bmi263.bin";
  EXPECT_EQ(message(config), "(valid)");
  Bmi263Config bad = config;
  bad.accepted_chip_ids.clear();
  EXPECT_NE(message(bad).find("accepted_chip_ids"), std::string::npos);
  bad = config;
  bad.blob_burst_bytes = 33;
  EXPECT_NE(message(bad).find("blob_burst_bytes"), std::string::npos);
  bad = config;
  bad.i2c_retries = -1;
  EXPECT_NE(message(bad).find("i2c_retries"), std::string::npos);
  bad = config;
  bad.time_fit.window = 1;
  EXPECT_NE(message(bad).find("SensorTimeFitConfig.window"), std::string::npos);
  bad = config;
  bad.fifo_read_max_bytes = 64;
  EXPECT_NE(message(bad).find("fifo_read_max_bytes"), std::string::npos);
}

TEST(Bmi263Config, RangeCodesAndScales) {
  EXPECT_EQ(odrCode(Odr::k800Hz), 0x0B);
  EXPECT_EQ(odrCode(Odr::k1600Hz), 0x0C);
  EXPECT_EQ(periodTicks(Odr::k800Hz), 32);
  EXPECT_EQ(periodTicks(Odr::k1600Hz), 16);
  EXPECT_EQ(odr::periodTicks(0x08), 256);
  EXPECT_DOUBLE_EQ(accelLsbPerG(AccelRange::k2g), 16384.0);
  EXPECT_DOUBLE_EQ(accelLsbPerG(AccelRange::k16g), 2048.0);
  EXPECT_EQ(accelRangeCode(AccelRange::k8g), 2);
  EXPECT_DOUBLE_EQ(gyroLsbPerDps(GyroRange::k2000dps), 16.384);
  EXPECT_DOUBLE_EQ(gyroLsbPerDps(GyroRange::k125dps), 262.144);
  EXPECT_EQ(gyroRangeCode(GyroRange::k2000dps), 0);
  EXPECT_EQ(gyroRangeCode(GyroRange::k125dps), 4);
}

}  // namespace
}  // namespace rilo::bmi263
