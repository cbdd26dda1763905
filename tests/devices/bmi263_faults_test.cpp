// Every injected fault ends in the documented behaviour: transparent retry,
// counted SourceFault with the sample lost, re-bring-up after repeated
// failures, fatal SourceFault only when recovery is exhausted. Never a crash.
#include <gtest/gtest.h>

#include <system_error>

#include "bmi263_test_util.h"
#include "hal/bmi263/bmi263_registers.h"

namespace rilo::bmi263 {
namespace {

using testing::RecordingSink;
using testing::Rig;

const std::error_code kNack = std::make_error_code(std::errc::no_such_device_or_address);  // ENXIO
const std::error_code kRemoteIo{121, std::system_category()};                              // EREMOTEIO
const std::error_code kTimeout = std::make_error_code(std::errc::timed_out);

TEST(Bmi263Faults, SingleNackIsRetriedTransparently) {
  Rig rig;
  rig.clock.schedule(rig.clock.nowNs() + 500'000'000,
                     [&] { rig.emulator->failNextOnRegister(reg::kAccDataX, 1, kRemoteIo); });
  RecordingSink sink;
  rig.runFor(1'000'000'000, sink);
  EXPECT_TRUE(sink.faults.empty()) << sink.allFaults();
  const Bmi263Counters c = rig.source->counters();
  EXPECT_EQ(c.i2c_retries, 1u);
  EXPECT_EQ(c.i2c_failures, 0u);
  EXPECT_EQ(c.missed_samples, 0u);
}

TEST(Bmi263Faults, ReadFailingBeyondRetriesIsReportedAndTheSampleCountedLost) {
  Rig rig;
  rig.clock.schedule(rig.clock.nowNs() + 500'000'000,
                     [&] { rig.emulator->failNextOnRegister(reg::kAccDataX, 4, kTimeout); });  // 1 + 3 retries
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(1'000'000'000, sink), SourceEnd::kStopped);
  const Bmi263Counters c = rig.source->counters();
  EXPECT_EQ(c.i2c_retries, 3u);
  EXPECT_EQ(c.i2c_failures, 1u);
  EXPECT_EQ(c.missed_samples, 1u);  // the next read sees a SENSORTIME step of two periods
  ASSERT_EQ(sink.faults.size(), 2u) << sink.allFaults();
  EXPECT_EQ(sink.faults[0].device, "emu:bmi263@0x68");
  EXPECT_FALSE(sink.faults[0].fatal);
  EXPECT_NE(sink.faults[0].what.find("I2C read of 15 bytes at reg 0x0C failed after 4 attempts: Connection timed out"),
            std::string::npos)
      << sink.faults[0].what;
  EXPECT_NE(sink.faults[1].what.find("missed 1 sample"), std::string::npos);
  EXPECT_EQ(c.recoveries, 0u);
}

TEST(Bmi263Faults, PersistentReadFailuresLeadToAReBringUpAndDataResumes) {
  Rig rig;
  // 10 reads x 4 attempts fail: the source re-initialises the part.
  rig.clock.schedule(rig.clock.nowNs() + 500'000'000,
                     [&] { rig.emulator->failNextOnRegister(reg::kAccDataX, 40, kRemoteIo); });
  RecordingSink sink;
  std::int64_t last_t = 0;
  sink.on_sample = [&](const ImuSample& s) { last_t = s.t_ns; };
  const std::int64_t t0 = rig.clock.nowNs();
  EXPECT_EQ(rig.runFor(2'000'000'000, sink), SourceEnd::kStopped);
  const Bmi263Counters c = rig.source->counters();
  EXPECT_EQ(c.i2c_failures, 10u);
  EXPECT_EQ(c.recoveries, 1u);
  EXPECT_EQ(c.bring_ups, 2u);
  EXPECT_EQ(rig.emulator->softResets(), 2u);
  EXPECT_TRUE(sink.hasFault("10 reads failed in a row: re-initialising the BMI263")) << sink.allFaults();
  // Each start-up is told for the log, the second as a re-initialization.
  ASSERT_EQ(sink.notes.size(), 2u);
  EXPECT_EQ(sink.notes[0].what.rfind("started: chip id 0x24", 0), 0u) << sink.notes[0].what;
  EXPECT_EQ(sink.notes[1].what.rfind("re-initialized: chip id 0x24", 0), 0u) << sink.notes[1].what;
  EXPECT_EQ(sink.notes[1].device, sink.notes[0].device);
  for (const auto& f : sink.faults) EXPECT_FALSE(f.fatal);
  EXPECT_GT(last_t, t0 + 1'900'000'000);  // samples again until the end
}

TEST(Bmi263Faults, NacksDuringBringUpAreRetried) {
  Rig rig;
  rig.emulator->failNextOnRegister(reg::kInitData, 2, kNack);
  rig.emulator->failNextOnRegister(reg::kChipId, 1, kRemoteIo);
  RecordingSink sink;
  rig.runFor(500'000'000, sink);
  EXPECT_TRUE(sink.faults.empty()) << sink.allFaults();
  EXPECT_EQ(rig.source->counters().i2c_retries, 3u);  // two on INIT_DATA, one on CHIP_ID
  EXPECT_EQ(rig.source->counters().bring_ups, 1u);
  EXPECT_GT(sink.count, 200u);
}

TEST(Bmi263Faults, DeadBusEndsInAFatalFaultAfterTheConfiguredAttempts) {
  Rig rig;
  rig.emulator->failTransactions(0, 1'000'000, kNack);
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(10'000'000'000, sink), SourceEnd::kFailed);
  ASSERT_EQ(sink.faults.size(), 3u) << sink.allFaults();
  EXPECT_TRUE(sink.faults.back().fatal);
  EXPECT_NE(sink.faults.back().what.find("bring-up failed 3 times, giving up"), std::string::npos);
  EXPECT_NE(sink.faults.back().what.find("reading CHIP_ID: I2C read of 1 byte at reg 0x00 failed after 4 attempts"),
            std::string::npos)
      << sink.faults.back().what;
}

TEST(Bmi263Faults, BrownOutStopsInterruptsAndTheSourceRecovers) {
  Rig rig;
  rig.clock.schedule(rig.clock.nowNs() + 1'000'000'000, [&] { rig.emulator->brownOut(); });
  RecordingSink sink;
  std::int64_t last_t = 0;
  sink.on_sample = [&](const ImuSample& s) { last_t = s.t_ns; };
  const std::int64_t t0 = rig.clock.nowNs();
  EXPECT_EQ(rig.runFor(3'000'000'000, sink), SourceEnd::kStopped);
  const Bmi263Counters c = rig.source->counters();
  EXPECT_EQ(c.irq_timeouts, 5u);  // max_consecutive_irq_timeouts
  EXPECT_EQ(c.recoveries, 1u);
  EXPECT_EQ(c.bring_ups, 2u);
  EXPECT_EQ(c.sensortime_backwards, 0u);  // the time keeping restarted with the part
  EXPECT_TRUE(sink.hasFault("no interrupt for 100 ms")) << sink.allFaults();
  EXPECT_TRUE(sink.hasFault("5 interrupt timeouts in a row: re-initialising")) << sink.allFaults();
  EXPECT_GT(last_t, t0 + 2'900'000'000);
  for (const auto& f : sink.faults) EXPECT_FALSE(f.fatal);
}

TEST(Bmi263Faults, InterruptWaitErrorsAreCountedThenFatal) {
  Rig rig;
  rig.clock.schedule(rig.clock.nowNs() + 400'000'000,
                     [&] { rig.irq.failNextWaits(3, std::make_error_code(std::errc::io_error)); });
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(1'000'000'000, sink), SourceEnd::kStopped);
  EXPECT_EQ(rig.source->counters().irq_errors, 3u);
  EXPECT_EQ(sink.faults.size(), 4u) << sink.allFaults();  // 3 errors + the samples missed meanwhile
  EXPECT_TRUE(sink.hasFault("waiting for an interrupt failed: Input/output error (errno 5)"));

  Rig broken;
  broken.clock.schedule(broken.clock.nowNs() + 400'000'000,
                        [&] { broken.irq.failNextWaits(1000, std::make_error_code(std::errc::io_error)); });
  RecordingSink broken_sink;
  EXPECT_EQ(broken.runFor(5'000'000'000, broken_sink), SourceEnd::kFailed);
  EXPECT_EQ(broken.source->counters().irq_errors, 10u);
  ASSERT_FALSE(broken_sink.faults.empty());
  EXPECT_TRUE(broken_sink.faults.back().fatal);
  EXPECT_NE(broken_sink.faults.back().what.find("10 in a row, giving up"), std::string::npos);
}

TEST(Bmi263Faults, FifoOverflowIsReportedAndTheLostFramesCounted) {
  Rig rig;
  rig.config.interrupt_mode = InterruptMode::kFifoWatermark;
  rig.config.irq_error_backoff_ns = 400'000'000;  // a stall long enough to overflow the 2 KB FIFO
  rig.clock.schedule(rig.clock.nowNs() + 500'000'000,
                     [&] { rig.irq.failNextWaits(1, std::make_error_code(std::errc::io_error)); });
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(2'000'000'000, sink), SourceEnd::kStopped);
  const Bmi263Counters c = rig.source->counters();
  EXPECT_EQ(c.fifo_overflows, 1u) << sink.allFaults();
  EXPECT_EQ(c.fifo_frames_lost, rig.emulator->fifoFramesDropped());
  EXPECT_GT(c.fifo_frames_lost, 100u);
  EXPECT_EQ(c.missed_samples, c.fifo_frames_lost);  // the SENSORTIME step says the same
  EXPECT_TRUE(sink.hasFault("FIFO overflow: ")) << sink.allFaults();
  // Data continues, in time order.
  std::int64_t last = 0;
  for (const ImuSample& s : sink.samples) {
    ASSERT_GT(s.t_ns, last);
    last = s.t_ns;
  }
}

}  // namespace
}  // namespace rilo::bmi263
