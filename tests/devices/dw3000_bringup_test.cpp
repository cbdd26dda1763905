#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "devices/dw3000_test_rig.h"
#include "hal/dw3000/dw3000_device.h"
#include "hal/dw3000/registers.h"
#include "hal/dw3000/timestamp.h"

namespace rilo::dw3000 {
namespace {

using testing::Rig;

/// The Dw3000Error thrown by bringUp() (fails the test if none).
Dw3000Error bringUpError(Rig& rig) {
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  try {
    device.bringUp();
  } catch (const Dw3000Error& e) {
    return e;
  }
  ADD_FAILURE() << "bringUp() did not throw";
  return Dw3000Error(Dw3000Error::Kind::kSpi, "");
}

TEST(Dw3000BringUp, ConfiguresTheChipAndRaisesTheSpiClock) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  EXPECT_EQ(device.devId(), kDevIdDw3110);
  EXPECT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdlePll);
  EXPECT_EQ(rig.chip.speedHz(), rig.config.spi_fast_hz);
  EXPECT_EQ(rig.chip.counters().speed_violations, 0u);
  EXPECT_EQ(rig.chip.counters().unsupported, 0u);
  EXPECT_GE(rig.chip.counters().resets, 2u);  // power-on + our reset pulse
  // Channel 5, SFD type 1, preamble code 9 for TX and RX.
  EXPECT_EQ(rig.chip.peek32(0x01, 0x14), 0u | (1u << 1) | (9u << 3) | (9u << 8));
  EXPECT_EQ(rig.chip.peek32(0x01, 0x04) & 0xFFFFu, rig.config.tx_antenna_delay);
  EXPECT_EQ(rig.chip.peek32(0x0E, 0x00) & 0xFFFFu, rig.config.rx_antenna_delay);
  EXPECT_EQ(rig.chip.peek32(0x01, 0x08) & 0xFFFFFu, uwbMicrosecondsFromUs(rig.config.rx_after_tx_delay_us));
  EXPECT_EQ(rig.chip.peek32(0x00, 0x34) & 0xFFFFFu, uwbMicrosecondsFromUs(rig.config.rx_timeout_us));
  EXPECT_NE(rig.chip.peek32(0x00, 0x10) & sys_cfg::kRxWtoe, 0u);
  EXPECT_EQ(rig.chip.peek32(0x00, 0x24) & 0xFC00u, (0x05u << 12) | tx_fctrl::kBr6M8 | tx_fctrl::kRanging);
  EXPECT_EQ(rig.chip.enabledInterrupts(), status::kRxFcg | status::kAllRxErrors | status::kAllRxTimeouts);
  EXPECT_EQ(rig.chip.status() & device.irqMask(), 0u);
  EXPECT_FALSE(rig.irq.level());
  EXPECT_FALSE(device.spiCrcEnabled());
}

TEST(Dw3000BringUp, Channel9AndDw3120) {
  Rig rig;
  rig.config.channel = UwbChannel::k9;
  rig.config.preamble_code = 10;
  rig.addAnchor(1, 0x0001, 3.0);
  rig.chip.setDevId(kDevIdDw3120);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  EXPECT_EQ(device.devId(), kDevIdDw3120);
  EXPECT_EQ(rig.chip.peek32(0x01, 0x14) & 0x7u, 1u | (1u << 1));
  EXPECT_EQ((rig.chip.peek32(0x01, 0x14) >> 8) & 0x1Fu, 10u);
}

TEST(Dw3000BringUp, WrongDevIdNamesTheValueAndThePath) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  rig.chip.setDevId(0xDECA0130);  // a DW1000
  const Dw3000Error e = bringUpError(rig);
  EXPECT_EQ(e.kind(), Dw3000Error::Kind::kWrongDevId);
  const std::string what = e.what();
  EXPECT_NE(what.find("emu:spidev0.0"), std::string::npos) << what;
  EXPECT_NE(what.find("0xDECA0130"), std::string::npos) << what;
  EXPECT_NE(what.find("0xDECA0302"), std::string::npos) << what;
  EXPECT_NE(what.find("0xDECA0312"), std::string::npos) << what;
}

TEST(Dw3000BringUp, NoSpiReadyIsATimeoutWithTheStatusRead) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  rig.chip.setNeverBoots(true);
  const std::int64_t start_ns = rig.clock.nowNs();
  const Dw3000Error e = bringUpError(rig);
  EXPECT_EQ(e.kind(), Dw3000Error::Kind::kBootTimeout);
  const std::string what = e.what();
  EXPECT_NE(what.find("SPIRDY/RCINIT"), std::string::npos) << what;
  EXPECT_NE(what.find("0x00000000"), std::string::npos) << what;
  EXPECT_NE(what.find("emu:spidev0.0"), std::string::npos) << what;
  // It waited (virtual time) for the configured timeout, not forever.
  EXPECT_GE(rig.clock.nowNs() - start_ns, rig.config.boot_timeout_ns);
  EXPECT_LT(rig.clock.nowNs() - start_ns, rig.config.boot_timeout_ns + 5'000'000);
}

TEST(Dw3000BringUp, PllLockFailureIsReported) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  rig.chip.injectPllLockFailures(1);
  const Dw3000Error e = bringUpError(rig);
  EXPECT_EQ(e.kind(), Dw3000Error::Kind::kPllLock);
  const std::string what = e.what();
  EXPECT_NE(what.find("CP_LOCK"), std::string::npos) << what;
  EXPECT_NE(what.find("channel 5"), std::string::npos) << what;
  // The next attempt locks.
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  EXPECT_NO_THROW(device.bringUp());
  EXPECT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdlePll);
}

TEST(Dw3000BringUp, FastClockTheChipCannotFollowIsCaught) {
  emu::Dw3000EmulatorParams params;
  params.max_spi_hz = 10'000'000;
  Rig rig(params);
  rig.addAnchor(1, 0x0001, 3.0);
  rig.config.spi_fast_hz = 16'000'000;
  const Dw3000Error e = bringUpError(rig);
  EXPECT_EQ(e.kind(), Dw3000Error::Kind::kFastSpi);
  EXPECT_NE(std::string(e.what()).find("lower spi_fast_hz"), std::string::npos) << e.what();
}

TEST(Dw3000BringUp, SpiFailureCarriesErrno) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  rig.chip.failNextTransfers(1, std::make_error_code(std::errc::io_error));
  const Dw3000Error e = bringUpError(rig);
  EXPECT_EQ(e.kind(), Dw3000Error::Kind::kSpi);
  const std::string what = e.what();
  EXPECT_NE(what.find(std::make_error_code(std::errc::io_error).message()), std::string::npos) << what;
  EXPECT_NE(what.find("while waiting for SPIRDY/RCINIT"), std::string::npos) << what;
}

TEST(Dw3000BringUp, SpiCrcModeChecksEveryWriteAndRead) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  rig.config.spi_crc = true;
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  EXPECT_TRUE(device.spiCrcEnabled());
  EXPECT_TRUE(rig.chip.spiCrcActive());
  EXPECT_EQ(rig.chip.counters().write_crc_errors, 0u);
  EXPECT_EQ(device.irqMask() & status::kSpiCrcE, status::kSpiCrcE);
  // A corrupted read is detected through SPI_RD_CRC.
  rig.chip.injectReadCrcErrors(1);
  std::uint32_t dev_id = 0;
  EXPECT_EQ(device.read32(reg::kDevId, dev_id), Dw3000Errc::kReadCrcMismatch);
  EXPECT_FALSE(device.read32(reg::kDevId, dev_id));
  EXPECT_EQ(dev_id, kDevIdDw3110);
}

TEST(Dw3000BringUp, SoftResetWithoutAResetLine) {
  Rig rig({}, /*with_reset_line=*/false);
  rig.addAnchor(1, 0x0001, 3.0);
  rig.clock.sleepForNs(10'000'000);  // long after power-on, as when the service starts
  ASSERT_EQ(rig.chip.counters().boots, 1u);
  Dw3000Device device(rig.config, rig.chip, rig.irq, nullptr, rig.clock);
  device.bringUp();
  EXPECT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdlePll);
  EXPECT_EQ(rig.chip.counters().resets, 2u);  // power-on + SOFT_RST
  EXPECT_EQ(rig.chip.counters().boots, 2u);
}

TEST(Dw3000BringUp, SoftResetAgainWithSpiCrcOn) {
  // A re-initialization must soft-reset a chip that still checks CRCs.
  Rig rig({}, /*with_reset_line=*/false);
  rig.addAnchor(1, 0x0001, 3.0);
  rig.config.spi_crc = true;
  rig.clock.sleepForNs(10'000'000);
  Dw3000Device device(rig.config, rig.chip, rig.irq, nullptr, rig.clock);
  device.bringUp();
  ASSERT_TRUE(rig.chip.spiCrcActive());
  device.bringUp();
  EXPECT_EQ(rig.chip.counters().boots, 3u);
  EXPECT_EQ(rig.chip.counters().write_crc_errors, 0u);
  EXPECT_EQ(rig.chip.peek32(0x11, 0x00) & 0xFFFF00u, 0u);  // nothing written past SOFT_RST
  const ExchangeResult r = device.range(rig.config.anchors[0]);
  EXPECT_EQ(r.status, ExchangeStatus::kOk);
}

TEST(Dw3000Emulator, RegisterSemantics) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  // Masked write: (old & AND) | OR.
  ASSERT_FALSE(device.write32(RegAddr{0x01, 0x30}, 0x1234'5678));
  ASSERT_FALSE(device.writeMasked(RegAddr{0x01, 0x30}, AccessMode::kMask16, 0x00FF, 0xAB00));
  EXPECT_EQ(rig.chip.peek32(0x01, 0x30), 0x1234'AB78u);
  ASSERT_FALSE(device.writeMasked(RegAddr{0x01, 0x31}, AccessMode::kMask8, 0x0F, 0x50));
  EXPECT_EQ(rig.chip.peek32(0x01, 0x30), 0x1234'5B78u);
  // DEV_ID is read-only.
  ASSERT_FALSE(device.write32(reg::kDevId, 0));
  std::uint32_t id = 0;
  ASSERT_FALSE(device.read32(reg::kDevId, id));
  EXPECT_EQ(id, kDevIdDw3110);
  // SYS_TIME runs with the device clock.
  std::uint32_t t0 = 0;
  std::uint32_t t1 = 0;
  ASSERT_FALSE(device.read32(reg::kSysTime, t0));
  rig.clock.sleepForNs(1'000'000);
  ASSERT_FALSE(device.read32(reg::kSysTime, t1));
  EXPECT_NEAR(static_cast<double>(t1 - t0), 1e-3 * kDeviceClockHz / 256.0, 2.0);
  // An enabled status bit raises the IRQ; write-1-to-clear drops it.
  ASSERT_FALSE(device.write32(reg::kSysEnable, status::kTxFrs));
  ASSERT_FALSE(device.fastCommand(fast_cmd::kTxW4r));
  rig.clock.sleepForNs(300'000);  // the (empty) poll went out: TXFRS
  EXPECT_NE(rig.chip.status() & status::kTxFrs, 0u);
  EXPECT_TRUE(rig.irq.level());
  ASSERT_FALSE(device.write32(reg::kSysStatus, status::kRxFcg));  // another bit: no effect
  EXPECT_TRUE(rig.irq.level());
  ASSERT_FALSE(device.write32(reg::kSysStatus, status::kTxFrs));
  EXPECT_EQ(rig.chip.status() & status::kTxFrs, 0u);
  EXPECT_FALSE(rig.irq.level());
  EXPECT_EQ(rig.chip.counters().tx_w4r, 1u);
}

TEST(Dw3000Emulator, SpeedAboveSevenMegahertzBeforeIdleIsAViolation) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 3.0);
  // Straight after power-on the chip is in INIT_RC.
  ASSERT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kInitRc);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  ASSERT_FALSE(rig.chip.setSpeedHz(16'000'000));
  std::uint32_t st = 0;
  ASSERT_FALSE(device.read32(reg::kSysStatus, st));
  EXPECT_EQ(rig.chip.counters().speed_violations, 1u);
  EXPECT_EQ(st, 0xFFFF'FFFFu);  // garbage
}

}  // namespace
}  // namespace rilo::dw3000
