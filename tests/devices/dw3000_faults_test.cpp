#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <system_error>

#include "devices/dw3000_test_rig.h"
#include "hal/dw3000/dw3000_source.h"
#include "hal/dw3000/registers.h"

namespace rilo::dw3000 {
namespace {

using testing::CollectingSink;
using testing::Rig;

constexpr std::int64_t kMs = 1'000'000;

/// One anchor at 4 m with a +15 ppm clock; the fault is injected at 300 ms.
struct FaultRun {
  explicit FaultRun(bool spi_crc = false) {
    rig.config.spi_crc = spi_crc;
    rig.addAnchor(7, 0x0007, 4.0, 15.0);
  }
  /// Runs 1 s with `inject` at 300 ms; returns the end.
  SourceEnd run(const std::function<void()>& inject) {
    inject_ns = rig.clock.nowNs() + 300 * kMs;
    rig.clock.schedule(inject_ns, inject);
    source = std::make_unique<Dw3000Source>(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
    return rig.run(*source, sink, 1000 * kMs);
  }
  std::uint64_t stat(const Dw3000Stats::Counter Dw3000Stats::*counter) const {
    return Dw3000Stats::get(source->stats().*counter);
  }
  /// Ranged normally after the fault (10 Hz for the rest of the second).
  void expectRecovered(std::size_t min_ranges_after = 5) const {
    EXPECT_GE(sink.rangesFrom(7, inject_ns + 100 * kMs), min_ranges_after);
    for (const RangeSample& r : sink.ranges) EXPECT_NEAR(r.range_m, 4.0, 0.01);
    for (const SourceFault& f : sink.faults) EXPECT_FALSE(f.fatal) << f.what;
    EXPECT_FALSE(rig.irq.level());
  }

  Rig rig;
  CollectingSink sink;
  std::unique_ptr<Dw3000Source> source;
  std::int64_t inject_ns = 0;
};

TEST(Dw3000Faults, RxErrorsAreCountedReportedAndRetried) {
  FaultRun f;
  EXPECT_EQ(f.run([&] { f.rig.chip.injectRxErrors(status::kRxPhe | status::kRxFce, 2); }), SourceEnd::kStopped);
  EXPECT_EQ(f.stat(&Dw3000Stats::rx_errors), 2u);
  EXPECT_EQ(f.sink.faultsContaining("RX error from anchor 7 (0x0007) (RXPHE|RXFCE); retry in"), 2u);
  EXPECT_EQ(f.stat(&Dw3000Stats::anchors_dropped), 0u);
  f.expectRecovered();
}

TEST(Dw3000Faults, FrameSyncLossAndSfdTimeout) {
  FaultRun f;
  f.run([&] { f.rig.chip.injectRxErrors(status::kRxFsl | status::kRxSto, 1); });
  EXPECT_EQ(f.stat(&Dw3000Stats::rx_errors), 1u);
  EXPECT_EQ(f.sink.faultsContaining("(RXFSL|RXSTO)"), 1u);
  f.expectRecovered();
}

TEST(Dw3000Faults, LostResponsesAreTimeouts) {
  FaultRun f;
  f.run([&] { f.rig.chip.injectRxTimeouts(2); });
  EXPECT_EQ(f.stat(&Dw3000Stats::rx_timeouts), 2u);
  EXPECT_EQ(f.sink.faultsContaining("RX timeout from anchor 7 (0x0007) (RXFTO)"), 2u);
  f.expectRecovered();
}

TEST(Dw3000Faults, RepeatedFailuresDropTheOnlyAnchorUntilRediscovered) {
  FaultRun f;
  f.run([&] { f.rig.chip.injectRxTimeouts(4); });
  EXPECT_EQ(f.stat(&Dw3000Stats::anchors_dropped), 1u);
  EXPECT_EQ(f.sink.faultsContaining("dropped from the ranging set"), 1u);
  // The fourth loss hits a rediscovery poll (counted, not reported); the
  // next rediscovery brings it back.
  EXPECT_EQ(f.stat(&Dw3000Stats::rx_timeouts), 4u);
  f.expectRecovered(3);
}

TEST(Dw3000Faults, WriteCrcErrorIsRetried) {
  FaultRun f(/*spi_crc=*/true);
  f.run([&] { f.rig.chip.injectWriteCrcErrors(1); });
  EXPECT_EQ(f.rig.chip.counters().write_crc_errors, 1u);
  EXPECT_EQ(f.stat(&Dw3000Stats::spi_crc_errors), 1u);
  EXPECT_EQ(f.sink.faultsContaining("SPI CRC error"), 1u);
  EXPECT_EQ(f.sink.faultsContaining("1 device fault(s) in a row, retrying in 10 ms"), 1u);
  EXPECT_EQ(f.stat(&Dw3000Stats::bringups), 1u);  // one fault: no re-init
  f.expectRecovered();
}

TEST(Dw3000Faults, ReadCrcErrorIsRetried) {
  FaultRun f(/*spi_crc=*/true);
  f.run([&] { f.rig.chip.injectReadCrcErrors(1); });
  EXPECT_EQ(f.stat(&Dw3000Stats::spi_crc_errors), 1u);
  EXPECT_EQ(f.sink.faultsContaining("SPI read CRC mismatch"), 1u);
  f.expectRecovered();
}

TEST(Dw3000Faults, RepeatedCrcErrorsReinitializeAfterBackoff) {
  FaultRun f(/*spi_crc=*/true);
  f.run([&] { f.rig.chip.injectReadCrcErrors(3); });
  EXPECT_EQ(f.stat(&Dw3000Stats::spi_crc_errors), 3u);
  EXPECT_EQ(f.sink.faultsContaining("retrying in 10 ms"), 1u);
  EXPECT_EQ(f.sink.faultsContaining("retrying in 20 ms"), 1u);
  EXPECT_EQ(f.sink.faultsContaining("3 device fault(s) in a row, re-initializing in 40 ms"), 1u);
  EXPECT_EQ(f.stat(&Dw3000Stats::bringups), 2u);
  // Each start-up is told for the log, the second as a re-initialization.
  ASSERT_EQ(f.sink.notes.size(), 2u);
  EXPECT_EQ(f.sink.notes[0].what.rfind("started: ", 0), 0u) << f.sink.notes[0].what;
  EXPECT_EQ(f.sink.notes[1].what.rfind("re-initialized: ", 0), 0u) << f.sink.notes[1].what;
  EXPECT_NE(f.sink.notes[1].what.find("PGF calibration done"), std::string::npos) << f.sink.notes[1].what;
  ASSERT_EQ(f.sink.faults.size(), 3u);
  EXPECT_GE(f.sink.faults[1].t_ns - f.sink.faults[0].t_ns, 10 * kMs);
  EXPECT_GE(f.sink.faults[2].t_ns - f.sink.faults[1].t_ns, 20 * kMs);
  f.expectRecovered();
}

TEST(Dw3000Faults, SpiTransferErrorCarriesErrno) {
  FaultRun f;
  f.run([&] { f.rig.chip.failNextTransfers(1, std::make_error_code(std::errc::io_error)); });
  EXPECT_EQ(f.stat(&Dw3000Stats::spi_errors), 1u);
  EXPECT_EQ(f.sink.faultsContaining("SPI error: " + std::make_error_code(std::errc::io_error).message()), 1u);
  f.expectRecovered();
}

TEST(Dw3000Faults, IrqWaitErrorIsADeviceFault) {
  FaultRun f;
  f.run([&] { f.rig.irq.failNextWaits(1, std::make_error_code(std::errc::io_error)); });
  EXPECT_EQ(f.stat(&Dw3000Stats::irq_wait_errors), 1u);
  EXPECT_EQ(f.sink.faultsContaining("IRQ wait error"), 1u);
  f.expectRecovered();
}

TEST(Dw3000Faults, IrqHighAfterClearingIsRecoveredByAFullClear) {
  FaultRun f;
  f.run([&] { f.rig.chip.injectStuckIrq(emu::StuckIrq::kUntilFullClear); });
  EXPECT_EQ(f.stat(&Dw3000Stats::irq_stuck_recovered), 1u);
  EXPECT_EQ(f.stat(&Dw3000Stats::irq_stuck), 0u);
  EXPECT_EQ(f.rig.chip.counters().clr_irqs, 1u);
  EXPECT_EQ(f.sink.faultsContaining("a full clear (all bits and CLR_IRQS) brought it low"), 1u);
  EXPECT_EQ(f.stat(&Dw3000Stats::bringups), 1u);
  f.expectRecovered();
}

TEST(Dw3000Faults, IrqStuckHighReinitializesTheChip) {
  FaultRun f;
  f.run([&] { f.rig.chip.injectStuckIrq(emu::StuckIrq::kUntilReset); });
  EXPECT_EQ(f.stat(&Dw3000Stats::irq_stuck), 1u);
  EXPECT_EQ(f.sink.faultsContaining("IRQ line stuck high after a full clear of SYS_STATUS"), 1u);
  EXPECT_EQ(f.sink.faultsContaining("re-initializing"), 1u);
  EXPECT_EQ(f.stat(&Dw3000Stats::bringups), 2u);
  // The range of that exchange itself was good and was kept.
  EXPECT_EQ(f.stat(&Dw3000Stats::ranges), f.sink.ranges.size());
  f.expectRecovered();
}

TEST(Dw3000Faults, PllLossOfLockIsSeenAsAPollNeverSentAndReinitializes) {
  FaultRun f;
  f.run([&] { f.rig.chip.injectPllLossOfLock(); });
  EXPECT_EQ(f.stat(&Dw3000Stats::tx_failures), 1u);
  EXPECT_EQ(f.sink.faultsContaining("poll not transmitted"), 1u);
  EXPECT_EQ(f.stat(&Dw3000Stats::bringups), 2u);
  EXPECT_GE(f.rig.chip.counters().pll_locks, 2u);
  f.expectRecovered();
}

TEST(Dw3000Faults, PllLockFailureDuringReinitIsRetried) {
  FaultRun f;
  f.run([&] {
    f.rig.chip.injectPllLossOfLock();
    f.rig.chip.injectPllLockFailures(2);
  });
  EXPECT_EQ(f.stat(&Dw3000Stats::pll_lock_failures), 2u);
  EXPECT_EQ(f.sink.faultsContaining("re-initialization failed: dw3000 emu:spidev0.0: PLL did not lock"), 2u);
  EXPECT_EQ(f.stat(&Dw3000Stats::bringups), 2u);
  f.expectRecovered(3);
}

TEST(Dw3000Faults, PllLockFailureAtStartupIsRetriedThenRecovered) {
  Rig rig;
  rig.addAnchor(7, 0x0007, 4.0);
  rig.chip.injectPllLockFailures(1);
  Dw3000Source source(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  CollectingSink sink;
  EXPECT_EQ(rig.run(source, sink, 500 * kMs), SourceEnd::kStopped);
  EXPECT_EQ(Dw3000Stats::get(source.stats().pll_lock_failures), 1u);
  EXPECT_EQ(Dw3000Stats::get(source.stats().bringups), 1u);
  ASSERT_EQ(sink.faults.size(), 1u);
  EXPECT_NE(sink.faults[0].what.find("bring-up failed"), std::string::npos);
  EXPECT_NE(sink.faults[0].what.find("CP_LOCK"), std::string::npos);
  EXPECT_GE(sink.ranges.size(), 3u);
}

TEST(Dw3000Faults, StartupGivesUpWithAFatalFault) {
  Rig rig;
  rig.addAnchor(7, 0x0007, 4.0);
  rig.chip.setDevId(0xFFFFFFFF);  // nothing on the bus
  Dw3000Source source(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  CollectingSink sink;
  EXPECT_EQ(rig.run(source, sink, 10'000 * kMs), SourceEnd::kFailed);
  ASSERT_EQ(sink.faults.size(), 4u);  // three attempts + the fatal one
  for (int i = 0; i < 3; ++i) EXPECT_FALSE(sink.faults[static_cast<std::size_t>(i)].fatal);
  EXPECT_TRUE(sink.faults[3].fatal);
  EXPECT_NE(sink.faults[3].what.find("giving up after 3 bring-up attempt(s)"), std::string::npos);
  EXPECT_NE(sink.faults[3].what.find("DEV_ID reads 0xFFFFFFFF"), std::string::npos) << sink.faults[3].what;
  EXPECT_TRUE(sink.ranges.empty());
}

TEST(Dw3000Faults, ReinitGivesUpAfterTheConfiguredFailures) {
  FaultRun f;
  f.rig.config.max_reinit_failures = 2;
  EXPECT_EQ(f.run([&] {
    f.rig.chip.injectPllLossOfLock();
    f.rig.chip.injectPllLockFailures(100);
  }),
            SourceEnd::kFailed);
  ASSERT_FALSE(f.sink.faults.empty());
  EXPECT_TRUE(f.sink.faults.back().fatal);
  EXPECT_NE(f.sink.faults.back().what.find("giving up after 2 failed re-initializations"), std::string::npos);
}

}  // namespace
}  // namespace rilo::dw3000
