// The DW3000 start-up step by step (hal/dw3000/bring_up.h) against the
// emulator's preconditions: every step is needed (a bring-up without it
// fails and names it), the OTP trims are read and applied, the PLL locks only
// the vendor's way, the soft reset behaves as the vendor's code expects.
#include <gtest/gtest.h>

#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <string>

#include "devices/dw3000_test_rig.h"
#include "hal/dw3000/bring_up.h"
#include "hal/dw3000/dw3000_device.h"
#include "hal/dw3000/registers.h"

namespace rilo::dw3000 {
namespace {

using testing::Rig;

/// What the chip does when a bring-up leaves the step out.
enum class Consequence {
  kNoReception,    ///< the receiver cannot take a response (times out)
  kNoDiagnostics,  ///< ranges, but the RX/first-path powers are not logged
  kNoPll,          ///< the PLL never locks: nothing is transmitted
  kNoAnswer,       ///< the poll goes out on the wrong channel / preamble code: no responder answers
  kRanges,         ///< still ranges here (the emulator does not model the RF effect); the audit catches it
};

struct LeftOut {
  BringUpStep step;
  Dw3000Error::Kind kind;
  Consequence consequence;
  const char* receiver_item;  ///< Dw3000Emulator::receiverNotReady() for kNoReception
  const char* register_named; ///< what the message names
};

void PrintTo(const LeftOut& c, std::ostream* os) { *os << stepName(c.step); }

class Dw3000StartUpStep : public ::testing::TestWithParam<LeftOut> {};

TEST_P(Dw3000StartUpStep, ABringUpWithoutItFailsAndNamesIt) {
  const LeftOut& c = GetParam();
  Rig rig;
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.leaveOut(stepBit(c.step));
  try {
    device.bringUp();
    FAIL() << "bringUp() did not throw";
  } catch (const Dw3000Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.kind(), c.kind) << what;
    EXPECT_NE(what.find(std::string("step '") + stepName(c.step) + "'"), std::string::npos) << what;
    EXPECT_NE(what.find("was left out"), std::string::npos) << what;
    EXPECT_NE(what.find(c.register_named), std::string::npos) << what;
    EXPECT_NE(what.find("emu:spidev0.0"), std::string::npos) << what;
  }
  EXPECT_EQ(device.bringUpReport().left_out, stepBit(c.step));

  // What the chip does with that start-up, everything else done: the same
  // bring-up without the audit (a PLL that does not lock still fails it).
  Rig chip_rig;
  chip_rig.config.startup_audit = false;
  chip_rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device unaudited(chip_rig.config, chip_rig.chip, chip_rig.irq, chip_rig.reset_line, chip_rig.clock);
  unaudited.leaveOut(stepBit(c.step));
  try {
    unaudited.bringUp();
    EXPECT_NE(c.step, BringUpStep::kRfPll) << "the PLL cannot lock without its configuration";
  } catch (const Dw3000Error& e) {
    EXPECT_EQ(e.kind(), Dw3000Error::Kind::kPllLock) << e.what();
    EXPECT_EQ(c.step, BringUpStep::kRfPll) << e.what();
  }
  const ExchangeResult r = unaudited.range(chip_rig.config.anchors[0]);
  switch (c.consequence) {
    case Consequence::kNoReception:
      ASSERT_NE(chip_rig.chip.receiverNotReady(), nullptr);
      EXPECT_STREQ(chip_rig.chip.receiverNotReady(), c.receiver_item);
      EXPECT_EQ(r.status, ExchangeStatus::kRxTimeout) << toString(r.status);
      EXPECT_EQ(chip_rig.chip.counters().rx_unconfigured, 1u);
      break;
    case Consequence::kNoDiagnostics:
      ASSERT_EQ(r.status, ExchangeStatus::kOk) << toString(r.status);
      EXPECT_NEAR(r.range_m, 4.0, 0.01);
      EXPECT_TRUE(std::isnan(r.rx_power.rssi_dbm));
      EXPECT_TRUE(std::isnan(r.rx_power.fp_power_dbm));
      break;
    case Consequence::kNoPll:
      EXPECT_EQ(chip_rig.chip.state(), emu::Dw3000Emulator::State::kIdleRc);
      EXPECT_NE(r.status, ExchangeStatus::kOk);
      EXPECT_EQ(chip_rig.chip.counters().tx_while_unlocked, 1u);
      break;
    case Consequence::kNoAnswer:
      EXPECT_NE(r.status, ExchangeStatus::kOk);
      EXPECT_EQ(chip_rig.chip.counters().responses_delivered, 0u);
      break;
    case Consequence::kRanges:
      EXPECT_EQ(chip_rig.chip.receiverNotReady(), nullptr);
      EXPECT_EQ(r.status, ExchangeStatus::kOk) << toString(r.status);
      break;
  }
}

using K = Dw3000Error::Kind;
INSTANTIATE_TEST_SUITE_P(
    EveryStep, Dw3000StartUpStep,
    ::testing::Values(
        LeftOut{BringUpStep::kLdoBiasTrims, K::kConfiguration, Consequence::kNoReception, "LDO and bias trims",
                "LDO_TUNE_LO reads 0x00000000, expected 0x2A6B4C38"},
        LeftOut{BringUpStep::kXtalTrim, K::kConfiguration, Consequence::kRanges, "", "XTAL trim reads 0x00, expected 0x1B"},
        LeftOut{BringUpStep::kFrameFormat, K::kConfiguration, Consequence::kNoAnswer, "", "CHAN_CTRL"},
        LeftOut{BringUpStep::kOpsTable, K::kConfiguration, Consequence::kNoReception, "OPS table",
                "OTP_CFG OPS_ID reads 0x0000, expected 0x1000"},
        LeftOut{BringUpStep::kRxTuning, K::kConfiguration, Consequence::kNoReception, "receiver tuning", "DTUNE0"},
        LeftOut{BringUpStep::kRfPll, K::kPllLock, Consequence::kNoPll, "", "PLL_CFG reads 0x0000, expected 0x1F3C"},
        LeftOut{BringUpStep::kPllLock, K::kConfiguration, Consequence::kNoPll, "", "without AINIT2IDLE"},
        LeftOut{BringUpStep::kDgc, K::kConfiguration, Consequence::kNoReception, "DGC", "DGC_CFG THR_64"},
        LeftOut{BringUpStep::kPgfCalibration, K::kConfiguration, Consequence::kNoReception, "PGF calibration",
                "RX_CAL_RESI/RESQ read 0x1FFFFFFF/0x1FFFFFFF"},
        LeftOut{BringUpStep::kTxRf, K::kConfiguration, Consequence::kRanges, "", "TX_POWER reads 0x00000000"},
        LeftOut{BringUpStep::kCiaDiagnostics, K::kConfiguration, Consequence::kNoDiagnostics, "", "MINDIAG set"},
        LeftOut{BringUpStep::kExchangeTiming, K::kConfiguration, Consequence::kRanges, "", "TX_ANTD"},
        LeftOut{BringUpStep::kInterrupts, K::kConfiguration, Consequence::kRanges, "", "SYS_ENABLE"}),
    [](const ::testing::TestParamInfo<LeftOut>& param_info) {
      std::string name;
      for (const char ch : std::string(stepName(param_info.param.step))) {
        if (std::isalnum(static_cast<unsigned char>(ch))) name += ch;
      }
      return name;
    });

TEST(Dw3000StartUp, WithoutTheAuditAStepLeftOutIsNotCaughtButTheChipStillRefuses) {
  Rig rig;
  rig.config.startup_audit = false;
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.leaveOut(stepBit(BringUpStep::kDgc));
  device.bringUp();
  EXPECT_STREQ(rig.chip.receiverNotReady(), "DGC");
  EXPECT_EQ(device.range(rig.config.anchors[0]).status, ExchangeStatus::kRxTimeout);
}

TEST(Dw3000StartUp, AFullBringUpReportsWhatItReadAndApplied) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  const BringUpReport& r = device.bringUpReport();
  const emu::Dw3000Otp otp;
  EXPECT_TRUE(r.ldo_bias_from_otp);
  EXPECT_EQ(r.otp_ldo_tune_lo, otp.ldo_tune_lo);
  EXPECT_EQ(r.otp_ldo_tune_hi, otp.ldo_tune_hi);
  EXPECT_EQ(r.otp_bias_tune, 0x13);
  EXPECT_EQ(r.otp_part_id, otp.part_id);
  EXPECT_EQ(r.otp_lot_id, otp.lot_id);
  EXPECT_EQ(r.otp_revision, otp.revision);
  EXPECT_TRUE(r.xtal_trim_from_otp);
  EXPECT_EQ(r.xtal_trim, 0x1B);
  EXPECT_GE(r.pll_lock_ns, emu::Dw3000EmulatorParams{}.pll_lock_ns);
  EXPECT_TRUE(r.dgc_on);
  EXPECT_FALSE(r.dgc_from_otp);
  EXPECT_TRUE(r.pgf_done);
  EXPECT_EQ(r.pgf_result_i, emu::Dw3000EmulatorParams{}.pgf_result_i);
  EXPECT_EQ(r.pgf_result_q, emu::Dw3000EmulatorParams{}.pgf_result_q);
  EXPECT_EQ(r.left_out, 0u);
  // The trims are in the chip, the tables loaded, the receiver ready.
  EXPECT_EQ(rig.chip.peek32(0x07, 0x40), otp.ldo_tune_lo);  // LDO_TUNE_LO, loaded by the kick
  EXPECT_EQ(rig.chip.peek32(0x11, 0x1F) & 0x1Fu, 0x13u);     // BIAS_CTRL
  EXPECT_EQ(rig.chip.peek32(0x09, 0x14) & 0x7Fu, 0x1Bu);     // XTAL
  EXPECT_EQ(rig.chip.peek32(0x03, 0x38), startup::kDgcLutCh5[0]);
  EXPECT_EQ(rig.chip.peek32(0x01, 0x0C), rig.config.tx_power);
  EXPECT_EQ(rig.chip.peek32(0x0E, 0x00) & startup::kCiaMinDiag, 0u);
  EXPECT_EQ(rig.chip.receiverNotReady(), nullptr);
  EXPECT_EQ(rig.chip.counters().pgf_calibrations, 1u);
  const std::string text = describe(r);
  EXPECT_NE(text.find("XTAL trim 0x1B from OTP"), std::string::npos) << text;
  EXPECT_NE(text.find("PGF calibration done"), std::string::npos) << text;
  EXPECT_NE(text.find("part 0x1C0A2B17, lot 0x0004F3E1, OTP revision 0x02"), std::string::npos) << text;
  const ExchangeResult range = device.range(rig.config.anchors[0]);
  ASSERT_EQ(range.status, ExchangeStatus::kOk) << toString(range.status);
  EXPECT_TRUE(std::isfinite(range.rx_power.rssi_dbm));
}

TEST(Dw3000StartUp, AnUnprogrammedOtpKeepsTheChipsDefaultsAndTheApisXtalTrim) {
  emu::Dw3000EmulatorParams params;
  params.otp.ldo_tune_lo = 0;  // one word missing: the API applies none of the three
  params.otp.xtal_trim = 0;
  Rig rig(params);
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  const BringUpReport& r = device.bringUpReport();
  EXPECT_FALSE(r.ldo_bias_from_otp);
  EXPECT_FALSE(r.xtal_trim_from_otp);
  EXPECT_EQ(r.xtal_trim, otp::kDefaultXtalTrim);
  EXPECT_EQ(rig.chip.peek32(0x09, 0x14) & 0x7Fu, 0x2Eu);
  EXPECT_EQ(rig.chip.peek32(0x07, 0x44), 0u);  // no LDO kick
  EXPECT_NE(describe(r).find("chip defaults (OTP words not programmed)"), std::string::npos);
  EXPECT_NE(describe(r).find("(default: OTP empty)"), std::string::npos);
  EXPECT_EQ(device.range(rig.config.anchors[0]).status, ExchangeStatus::kOk);
}

TEST(Dw3000StartUp, ADgcTableInOtpIsKickedInsteadOfWritten) {
  for (const UwbChannel channel : {UwbChannel::k5, UwbChannel::k9}) {
    SCOPED_TRACE(static_cast<int>(channel));
    emu::Dw3000EmulatorParams params;
    params.otp.dgc_table = true;
    Rig rig(params);
    rig.config.channel = channel;
    rig.addAnchor(1, 0x0001, 4.0);
    Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
    device.bringUp();
    EXPECT_TRUE(device.bringUpReport().dgc_from_otp);
    EXPECT_TRUE(device.bringUpReport().dgc_on);
    // The part's own table for the channel, not the API's.
    const std::size_t first = channel == UwbChannel::k9 ? 7 : 0;
    EXPECT_EQ(rig.chip.peek32(0x03, 0x38), params.otp.dgc_lut[first]);
    EXPECT_EQ(rig.chip.peek32(0x03, 0x50), params.otp.dgc_lut[first + 6]);
    EXPECT_NE(rig.chip.peek32(0x03, 0x38), startup::kDgcLutCh5[0]);
    EXPECT_EQ(device.range(rig.config.anchors[0]).status, ExchangeStatus::kOk);
  }
}

TEST(Dw3000StartUp, TheSitesWritesOverrideTheVendorsStepsWithoutFailingTheAudit) {
  Rig rig;
  rig.config.extra_init_writes.push_back(RegisterWrite{reg::kTxPower, 0xFEFEFEFE, 4});  // a board's TX power
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  EXPECT_EQ(rig.chip.peek32(0x01, 0x0C), 0xFEFEFEFEu);
  EXPECT_EQ(device.range(rig.config.anchors[0]).status, ExchangeStatus::kOk);
}

TEST(Dw3000StartUp, ASoftResetGetsThroughAChipLeftInSpiCrcModeByAnotherProcess) {
  Rig rig(emu::Dw3000EmulatorParams{}, /*with_reset_line=*/false);
  rig.config.spi_crc = true;
  rig.addAnchor(1, 0x0001, 4.0);
  {
    Dw3000Device earlier(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
    earlier.bringUp();
    ASSERT_TRUE(rig.chip.spiCrcActive());
  }  // that process ended without resetting the chip
  for (const bool crc : {true, false}) {
    SCOPED_TRACE(crc);
    Dw3000Config config = rig.config;
    config.spi_crc = crc;
    Dw3000Device device(config, rig.chip, rig.irq, rig.reset_line, rig.clock);  // knows nothing of the CRC mode
    device.bringUp();
    EXPECT_EQ(rig.chip.spiCrcActive(), crc);
    EXPECT_EQ(device.range(config.anchors[0]).status, ExchangeStatus::kOk);
  }
  EXPECT_GE(rig.chip.counters().write_crc_errors, 1u);  // the first soft reset's writes were dropped
}

TEST(Dw3000StartUp, TheLongOpsSetLooksLikeTheResetValueSoOnlyTheReceiverShowsItMissing) {
  // OPS_ID 0 (the long set, preambles of 256 symbols and more) is also the
  // register's reset value: the audit cannot tell the kick was left out.
  for (const bool left_out : {false, true}) {
    SCOPED_TRACE(left_out);
    Rig rig;
    rig.config.preamble_length = 256;
    rig.config.pac_symbols = 16;
    rig.config.reply_delay_us = 900.0;  // the longer preamble: the receiver opens and closes later
    rig.config.rx_timeout_us = 900.0;
    rig.addAnchor(1, 0x0001, 4.0);
    Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
    if (left_out) device.leaveOut(stepBit(BringUpStep::kOpsTable));
    device.bringUp();
    const ExchangeResult r = device.range(rig.config.anchors[0]);
    EXPECT_EQ(r.status, left_out ? ExchangeStatus::kRxTimeout : ExchangeStatus::kOk) << toString(r.status);
    if (left_out) {
      EXPECT_STREQ(rig.chip.receiverNotReady(), "OPS table");
    }
  }
}

TEST(Dw3000StartUp, AFailedPgfCalibrationFailsTheBringUpWithItsResult) {
  emu::Dw3000EmulatorParams params;
  params.pgf_result_q = startup::kRxCalFailed;  // the Q channel did not calibrate
  Rig rig(params);
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  try {
    device.bringUp();
    FAIL() << "bringUp() did not throw";
  } catch (const Dw3000Error& e) {
    EXPECT_EQ(e.kind(), Dw3000Error::Kind::kCalibration);
    const std::string what = e.what();
    EXPECT_NE(what.find("PGF calibration failed"), std::string::npos) << what;
    EXPECT_NE(what.find("RX_CAL_RESQ 0x1FFFFFFF"), std::string::npos) << what;
    EXPECT_EQ(what.find("step '"), std::string::npos) << what;  // every earlier step took
  }
  EXPECT_TRUE(device.bringUpReport().pgf_done);
  EXPECT_EQ(device.bringUpReport().pgf_result_q, startup::kRxCalFailed);
}

// --- The emulator's own preconditions, register by register -------------------

TEST(Dw3000StartUp, ThePllLocksOnlyAfterAinit2IdleWithThePllConfiguredAndAutoClocks) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  rig.clock.sleepForNs(5'000'000);  // booted: IDLE_RC
  ASSERT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdleRc);
  const auto settle = [&] { rig.clock.sleepForNs(1'000'000); };
  const auto setAinit2Idle = [&] {
    ASSERT_FALSE(device.writeMasked(RegAddr{0x11, 0x09}, AccessMode::kMask8, 0xFF, 0x01));
  };
  // A channel configuration alone no longer locks (it did in our first emulator).
  ASSERT_FALSE(device.write32(reg::kChanCtrl, 0x094A));
  settle();
  EXPECT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdleRc);
  EXPECT_EQ(rig.chip.status() & status::kCpLock, 0u);
  // AINIT2IDLE without PLL_CFG: refused.
  setAinit2Idle();
  settle();
  EXPECT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdleRc);
  EXPECT_EQ(rig.chip.counters().pll_refusals, 1u);
  // PLL_CFG for channel 5 but the system clock forced to FOSC: refused.
  const std::array<std::uint8_t, 2> pll{0x3C, 0x1F};
  ASSERT_FALSE(device.write(reg::kPllCfg, pll));
  ASSERT_FALSE(device.writeMasked(reg::kClkCtrl, AccessMode::kMask8, 0xFF, 0x03));
  setAinit2Idle();
  settle();
  EXPECT_EQ(rig.chip.counters().pll_refusals, 2u);
  // Clocks on auto, then AINIT2IDLE: CP_LOCK, IDLE_PLL.
  ASSERT_FALSE(device.writeMasked(reg::kClkCtrl, AccessMode::kMask8, 0xFC, 0x00));
  setAinit2Idle();
  settle();
  EXPECT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdlePll);
  EXPECT_NE(rig.chip.status() & status::kCpLock, 0u);
}

TEST(Dw3000StartUp, OtpWordsAreReadOnlyWithTheManualModeThenTheStrobe) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  rig.clock.sleepForNs(5'000'000);
  const auto write16 = [&](RegAddr a, std::uint16_t v) {
    const std::array<std::uint8_t, 2> b{static_cast<std::uint8_t>(v & 0xFF), static_cast<std::uint8_t>(v >> 8)};
    ASSERT_FALSE(device.write(a, b));
  };
  std::uint32_t word = 0;
  // The strobe without the manual mode first reads nothing.
  write16(reg::kOtpAddr, otp::kXtalTrim);
  write16(reg::kOtpCfg, 0x0002);
  ASSERT_FALSE(device.read32(reg::kOtpRdata, word));
  EXPECT_EQ(word, 0u);
  write16(reg::kOtpCfg, 0x0001);
  write16(reg::kOtpAddr, otp::kXtalTrim);
  write16(reg::kOtpCfg, 0x0002);
  ASSERT_FALSE(device.read32(reg::kOtpRdata, word));
  EXPECT_EQ(word, 0x1Bu);
  EXPECT_EQ(rig.chip.counters().otp_reads, 1u);
}

TEST(Dw3000StartUp, ASoftResetWithTheClockOnThePllHangsTheChipUntilTheResetLine) {
  Rig rig;  // with a reset line
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  ASSERT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdlePll);
  // SOFT_RST without forcing FOSC first (what dwt_softreset does before it).
  const std::uint8_t reset_all = 0x00;
  ASSERT_FALSE(device.write(reg::kSoftRst, {&reset_all, 1}));
  rig.clock.sleepForNs(20'000'000);
  EXPECT_EQ(rig.chip.counters().soft_reset_hangs, 1u);
  EXPECT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kInitRc);  // never boots
  // The reset line brings it back; the bring-up uses it.
  device.bringUp();
  EXPECT_EQ(rig.chip.state(), emu::Dw3000Emulator::State::kIdlePll);
  EXPECT_EQ(device.range(rig.config.anchors[0]).status, ExchangeStatus::kOk);
}

TEST(Dw3000StartUp, TheApisSoftResetRebootsAfterOneWriteEvenWithThePllLocked) {
  Rig rig(emu::Dw3000EmulatorParams{}, /*with_reset_line=*/false);
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();
  const std::uint64_t boots = rig.chip.counters().boots;
  device.bringUp();  // soft reset from IDLE_PLL: FOSC forced first, SOFT_RST once
  EXPECT_EQ(rig.chip.counters().boots, boots + 1);
  EXPECT_EQ(rig.chip.counters().soft_reset_hangs, 0u);
  EXPECT_EQ(device.range(rig.config.anchors[0]).status, ExchangeStatus::kOk);
}

TEST(Dw3000StartUp, WithoutTheResetStepTheChipNeverReportsIdleRc) {
  Rig rig;
  rig.addAnchor(1, 0x0001, 4.0);
  Dw3000Device device(rig.config, rig.chip, rig.irq, rig.reset_line, rig.clock);
  device.bringUp();  // SPIRDY/RCINIT cleared since
  device.leaveOut(stepBit(BringUpStep::kReset));
  try {
    device.bringUp();
    FAIL() << "bringUp() did not throw";
  } catch (const Dw3000Error& e) {
    EXPECT_EQ(e.kind(), Dw3000Error::Kind::kBootTimeout);
    const std::string what = e.what();
    EXPECT_NE(what.find("step 'reset'"), std::string::npos) << what;
    EXPECT_NE(what.find("was left out"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace rilo::dw3000
