// RX level and first-path power: the user manual's formulas against worked
// numbers, the register decoding, and the driver reading them with every
// good exchange (through the emulator's channel), a failed read keeping the
// range.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <system_error>

#include "devices/dw3000_test_rig.h"
#include "hal/dw3000/dw3000_device.h"
#include "hal/dw3000/dw3000_source.h"
#include "hal/dw3000/registers.h"
#include "hal/dw3000/rx_power.h"

namespace rilo::dw3000 {
namespace {

using testing::CollectingSink;
using testing::Rig;

constexpr std::int64_t kS = 1'000'000'000;

RxDiagnostics diagnostics(std::uint32_t c, std::uint32_t f1, std::uint32_t f2, std::uint32_t f3, std::uint32_t n,
                          std::uint8_t d) {
  RxDiagnostics diag;
  diag.cir_power = c;
  diag.fp_ampl1 = f1;
  diag.fp_ampl2 = f2;
  diag.fp_ampl3 = f3;
  diag.accumulation_count = n;
  diag.dgc_decision = d;
  return diag;
}

// Worked numbers for the DW3000 user manual v1.1 formulas (4.7.1, 4.7.2),
// computed by hand from the formulas (the arithmetic is beside each case).
// The manual gives no numeric example; Qorvo's driver's RSL unit test lists
// the same values (0.1 dB), which cross-checks our reading of the constants.
TEST(RxPowerFromDiagnostics, MatchesWorkedExamplesOfTheUserManualFormula) {
  // RX level, 64 MHz PRF (A = 121.7): 10 log10(47 * 2^21 / 65^2) - 121.7.
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(47, 0, 0, 0, 65, 0), true).rssi_dbm, -78.0, 0.05);
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(32, 0, 0, 0, 65, 0), true).rssi_dbm, -79.7, 0.05);
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(13, 0, 0, 0, 65, 0), true).rssi_dbm, -83.6, 0.05);
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(2, 0, 0, 0, 65, 0), true).rssi_dbm, -91.7, 0.05);
  // One DGC step adds 6 dB.
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(13, 0, 0, 0, 65, 1), true).rssi_dbm, -77.6, 0.05);
  // 16 MHz PRF (A = 113.8).
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(2, 0, 0, 0, 65, 0), false).rssi_dbm, -83.83, 0.05);

  // First path: F = 0x26D9, 0x27EA, 0x159E (2 fractional bits: 2486.25,
  // 2554.5, 1383.5), N = 63, D = 3: 10 log10(sum F^2 / 63^2) + 6 * 3 - A.
  // With A = 120.7 (an STS reception) that is -67.04 dBm; the Ipatov
  // preamble we range on has A = 121.7, 1 dB lower: -68.04 dBm.
  const RxPower fp = rxPowerFromDiagnostics(diagnostics(0, 0x26D9, 0x27EA, 0x159E, 0x3F, 3), true);
  EXPECT_NEAR(fp.fp_power_dbm, -67.04 - 1.0, 0.05);
  EXPECT_TRUE(std::isnan(fp.rssi_dbm));  // C = 0: no RX level, not -inf
}

TEST(RxPowerFromDiagnostics, ExactFormulaAndNoDiagnostics) {
  // C = 2^15, N = 128: 10 log10(2^15 * 2^21 / 2^14) - 121.7 = 10 log10(2^22) - 121.7.
  const RxPower p = rxPowerFromDiagnostics(diagnostics(1u << 15, 4000, 4000, 4000, 128, 0), true);
  EXPECT_NEAR(p.rssi_dbm, 10.0 * std::log10(4194304.0) - 121.7, 1e-9);
  // F carry 2 fractional bits: 1000 each, 3e6 / 16384.
  EXPECT_NEAR(p.fp_power_dbm, 10.0 * std::log10(3e6 / 16384.0) - 121.7, 1e-9);
  const RxPower prf16 = rxPowerFromDiagnostics(diagnostics(1u << 15, 4000, 4000, 4000, 128, 0), false);
  EXPECT_NEAR(prf16.rssi_dbm - p.rssi_dbm, 121.7 - 113.8, 1e-9);
  EXPECT_NEAR(prf16.fp_power_dbm - p.fp_power_dbm, 121.7 - 113.8, 1e-9);
  const RxPower dgc = rxPowerFromDiagnostics(diagnostics(1u << 15, 4000, 4000, 4000, 128, 7), true);
  EXPECT_NEAR(dgc.rssi_dbm - p.rssi_dbm, 42.0, 1e-9);
  EXPECT_NEAR(dgc.fp_power_dbm - p.fp_power_dbm, 42.0, 1e-9);
  // No diagnostics: NaN, not -inf.
  EXPECT_TRUE(std::isnan(rxPowerFromDiagnostics(diagnostics(1000, 1, 1, 1, 0, 0), true).rssi_dbm));
  EXPECT_TRUE(std::isnan(rxPowerFromDiagnostics(diagnostics(1000, 1, 1, 1, 0, 0), true).fp_power_dbm));
  EXPECT_TRUE(std::isnan(rxPowerFromDiagnostics(diagnostics(0, 0, 0, 0, 128, 0), true).rssi_dbm));
  EXPECT_TRUE(std::isnan(rxPowerFromDiagnostics(diagnostics(0, 0, 0, 0, 128, 0), true).fp_power_dbm));
}

TEST(DecodeRxDiagnostics, MasksEveryFieldAtItsOffset) {
  std::array<std::uint8_t, kIpDiagBlockBytes> block{};
  block.fill(0xFF);  // reserved bits and the diagnostics between F3 and N all set
  const auto put = [&block](std::size_t reg_offset, std::uint32_t v) {
    for (std::size_t i = 0; i < 4; ++i) {
      block[reg_offset - kIpDiagFirstOffset + i] = static_cast<std::uint8_t>((v >> (8 * i)) & 0xFFu);
    }
  };
  put(0x2C, 0xFFFE'0000u | 0x1'2345u);
  put(0x30, 0xFFC0'0000u | 0x3A'BCDEu);
  put(0x34, 0xFFC0'0000u | 0x00'0001u);
  put(0x38, 0xFFC0'0000u | 0x2F'0000u);
  put(0x58, 0xFFFF'F000u | 0x077u);
  const RxDiagnostics d = decodeRxDiagnostics(block, 0xDFFF'FFFFu);  // bits 30:28 = 5
  EXPECT_EQ(d.cir_power, 0x1'2345u);
  EXPECT_EQ(d.fp_ampl1, 0x3A'BCDEu);
  EXPECT_EQ(d.fp_ampl2, 0x1u);
  EXPECT_EQ(d.fp_ampl3, 0x2F'0000u);
  EXPECT_EQ(d.accumulation_count, 0x77u);
  EXPECT_EQ(d.dgc_decision, 5);
  EXPECT_EQ(decodeRxDiagnostics(block, 0).dgc_decision, 0);
}

// --- through the driver and the emulated channel ---------------------------

/// |error| bound of the RX level from C's rounding to an integer.
double rssiRoundingDb(double rx_level_dbm, std::uint32_t n, int dgc_decision, bool prf64 = true) {
  const double c = std::pow(10.0, (rx_level_dbm + rxPowerConstantDb(prf64) - 6.0 * dgc_decision) / 10.0) *
                   static_cast<double>(n) * static_cast<double>(n) / 2097152.0;
  return 10.0 * std::log10((c + 0.5) / c) + 1e-9;
}

// The start-up turns the DGC on at 64 MHz PRF (its table and threshold) and
// off at 16 MHz (dwt_configure); its decision then enters the RX level.
class Dw3000RxPowerDgc : public ::testing::TestWithParam<bool> {};  // 64 MHz PRF: DGC on?

TEST_P(Dw3000RxPowerDgc, EveryGoodExchangeCarriesTheChannelsLevels) {
  const bool dgc = GetParam();
  Rig rig;
  rig.config.preamble_code = dgc ? 9 : 3;  // 64 / 16 MHz PRF on channel 5
  rig.addAnchor(1, 0x0001, 3.0);
  rig.addAnchor(2, 0x0002, 12.0);
  rig.chip.responder(0).nlos_gap_db = [](std::int64_t) { return 1.5; };  // line of sight
  rig.chip.responder(1).nlos_gap_db = [](std::int64_t) { return 9.0; };  // direct path blocked
  rig.chip.responder(1).rx_level_at_1m_dbm = -60.0;
  rig.chip.responder(0).dgc_decision = 2;  // served only while the DGC is on
  rig.chip.responder(1).dgc_decision = 1;
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  EXPECT_EQ(device.dgcEnabled(), dgc);
  const std::uint32_t n = emu::Dw3000EmulatorParams{}.preamble_accumulation_count;
  for (int round = 0; round < 3; ++round) {
    for (const AnchorConfig& anchor : rig.config.anchors) {
      SCOPED_TRACE(anchor.id);
      const ExchangeResult r = device.range(anchor);
      ASSERT_EQ(r.status, ExchangeStatus::kOk) << toString(r.status);
      EXPECT_FALSE(r.diagnostics_error);
      const emu::Dw3000ExchangeTruth& truth = rig.chip.lastExchange();
      ASSERT_TRUE(truth.valid);
      EXPECT_EQ(truth.dgc_decision, dgc ? (anchor.id == 1 ? 2 : 1) : 0);
      EXPECT_NEAR(r.rx_power.rssi_dbm, truth.rx_level_dbm,
                  rssiRoundingDb(truth.rx_level_dbm, n, truth.dgc_decision, dgc));
      EXPECT_NEAR(r.rx_power.fp_power_dbm, truth.fp_power_dbm, 0.01);
      EXPECT_EQ(rig.chip.status() & device.irqMask(), 0u);
      rig.clock.sleepForNs(1'000'000);
    }
  }
  // The levels follow the channel: 20 log10 over distance, the NLOS gap.
  const double near_dbm = -63.0 - 20.0 * std::log10(3.0);
  const double near_tol_db = rssiRoundingDb(near_dbm, n, dgc ? 2 : 0, dgc) + 0.01;
  const ExchangeResult near = device.range(rig.config.anchors[0]);
  EXPECT_NEAR(near.rx_power.rssi_dbm, near_dbm, near_tol_db);
  EXPECT_NEAR(near.rx_power.rssi_dbm - near.rx_power.fp_power_dbm, 1.5, near_tol_db);
  rig.clock.sleepForNs(1'000'000);
  const double far_dbm = -60.0 - 20.0 * std::log10(12.0);
  const ExchangeResult far = device.range(rig.config.anchors[1]);
  EXPECT_NEAR(far.rx_power.rssi_dbm, far_dbm, rssiRoundingDb(far_dbm, n, dgc ? 1 : 0, dgc) + 0.01);
  EXPECT_GT(far.rx_power.rssi_dbm - far.rx_power.fp_power_dbm, 6.0);  // APS006: likely NLOS
}

INSTANTIATE_TEST_SUITE_P(DgcOffAndOn, Dw3000RxPowerDgc, ::testing::Bool());

TEST(Dw3000RxPower, TheNlosGapFollowsTheChannelOverTime) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 5.0);
  // Someone walks into the direct path one second in.
  const std::int64_t blocked_from_ns = rig.clock.nowNs() + kS;
  rig.chip.responder(0).nlos_gap_db = [blocked_from_ns](std::int64_t t_ns) {
    return t_ns < blocked_from_ns ? 2.0 : 10.0;
  };
  Dw3000Source source(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  CollectingSink sink;
  rig.run(source, sink, 2 * kS);
  ASSERT_GE(sink.ranges.size(), 15u);
  for (const RangeSample& s : sink.ranges) {
    ASSERT_TRUE(std::isfinite(s.rssi_dbm));
    ASSERT_TRUE(std::isfinite(s.fp_power_dbm));
    EXPECT_NEAR(s.rssi_dbm, -63.0 - 20.0 * std::log10(5.0), 0.05);
    EXPECT_NEAR(s.rssi_dbm - s.fp_power_dbm, s.t_ns < blocked_from_ns ? 2.0 : 10.0, 0.05) << s.t_ns;
  }
  EXPECT_EQ(Dw3000Stats::get(source.stats().diagnostics_read_failures), 0u);
}

TEST(Dw3000RxPower, AFailedDiagnosticsReadKeepsTheRangeWithoutPowers) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  rig.chip.failReadsOf(reg::kIpDiag1.file, reg::kIpDiag1.offset, 1, std::make_error_code(std::errc::io_error));
  const ExchangeResult failed = device.range(rig.config.anchors[0]);
  ASSERT_EQ(failed.status, ExchangeStatus::kOk) << toString(failed.status);
  EXPECT_EQ(failed.diagnostics_error, std::make_error_code(std::errc::io_error));
  EXPECT_NEAR(failed.range_m, 4.0, 0.01);
  EXPECT_TRUE(std::isnan(failed.rx_power.rssi_dbm));
  EXPECT_TRUE(std::isnan(failed.rx_power.fp_power_dbm));
  EXPECT_EQ(failed.irq, IrqCheck::kOk);  // the exchange was still cleared up
  EXPECT_EQ(rig.chip.status() & device.irqMask(), 0u);
  rig.clock.sleepForNs(1'000'000);
  const ExchangeResult next = device.range(rig.config.anchors[0]);
  ASSERT_EQ(next.status, ExchangeStatus::kOk);
  EXPECT_FALSE(next.diagnostics_error);
  EXPECT_TRUE(std::isfinite(next.rx_power.rssi_dbm));
}

TEST(Dw3000RxPower, TheSourcePushesTheRangeWithNanPowersAndCountsTheFailure) {
  Rig rig;
  rig.config.spi_crc = true;  // every read followed by its SPI_RD_CRC check (the DGC is on: 64 MHz PRF)
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Source source(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  CollectingSink sink;
  // Fail the DGC_DBG read of the first two exchanges (the second read of a
  // good exchange, after the IP_DIAG burst).
  rig.chip.failReadsOf(reg::kDgcDbg.file, reg::kDgcDbg.offset, 2, std::make_error_code(std::errc::io_error));
  EXPECT_EQ(rig.run(source, sink, kS), SourceEnd::kStopped);
  ASSERT_GE(sink.ranges.size(), 8u);
  EXPECT_TRUE(sink.faults.empty()) << sink.faults.front().what;  // not a device fault
  EXPECT_EQ(Dw3000Stats::get(source.stats().diagnostics_read_failures), 2u);
  EXPECT_EQ(Dw3000Stats::get(source.stats().ranges), sink.ranges.size());
  EXPECT_EQ(Dw3000Stats::get(source.stats().spi_errors), 0u);
  for (std::size_t i = 0; i < sink.ranges.size(); ++i) {
    const RangeSample& s = sink.ranges[i];
    SCOPED_TRACE(i);
    EXPECT_NEAR(s.range_m, 4.0, 0.01);
    EXPECT_EQ(std::isnan(s.rssi_dbm), i < 2);
    EXPECT_EQ(std::isnan(s.fp_power_dbm), i < 2);
  }
}

}  // namespace
}  // namespace rilo::dw3000
