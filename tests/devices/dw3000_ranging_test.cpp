#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <tuple>

#include "devices/dw3000_test_rig.h"
#include "hal/dw3000/dw3000_device.h"
#include "hal/dw3000/ss_twr.h"
#include "hal/dw3000/timestamp.h"

namespace rilo::dw3000 {
namespace {

using testing::Rig;

constexpr double kCm = 0.01;

// (clock offset source, responder ppm, our ppm)
class Dw3000RangingAccuracy
    : public ::testing::TestWithParam<std::tuple<ClockOffsetSource, double, double>> {};

TEST_P(Dw3000RangingAccuracy, RangesWithinOneCentimetre) {
  const auto [source, responder_ppm, our_ppm] = GetParam();
  emu::Dw3000EmulatorParams params;
  params.clock_ppm = our_ppm;
  Rig rig(params);
  rig.config.clock_offset_source = source;
  rig.addAnchor(1, 0x0001, 1.0, responder_ppm);
  rig.addAnchor(2, 0x0002, 7.5, responder_ppm);
  rig.addAnchor(3, 0x0003, 42.0, responder_ppm);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  for (int round = 0; round < 5; ++round) {
    for (const AnchorConfig& anchor : rig.config.anchors) {
      const ExchangeResult r = device.range(anchor);
      ASSERT_EQ(r.status, ExchangeStatus::kOk) << toString(r.status);
      EXPECT_EQ(r.irq, IrqCheck::kOk);
      EXPECT_FALSE(r.missed_edge);
      const emu::Dw3000ExchangeTruth& truth = rig.chip.lastExchange();
      ASSERT_TRUE(truth.valid);
      EXPECT_EQ(truth.responder, anchor.short_address);
      EXPECT_NEAR(r.range_m, truth.distance_m, kCm) << "anchor " << anchor.id;
      EXPECT_NEAR(r.clock_offset_ratio, truth.clock_offset_ratio, 0.02e-6);
      // The sample time is the RX-good edge.
      EXPECT_EQ(r.t_ns, truth.rx_good_ns);
      // Nothing left that could hold the IRQ line high.
      EXPECT_EQ(rig.chip.status() & device.irqMask(), 0u);
      EXPECT_FALSE(rig.irq.level());
      rig.clock.sleepForNs(1'000'000);
    }
  }
  EXPECT_EQ(rig.chip.counters().speed_violations, 0u);
  EXPECT_EQ(rig.chip.counters().missed_preambles, 0u);
}

INSTANTIATE_TEST_SUITE_P(
    OffsetSources, Dw3000RangingAccuracy,
    ::testing::Combine(::testing::Values(ClockOffsetSource::kCiaDiag0, ClockOffsetSource::kCarrierIntegrator),
                       ::testing::Values(20.0, -20.0), ::testing::Values(0.0, 7.0)));

TEST(Dw3000Ranging, UncorrectedErrorMatchesTheory) {
  for (const double responder_ppm : {20.0, -20.0, 5.0}) {
    Rig rig;
    rig.config.clock_offset_source = ClockOffsetSource::kNone;
    rig.addAnchor(1, 0x0001, 10.0, responder_ppm);
    Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
    device.bringUp();
    const ExchangeResult r = device.range(rig.config.anchors[0]);
    ASSERT_EQ(r.status, ExchangeStatus::kOk);
    const emu::Dw3000ExchangeTruth& truth = rig.chip.lastExchange();
    const double expected_error_m = uncorrectedOffsetErrorM(truth.reply_s, truth.clock_offset_ratio);
    // ~c * Treply * e / 2: 1.5 m at 20 ppm and 500 us.
    EXPECT_NEAR(std::abs(expected_error_m), 299702547.0 * 500e-6 * std::abs(responder_ppm) * 1e-6 / 2.0, 0.01);
    EXPECT_NEAR(r.range_m - truth.distance_m, expected_error_m, 0.005) << responder_ppm << " ppm";
  }
}

TEST(Dw3000Ranging, RangesAcrossTimestampWrapsOfBothClocks) {
  for (const double responder_ppm : {20.0, -20.0}) {
    emu::Dw3000EmulatorParams params;
    params.initial_device_time = kTimestampModulus - 320'000'000;  // ~5 ms after boot
    params.clock_ppm = 3.0;
    Rig rig(params);
    rig.addAnchor(1, 0x0001, 12.3, responder_ppm);
    Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
    device.bringUp();
    // Start the exchange 300 us before our clock wraps, and place the
    // responder's wrap 100 us after ours: both fall inside the exchange.
    const std::uint64_t to_wrap = (kTimestampModulus - rig.chip.deviceTimeNow()) & kTimestampMask;
    const auto to_wrap_ns = static_cast<std::int64_t>(static_cast<double>(to_wrap) / kDeviceClockHz / (1 + 3e-6) * 1e9);
    ASSERT_GT(to_wrap_ns, 300'000);
    rig.clock.sleepForNs(to_wrap_ns - 300'000);
    const double wrap_ns = static_cast<double>(rig.clock.nowNs() + 300'000);
    const double responder_units_at = (wrap_ns + 100'000.0) * 1e-9 * kDeviceClockHz * (1 + responder_ppm * 1e-6);
    rig.chip.responder(0).initial_device_time =
        2 * kTimestampModulus - static_cast<std::uint64_t>(std::llround(responder_units_at));

    const ExchangeResult r = device.range(rig.config.anchors[0]);
    ASSERT_EQ(r.status, ExchangeStatus::kOk) << toString(r.status);
    EXPECT_LT(r.stamps.resp_rx, r.stamps.poll_tx) << "our clock did not wrap inside the exchange";
    EXPECT_LT(r.stamps.resp_tx, r.stamps.poll_rx) << "the responder's clock did not wrap inside the exchange";
    EXPECT_NEAR(r.range_m, rig.chip.lastExchange().distance_m, kCm);
    // And on the other side of the wrap.
    rig.clock.sleepForNs(1'000'000);
    const ExchangeResult after = device.range(rig.config.anchors[0]);
    ASSERT_EQ(after.status, ExchangeStatus::kOk);
    EXPECT_LT(after.stamps.poll_tx, 1'000'000'000u);
    EXPECT_NEAR(after.range_m, rig.chip.lastExchange().distance_m, kCm);
  }
}

TEST(Dw3000Ranging, MovingAnchorAndIrqLatency) {
  Rig rig;
  const std::int64_t t0 = rig.clock.nowNs();
  rig.addAnchor(1, 0x0001, [t0](std::int64_t t_ns) { return 3.0 + 1.5 * static_cast<double>(t_ns - t0) * 1e-9; },
                -12.0);
  rig.irq.setTimestampJitter([] { return std::int64_t{700}; });
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  for (int i = 0; i < 20; ++i) {
    const ExchangeResult r = device.range(rig.config.anchors[0]);
    ASSERT_EQ(r.status, ExchangeStatus::kOk);
    EXPECT_NEAR(r.range_m, rig.chip.lastExchange().distance_m, kCm);
    EXPECT_EQ(r.t_ns, rig.chip.lastExchange().rx_good_ns + 700);
    rig.clock.sleepForNs(100'000'000);
  }
  EXPECT_GT(rig.chip.lastExchange().distance_m, 5.5);  // it did move
}

TEST(Dw3000Ranging, AntennaDelayCalibrationRemovesTheBias) {
  // Our physical delays are 65 units longer than configured: the range is
  // ~65 * 4.69 mm = 0.30 m long until the calibration corrects them.
  emu::Dw3000EmulatorParams params;
  params.true_tx_antenna_delay_units = 16385.0 + 65.0;
  params.true_rx_antenna_delay_units = 16385.0 + 65.0;
  Rig rig(params);
  rig.addAnchor(1, 0x0001, 4.0, 10.0);
  double bias_m = 0.0;
  {
    Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
    device.bringUp();
    for (int i = 0; i < 10; ++i) {
      const ExchangeResult r = device.range(rig.config.anchors[0]);
      ASSERT_EQ(r.status, ExchangeStatus::kOk);
      bias_m += (r.range_m - 4.0) / 10.0;
    }
  }
  EXPECT_NEAR(bias_m, 65.0 * kMetersPerDeviceUnit, kCm);
  const double correction = antennaDelayCorrectionUnits(bias_m);
  rig.config.tx_antenna_delay = static_cast<std::uint16_t>(std::lround(rig.config.tx_antenna_delay + correction));
  rig.config.rx_antenna_delay = static_cast<std::uint16_t>(std::lround(rig.config.rx_antenna_delay + correction));
  EXPECT_EQ(rig.config.tx_antenna_delay, 16385 + 65);
  Dw3000Device calibrated(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  calibrated.bringUp();
  const ExchangeResult r = calibrated.range(rig.config.anchors[0]);
  ASSERT_EQ(r.status, ExchangeStatus::kOk);
  EXPECT_NEAR(r.range_m, 4.0, kCm);
}

TEST(Dw3000Ranging, LinkFailuresAreClassified) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 5.0);
  rig.addAnchor(2, 0x0002, 5.0);
  rig.chip.responder(1).present = false;
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  // Absent anchor: the chip's frame wait timeout ends the exchange.
  ExchangeResult r = device.range(rig.config.anchors[1]);
  EXPECT_EQ(r.status, ExchangeStatus::kRxTimeout);
  EXPECT_EQ(r.irq, IrqCheck::kOk);
  EXPECT_NE(r.sys_status & status::kRxFto, 0u);
  EXPECT_FALSE(rig.irq.level());
  // Injected RX errors.
  for (const std::uint32_t bit : {status::kRxPhe, status::kRxFce, status::kRxFsl, status::kRxSto}) {
    rig.chip.injectRxErrors(bit, 1);
    r = device.range(rig.config.anchors[0]);
    EXPECT_EQ(r.status, ExchangeStatus::kRxError);
    EXPECT_EQ(r.irq, IrqCheck::kOk);  // the ordinary clear was enough
    EXPECT_NE(r.sys_status & bit, 0u);
    EXPECT_EQ(rig.chip.status() & device.irqMask(), 0u);
    EXPECT_FALSE(rig.irq.level());
  }
  // A responder on a reply delay the receiver window cannot catch.
  rig.chip.responder(0).reply_delay_us = 200.0;
  r = device.range(rig.config.anchors[0]);
  EXPECT_EQ(r.status, ExchangeStatus::kRxTimeout);
  EXPECT_EQ(rig.chip.counters().missed_preambles, 1u);
  // Responses that decode but are not ours (a buggy or foreign firmware).
  rig.chip.responder(0).reply_delay_us = rig.config.reply_delay_us;
  const struct {
    std::size_t byte;
    FrameError expected;
  } kCorruptions[] = {{2, FrameError::kWrongSequence},
                      {7, FrameError::kWrongAddress},
                      {5, FrameError::kWrongAddress},
                      {9, FrameError::kWrongFunction},
                      {10, FrameError::kWrongVersion},
                      {0, FrameError::kNotDataFrame}};
  for (const auto& c : kCorruptions) {
    rig.chip.injectResponseCorruption(c.byte, 0x40, 1);
    r = device.range(rig.config.anchors[0]);
    EXPECT_EQ(r.status, ExchangeStatus::kBadFrame) << c.byte;
    EXPECT_EQ(r.frame_error, c.expected) << c.byte;
    EXPECT_FALSE(rig.irq.level());
  }
  // Everything recovers.
  r = device.range(rig.config.anchors[0]);
  EXPECT_EQ(r.status, ExchangeStatus::kOk);
  EXPECT_NEAR(r.range_m, 5.0, kCm);
}

}  // namespace
}  // namespace rilo::dw3000
