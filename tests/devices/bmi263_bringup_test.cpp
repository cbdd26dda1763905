// Bring-up of the BMI263 driver against the emulator: success, and the clear
// failures (wrong blob, wrong chip id, missing or malformed blob file, init
// timeout).
#include <gtest/gtest.h>

#include <string>

#include "bmi263_test_util.h"
#include "hal/bmi263/bmi263_registers.h"

namespace rilo::bmi263 {
namespace {

using testing::RecordingSink;
using testing::Rig;
using testing::TempFile;

TEST(Bmi263BringUp, SucceedsWithTheRightBlobAndConfiguresThePart) {
  Rig rig;
  rig.config.accel_range = AccelRange::k4g;
  rig.config.gyro_range = GyroRange::k500dps;
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(1'000'000'000, sink), SourceEnd::kStopped);
  EXPECT_TRUE(sink.faults.empty()) << sink.allFaults();
  const Bmi263Counters c = rig.source->counters();
  EXPECT_EQ(c.bring_ups, 1u);
  EXPECT_EQ(c.bring_up_failures, 0u);
  EXPECT_TRUE(rig.emulator->measuring());
  EXPECT_EQ(rig.emulator->softResets(), 1u);
  EXPECT_EQ(rig.emulator->initDataBytesReceived(), 8192u);
  EXPECT_EQ(rig.emulator->internalStatus(), internal_status::kInitOk);
  EXPECT_EQ(rig.emulator->registerValue(reg::kAccConf), 0xAB);
  EXPECT_EQ(rig.emulator->registerValue(reg::kAccRange), 1);
  EXPECT_EQ(rig.emulator->registerValue(reg::kGyrConf), 0xEB);
  EXPECT_EQ(rig.emulator->registerValue(reg::kGyrRange), 2);
  EXPECT_EQ(rig.emulator->registerValue(reg::kPwrConf), 0x00);
  EXPECT_EQ(rig.emulator->registerValue(reg::kPwrCtrl), 0x0E);
  EXPECT_EQ(rig.emulator->registerValue(reg::kInt1IoCtrl), 0x0A);
  EXPECT_EQ(rig.emulator->registerValue(reg::kIntMapData), 0x04);
  // About 0.9 s of 800 Hz after ~100 ms of bring-up.
  EXPECT_GT(sink.count, 600u);
  EXPECT_LE(sink.count, 800u);
  EXPECT_EQ(rig.source->describe(), "bmi263 emu:bmi263@0x68 irq emu:gpiochip0:17 (800 Hz, data-ready)");
}

TEST(Bmi263BringUp, SmallUploadBurstsAndSlowBusWork) {
  emu::Bmi263EmulatorConfig emu_config;
  emu_config.bus_ns_per_byte = 22'500;  // 400 kHz
  Rig rig(emu_config);
  rig.config.blob_burst_bytes = 32;
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(1'000'000'000, sink), SourceEnd::kStopped);
  EXPECT_TRUE(sink.faults.empty()) << sink.allFaults();
  EXPECT_EQ(rig.emulator->internalStatus(), internal_status::kInitOk);
  EXPECT_GT(sink.count, 400u);  // the upload alone takes ~0.2 s at 400 kHz
}

TEST(Bmi263BringUp, WrongBlobFailsNamingTheFileAndInternalStatus) {
  Rig rig;
  const TempFile wrong(testing::makeBlob(8192, 99));
  rig.config.config_blob_path = wrong.path();
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(5'000'000'000, sink), SourceEnd::kFailed);
  EXPECT_EQ(sink.count, 0u);
  ASSERT_FALSE(sink.faults.empty());
  const SourceFault& last = sink.faults.back();
  EXPECT_TRUE(last.fatal);
  EXPECT_EQ(last.device, "emu:bmi263@0x68");
  EXPECT_NE(last.what.find("INTERNAL_STATUS 0x02 (init_err)"), std::string::npos) << last.what;
  EXPECT_NE(last.what.find(wrong.path()), std::string::npos) << last.what;
  EXPECT_NE(last.what.find("giving up"), std::string::npos) << last.what;
  // Retried (a load can fail transiently) up to the configured attempts.
  EXPECT_EQ(rig.source->counters().bring_up_failures, 3u);
  EXPECT_EQ(sink.faults.size(), 3u) << sink.allFaults();
  EXPECT_FALSE(sink.faults.front().fatal);
}

TEST(Bmi263BringUp, WrongChipIdFailsAtOnceListingTheAcceptedIds) {
  emu::Bmi263EmulatorConfig emu_config;
  emu_config.chip_id = 0x99;
  Rig rig(emu_config);
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(1'000'000'000, sink), SourceEnd::kFailed);
  ASSERT_EQ(sink.faults.size(), 1u) << sink.allFaults();
  EXPECT_TRUE(sink.faults[0].fatal);
  EXPECT_NE(sink.faults[0].what.find("unexpected CHIP_ID 0x99; accepted: 0x24, 0x27"), std::string::npos)
      << sink.faults[0].what;
  EXPECT_EQ(rig.emulator->softResets(), 0u);

  // The same part is accepted once its id is configured.
  Rig accepted(emu_config);
  accepted.config.accepted_chip_ids = {0x99};
  RecordingSink ok_sink;
  EXPECT_EQ(accepted.runFor(500'000'000, ok_sink), SourceEnd::kStopped);
  EXPECT_TRUE(ok_sink.faults.empty()) << ok_sink.allFaults();
  EXPECT_GT(ok_sink.count, 100u);
}

TEST(Bmi263BringUp, MissingBlobFileFailsBeforeTouchingTheBus) {
  Rig rig;
  rig.config.config_blob_path = "/nonexistent/bmi263_config.bin";
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(1'000'000'000, sink), SourceEnd::kFailed);
  ASSERT_EQ(sink.faults.size(), 1u) << sink.allFaults();
  EXPECT_TRUE(sink.faults[0].fatal);
  EXPECT_NE(sink.faults[0].what.find("'/nonexistent/bmi263_config.bin'"), std::string::npos) << sink.faults[0].what;
  EXPECT_NE(sink.faults[0].what.find("No such file or directory"), std::string::npos) << sink.faults[0].what;
  EXPECT_EQ(rig.emulator->transactionCount(), 0u);
}

TEST(Bmi263BringUp, BlobOfTheWrongSizeIsRejected) {
  Rig rig;
  const TempFile small(testing::makeBlob(100, 1));
  rig.config.config_blob_path = small.path();
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(1'000'000'000, sink), SourceEnd::kFailed);
  ASSERT_EQ(sink.faults.size(), 1u);
  EXPECT_NE(sink.faults[0].what.find("has 100 bytes, expected 8192"), std::string::npos) << sink.faults[0].what;
  const TempFile empty(std::vector<std::uint8_t>{});
  rig.config.config_blob_path = empty.path();
  RecordingSink empty_sink;
  EXPECT_EQ(rig.runFor(1'000'000'000, empty_sink), SourceEnd::kFailed);
  ASSERT_EQ(empty_sink.faults.size(), 1u);
  EXPECT_NE(empty_sink.faults[0].what.find("is empty"), std::string::npos) << empty_sink.faults[0].what;
}

TEST(Bmi263BringUp, InitTimeoutIsReported) {
  emu::Bmi263EmulatorConfig emu_config;
  emu_config.init_duration_ns = 400'000'000;  // the part never gets there within 150 ms
  Rig rig(emu_config);
  rig.config.bring_up_attempts = 1;
  RecordingSink sink;
  EXPECT_EQ(rig.runFor(2'000'000'000, sink), SourceEnd::kFailed);
  ASSERT_EQ(sink.faults.size(), 1u);
  EXPECT_NE(sink.faults[0].what.find("timed out: INTERNAL_STATUS still 0x00 (not_init) 150 ms"), std::string::npos)
      << sink.faults[0].what;
}

TEST(Bmi263BringUp, BadConfigurationThrowsAtConstruction) {
  Rig rig;
  rig.config.blob_burst_bytes = 7;
  EXPECT_THROW(Bmi263Source(*rig.emulator, rig.irq, rig.clock, rig.config), std::invalid_argument);
}

}  // namespace
}  // namespace rilo::bmi263
