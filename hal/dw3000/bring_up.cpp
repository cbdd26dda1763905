// The DW3000 start-up, step by step (bring_up.h). The order and the values
// follow Qorvo's public C0 API v04.00.00 (deca_device.c / deca_regs.h /
// deca_vals.h); our own code. Each apply* below names the API function it
// follows; auditStep() says how the step shows in the registers afterwards.
#include <algorithm>
#include <array>
#include <cstdio>

#include "hal/dw3000/dw3000_device.h"
#include "hal/dw3000/registers.h"
#include "hal/dw3000/text.h"
#include "hal/dw3000/timestamp.h"

namespace rilo::dw3000 {
namespace {

std::string mismatch(const char* what, std::uint32_t read, std::uint32_t expected, std::string (*hex)(std::uint32_t)) {
  return std::string(what) + " reads " + hex(read) + ", expected " + hex(expected);
}

const std::uint32_t* dgcLut(UwbChannel channel) {
  return channel == UwbChannel::k9 ? startup::kDgcLutCh9 : startup::kDgcLutCh5;
}

// The API kicks the long operating-parameter set for preambles of 256
// symbols and more (counting the STS, which we leave off), the short one below.
std::uint32_t opsSet(const Dw3000Config& c) { return c.preamble_length >= 256 ? otp_cfg::kOpsLong : otp_cfg::kOpsShort; }

}  // namespace

const char* stepName(BringUpStep step) noexcept {
  switch (step) {
    case BringUpStep::kReset: return "reset";
    case BringUpStep::kIdleRc: return "IDLE_RC";
    case BringUpStep::kDevId: return "device id";
    case BringUpStep::kSpiCrc: return "SPI CRC";
    case BringUpStep::kLdoBiasTrims: return "LDO and bias trims";
    case BringUpStep::kXtalTrim: return "crystal trim";
    case BringUpStep::kFrameFormat: return "frame format";
    case BringUpStep::kOpsTable: return "OPS table";
    case BringUpStep::kRxTuning: return "receiver tuning";
    case BringUpStep::kRfPll: return "RF and PLL configuration";
    case BringUpStep::kPllLock: return "PLL lock";
    case BringUpStep::kDgc: return "DGC";
    case BringUpStep::kPgfCalibration: return "PGF calibration";
    case BringUpStep::kTxRf: return "TX power and pulse delay";
    case BringUpStep::kCiaDiagnostics: return "CIA diagnostics";
    case BringUpStep::kSiteWrites: return "extra_init_writes";
    case BringUpStep::kExchangeTiming: return "exchange timing";
    case BringUpStep::kInterrupts: return "interrupts";
    case BringUpStep::kFastSpi: return "fast SPI";
    case BringUpStep::kCount: break;
  }
  return "?";
}

const char* stepReference(BringUpStep step) noexcept {
  switch (step) {
    case BringUpStep::kReset: return "dwt_softreset / reset line";
    case BringUpStep::kIdleRc: return "dwt_checkidlerc";
    case BringUpStep::kDevId: return "dwt_check_dev_id";
    case BringUpStep::kSpiCrc: return "dwt_enablespicrccheck";
    case BringUpStep::kLdoBiasTrims: return "dwt_initialise: _dwt_prog_ldo_and_bias_tune";
    case BringUpStep::kXtalTrim: return "dwt_initialise: XTAL from OTP 0x1E";
    case BringUpStep::kFrameFormat: return "dwt_configure: SYS_CFG, CHAN_CTRL, TX_FCTRL, FINE_PLEN";
    case BringUpStep::kOpsTable: return "dwt_configure: OTP_CFG OPS kick";
    case BringUpStep::kRxTuning: return "dwt_configure: DTUNE0, STS_CFG0, DTUNE3";
    case BringUpStep::kRfPll: return "dwt_configure: TX_CTRL_HI, PLL_CFG, RX_CTRL_HI, LDO_RLOAD, TX_CTRL_LO, PLL_CAL";
    case BringUpStep::kPllLock: return "dwt_configure: dwt_setdwstate(DWT_DW_IDLE), CP_LOCK";
    case BringUpStep::kDgc: return "dwt_configure: dwt_configmrxlut / DGC kick, DGC_CFG";
    case BringUpStep::kPgfCalibration: return "dwt_pgf_cal";
    case BringUpStep::kTxRf: return "dwt_configuretxrf";
    case BringUpStep::kCiaDiagnostics: return "dwt_configciadiag(DW_CIA_DIAG_LOG_ALL)";
    case BringUpStep::kSiteWrites: return "rilo: site override";
    case BringUpStep::kExchangeTiming: return "rilo: dwt_settxantennadelay, dwt_setrxantennadelay, W4R, RX_FWTO";
    case BringUpStep::kInterrupts: return "rilo: SYS_ENABLE";
    case BringUpStep::kFastSpi: return "rilo: SPI clock";
    case BringUpStep::kCount: break;
  }
  return "?";
}

std::string describe(const BringUpReport& r) {
  std::string s;
  if (r.ldo_bias_from_otp) {
    s += "LDO trims " + hex32(r.otp_ldo_tune_lo) + "/" + hex32(r.otp_ldo_tune_hi) + " and bias " +
         hex8(r.otp_bias_tune) + " from OTP";
  } else {
    s += "LDO/bias: chip defaults (OTP words not programmed)";
  }
  s += "; XTAL trim " + hex8(r.xtal_trim) + (r.xtal_trim_from_otp ? " from OTP" : " (default: OTP empty)");
  s += "; PLL lock " + (r.pll_lock_ns >= 0 ? std::to_string(r.pll_lock_ns / 1000) + " us" : std::string("none"));
  s += "; DGC " + std::string(r.dgc_on ? (r.dgc_from_otp ? "on (table from OTP)" : "on (driver's table)") : "off");
  s += "; PGF calibration " + std::string(r.pgf_done ? "done" : "not done") + " (I " + hex32(r.pgf_result_i) + ", Q " +
       hex32(r.pgf_result_q) + ")";
  s += "; part " + hex32(r.otp_part_id) + ", lot " + hex32(r.otp_lot_id) + ", OTP revision " + hex8(r.otp_revision);
  if (r.left_out != 0) s += "; steps left out: " + hex32(r.left_out);
  return s;
}

// ---------------------------------------------------------------------------
// Register helpers


std::uint32_t Dw3000Device::readReg32(RegAddr addr, const char* what) {
  std::uint32_t v = 0;
  check(read32(addr, v), what);
  return v;
}

std::uint8_t Dw3000Device::readReg8(RegAddr addr, const char* what) {
  std::uint8_t v = 0;
  check(read(addr, {&v, 1}), what);
  return v;
}

std::uint32_t Dw3000Device::otpRead(std::uint16_t address, const char* what) {
  // _dwt_otpread: manual mode, the word address, the read strobe, then RDATA.
  check(write16(reg::kOtpCfg, static_cast<std::uint16_t>(otp_cfg::kManualEnable)), what);
  check(write16(reg::kOtpAddr, address), what);
  check(write16(reg::kOtpCfg, static_cast<std::uint16_t>(otp_cfg::kRead)), what);
  return readReg32(reg::kOtpRdata, what);
}

// ---------------------------------------------------------------------------
// The sequence

void Dw3000Device::bringUp() {
  dev_id_ = 0;
  irq_mask_ = 0;
  dgc_enabled_ = false;
  report_ = {};
  report_.left_out = left_out_;
  if (const std::error_code e = spi_.setSpeedHz(config_.spi_slow_hz)) {
    fail(Dw3000Error::Kind::kSpi, "cannot set the slow SPI clock (" + std::to_string(config_.spi_slow_hz) +
                                      " Hz): " + e.message());
  }
  // The audit: every configuration step must show in the registers, whether
  // it was left out, or its writes were lost (SPI), or a later step undid it.
  // The vendor's steps are audited before the site's writes, which may
  // override any of them on purpose; ours after everything.
  const auto audit = [&](BringUpStep from, BringUpStep to) {
    const std::string not_in_effect = firstStepNotInEffect(from, to);
    if (!not_in_effect.empty()) fail(Dw3000Error::Kind::kConfiguration, "bring-up incomplete" + not_in_effect);
  };
  for (int i = 0; i < static_cast<int>(BringUpStep::kCount); ++i) {
    const auto step = static_cast<BringUpStep>(i);
    if (step == BringUpStep::kSiteWrites) audit(BringUpStep::kReset, BringUpStep::kSiteWrites);
    runStep(step);
  }
  audit(BringUpStep::kSiteWrites, BringUpStep::kCount);
  // The DGC decision enters the RX power estimate when RX_TUNE_EN is on
  // (read after every step, the site's writes included).
  dgc_enabled_ = (readReg32(reg::kDgcCfg, "reading DGC_CFG") & startup::kDgcRxTuneEn) != 0;
  report_.dgc_on = dgc_enabled_;
  if (const std::error_code drain_error = drainEdges()) {
    fail(Dw3000Error::Kind::kIrqStuck, "cannot read IRQ line " + irq_.path() + ": " + drain_error.message());
  }
}

void Dw3000Device::runStep(BringUpStep step) {
  const bool mandatory = step == BringUpStep::kIdleRc || step == BringUpStep::kDevId;
  const bool left_out = !mandatory && (left_out_ & stepBit(step)) != 0;
  // The OTP reads around the LDO/bias kick happen even when the step is left
  // out: they are how the driver learns the part, and later steps use them.
  if (left_out && step != BringUpStep::kLdoBiasTrims) return;
  switch (step) {
    case BringUpStep::kReset:
      resetChip();
      crc_enabled_ = false;  // every reset turns the chip's SPI CRC off
      break;
    case BringUpStep::kIdleRc: {
      // RCINIT alone, as dwt_checkidlerc tests it (SPIRDY comes with it).
      const std::uint32_t ready = status::kRcInit;
      std::uint32_t boot_status = waitStatus(ready, config_.boot_timeout_ns, "waiting for SPIRDY/RCINIT");
      if ((boot_status & ready) != ready && reset_ == nullptr && (left_out_ & stepBit(BringUpStep::kReset)) == 0) {
        // A soft reset speaks the SPI CRC mode the chip is in, which another
        // process (or a crash) may have left on: its writes were dropped.
        // Once more in the other mode.
        crc_enabled_ = !soft_reset_crc_;
        softReset();
        boot_status = waitStatus(ready, config_.boot_timeout_ns, "waiting for SPIRDY/RCINIT");
      }
      if ((boot_status & ready) != ready) {
        fail(Dw3000Error::Kind::kBootTimeout,
             "no SPIRDY/RCINIT within " + msText(config_.boot_timeout_ns) + " after reset (SYS_STATUS reads " +
                 hex32(boot_status) + "): check power, the reset line and the SPI wiring (mode 0)" +
                 ((left_out_ & stepBit(BringUpStep::kReset)) != 0
                      ? std::string("; step 'reset' (") + stepReference(BringUpStep::kReset) + ") was left out"
                      : std::string()));
      }
      break;
    }
    case BringUpStep::kDevId:
      check(read32(reg::kDevId, dev_id_), "reading DEV_ID");
      if (dev_id_ != kDevIdDw3110 && dev_id_ != kDevIdDw3120) {
        fail(Dw3000Error::Kind::kWrongDevId, "DEV_ID reads " + hex32(dev_id_) + ", expected " +
                                                 hex32(kDevIdDw3110) + " (DW3110) or " + hex32(kDevIdDw3120) +
                                                 " (DW3120): wrong device, wiring or SPI mode");
      }
      check(clearAllStatus(), "clearing SYS_STATUS");
      break;
    case BringUpStep::kSpiCrc:
      if (config_.spi_crc) {
        // This write itself carries no CRC; everything after it does.
        check(writeMasked(reg::kSysCfg, AccessMode::kMask8, 0xFF, sys_cfg::kSpiCrc), "enabling SPI CRC");
        crc_enabled_ = true;
        const std::uint32_t sys_cfg = readReg32(reg::kSysCfg, "reading SYS_CFG back");
        if ((sys_cfg & sys_cfg::kSpiCrc) == 0) {
          fail(Dw3000Error::Kind::kSpiCrc, "SYS_CFG reads " + hex32(sys_cfg) + " after enabling SPI CRC");
        }
      }
      break;
    case BringUpStep::kLdoBiasTrims:
      // dwt_initialise's OTP reads, in its order around the kick (the reads
      // after it leave OTP_CFG's kick bits cleared).
      readOtpTrimWords();
      if (!left_out) applyOtpTrims();
      readOtpOtherWords();
      break;
    case BringUpStep::kXtalTrim: applyXtalTrim(); break;
    case BringUpStep::kFrameFormat: applyFrameFormat(); break;
    case BringUpStep::kOpsTable: applyOpsTable(); break;
    case BringUpStep::kRxTuning: applyRxTuning(); break;
    case BringUpStep::kRfPll: applyRfPll(); break;
    case BringUpStep::kPllLock: lockPll(); break;
    case BringUpStep::kDgc: applyDgc(); break;
    case BringUpStep::kPgfCalibration: calibratePgf(); break;
    case BringUpStep::kTxRf: applyTxRf(); break;
    case BringUpStep::kCiaDiagnostics: applyCiaDiagnostics(); break;
    case BringUpStep::kSiteWrites: applySiteWrites(); break;
    case BringUpStep::kExchangeTiming: applyExchangeTiming(); break;
    case BringUpStep::kInterrupts: applyInterrupts(); break;
    case BringUpStep::kFastSpi: raiseSpiClock(); break;
    case BringUpStep::kCount: break;
  }
}

// --- Reset -------------------------------------------------------------------

void Dw3000Device::resetChip() {
  if (reset_ != nullptr) {
    if (const std::error_code e = reset_->set(false)) {
      fail(Dw3000Error::Kind::kSpi, "cannot drive reset line " + reset_->path() + " low: " + e.message());
    }
    clock_.sleepForNs(config_.reset_low_ns);
    if (const std::error_code e = reset_->set(true)) {
      fail(Dw3000Error::Kind::kSpi, "cannot release reset line " + reset_->path() + ": " + e.message());
    }
    return;
  }
  softReset();
}

void Dw3000Device::softReset() {
  // dwt_softreset. A soft reset still speaks the CRC mode of the last
  // bring-up, so these writes carry it; the SPI must be <= 7 MHz (the chip
  // runs on FOSC/4 while it resets).
  // Clear the AON configuration: a reset triggers the AON download, which
  // would otherwise bring back a stale wake-up configuration.
  check(write16(reg::kAonDigCfg, 0x0000), "soft reset: clearing AON_DIG_CFG");
  check(write8(reg::kAnaCfg, 0x00), "soft reset: clearing ANA_CFG");
  check(write8(reg::kAonCtrl, 0x00), "soft reset: clearing AON_CTRL");
  check(write8(reg::kAonCtrl, 0x02), "soft reset: AON_CTRL ARRAY_SAVE");
  clock_.sleepForNs(1'000'000);
  // The system clock must not be the PLL: the reset switches the PLL off.
  check(writeMasked(reg::kClkCtrl, AccessMode::kMask8, 0xFF, startup::kForceSysClkFosc),
        "soft reset: forcing the FOSC clock (CLK_CTRL)");
  soft_reset_crc_ = crc_enabled_;
  check(write8(reg::kSoftRst, 0x00), "soft reset: SOFT_RST (reset all)");
  crc_enabled_ = false;
  clock_.sleepForNs(config_.reset_low_ns);
}

// --- dwt_initialise: OTP trims -------------------------------------------------

void Dw3000Device::readOtpTrimWords() {
  report_.otp_ldo_tune_lo = otpRead(otp::kLdoTuneLo, "reading OTP LDO_TUNE_LO");
  report_.otp_ldo_tune_hi = otpRead(otp::kLdoTuneHi, "reading OTP LDO_TUNE_HI");
  report_.otp_bias_tune = static_cast<std::uint8_t>((otpRead(otp::kBiasTune, "reading OTP BIAS_TUNE") >> 16) & 0x1Fu);
  // The API applies the LDO and bias trims only when all three words are
  // programmed.
  report_.ldo_bias_from_otp =
      report_.otp_ldo_tune_lo != 0 && report_.otp_ldo_tune_hi != 0 && report_.otp_bias_tune != 0;
}

void Dw3000Device::readOtpOtherWords() {
  // The DGC word (dwt_initialise reads it too: the table is kicked later),
  // the ids (ours, for the report; DWT_DW_INIT reads none), the revision and
  // the crystal trim. All before any step selects a table in OTP_CFG, which
  // every OTP read rewrites.
  report_.dgc_from_otp = prf64_ && otpRead(otp::kDgcTune, "reading OTP DGC") == startup::kDgcCfg0Value;
  report_.otp_part_id = otpRead(otp::kPartId, "reading OTP PART_ID");
  report_.otp_lot_id = otpRead(otp::kLotId, "reading OTP LOT_ID");
  report_.otp_revision = static_cast<std::uint8_t>(otpRead(otp::kRevision, "reading OTP revision") & 0xFFu);
  const auto trim = static_cast<std::uint8_t>(otpRead(otp::kXtalTrim, "reading OTP XTAL trim") & 0x7Fu);
  report_.xtal_trim_from_otp = trim != 0;
  report_.xtal_trim = trim != 0 ? trim : otp::kDefaultXtalTrim;
}

void Dw3000Device::applyOtpTrims() {
  // The LDO values are loaded by the kick itself; the bias is written.
  if (!report_.ldo_bias_from_otp) return;
  check(writeMasked(reg::kOtpCfg, AccessMode::kMask16, 0xFFFF, otp_cfg::kLdoKick | otp_cfg::kBiasKick),
        "kicking the LDO/bias trims (OTP_CFG)");
  check(writeMasked(reg::kBiasCtrl, AccessMode::kMask16, 0xFFE0, report_.otp_bias_tune), "writing BIAS_CTRL");
}

void Dw3000Device::applyXtalTrim() {
  check(write8(reg::kXtalTrim, report_.xtal_trim), "writing XTAL");
}

// --- dwt_configure ---------------------------------------------------------------

void Dw3000Device::applyFrameFormat() {
  // Channel, preamble codes, SFD; frame wait timeout enable (ours, for
  // RX_FWTO); standard PHR at 850 kb/s, STS off.
  const std::uint32_t chan_ctrl = (config_.channel == UwbChannel::k9 ? 1u : 0u) |
                                  (static_cast<std::uint32_t>(config_.sfd_type) << 1) |
                                  (static_cast<std::uint32_t>(config_.preamble_code) << 3) |
                                  (static_cast<std::uint32_t>(config_.preamble_code) << 8);
  check(writeMasked(reg::kSysCfg, AccessMode::kMask32, ~(sys_cfg::kPhr6M8 | 0x3B010u), sys_cfg::kRxWtoe),
        "writing SYS_CFG");
  check(write32(reg::kChanCtrl, chan_ctrl), "writing CHAN_CTRL");
  const std::uint32_t tx_fctrl = (static_cast<std::uint32_t>(preambleLengthCode(config_.preamble_length))
                                  << tx_fctrl::kPsrShift) |
                                 (config_.data_rate == DataRate::k6M8 ? tx_fctrl::kBr6M8 : 0u) | tx_fctrl::kRanging;
  check(write32(reg::kTxFctrl, tx_fctrl), "writing TX_FCTRL");
  const std::uint8_t fine_plen = config_.preamble_length == 72 ? 8 : 0;  // 72 symbols: TXPSR 64 + FINE_PLEN
  check(write8(reg::kTxFctrlHi.plus(1), fine_plen), "writing FINE_PLEN");
  check(write32(reg::kPanAdr, (static_cast<std::uint32_t>(config_.pan_id) << 16) | config_.tag_address),
        "writing PAN_ADR");
}

void Dw3000Device::applyOpsTable() {
  check(writeMasked(reg::kOtpCfg, AccessMode::kMask32, ~otp_cfg::kOpsIdMask, opsSet(config_) | otp_cfg::kOpsKick),
        "kicking the OPS table (OTP_CFG)");
}

void Dw3000Device::applyRxTuning() {
  check(writeMasked(reg::kDtune0, AccessMode::kMask8, 0xFC, static_cast<std::uint32_t>(pacCode(config_.pac_symbols))),
        "writing DTUNE0 (PAC)");
  // Written with the STS off too, as the API does.
  check(write8(reg::kStsCfg0, startup::kStsCfg0Len64), "writing STS_CFG0");
  check(write32(reg::kDtune3, startup::kDtune3Default), "writing DTUNE3");
  check(write16(reg::kDtune0SfdTimeout, sfdTimeoutSymbols(config_)), "writing DTUNE0 (SFD timeout)");
}

void Dw3000Device::applyRfPll() {
  const bool ch9 = config_.channel == UwbChannel::k9;
  check(write32(reg::kTxCtrlHi, ch9 ? startup::kTxCtrlHiCh9 : startup::kTxCtrlHiCh5), "writing TX_CTRL_HI");
  check(write16(reg::kPllCfg, ch9 ? startup::kPllCfgCh9 : startup::kPllCfgCh5), "writing PLL_CFG");
  if (ch9) check(write32(reg::kRxCtrlHi, startup::kRxCtrlHiCh9), "writing RX_CTRL_HI");
  check(write8(reg::kLdoRload.plus(1), startup::kLdoRloadByte1), "writing LDO_RLOAD");
  check(write8(reg::kTxCtrlLo.plus(2), startup::kTxCtrlLoByte2), "writing TX_CTRL_LO");
  check(write8(reg::kPllCal, startup::kPllCalByte0), "writing PLL_CAL");
}

void Dw3000Device::lockPll() {
  // Clear CP_LOCK, then dwt_setdwstate(DWT_DW_IDLE): clocks to auto and
  // AINIT2IDLE, so the chip calibrates its PLL and moves to IDLE_PLL; only
  // then is CP_LOCK waited for.
  check(write8(reg::kSysStatus, static_cast<std::uint8_t>(status::kCpLock)), "clearing CP_LOCK");
  check(write16(reg::kClkCtrl, startup::kAutoClocks), "writing CLK_CTRL (auto clocks)");
  check(writeMasked(reg::kSeqCtrl.plus(1), AccessMode::kMask8, 0xFF, startup::kAinit2Idle >> 8),
        "setting SEQ_CTRL AINIT2IDLE");
  const std::int64_t start_ns = clock_.nowNs();
  const std::uint32_t pll_status = waitStatus(status::kCpLock, config_.pll_lock_timeout_ns, "waiting for CP_LOCK");
  if ((pll_status & status::kCpLock) == 0) {
    fail(Dw3000Error::Kind::kPllLock,
         "PLL did not lock: CP_LOCK not set within " + msText(config_.pll_lock_timeout_ns) +
             " after AINIT2IDLE on channel " + std::to_string(static_cast<int>(config_.channel)) +
             " (SYS_STATUS reads " + hex32(pll_status) + ")" + firstStepNotInEffect(BringUpStep::kReset, BringUpStep::kPllLock));
  }
  report_.pll_lock_ns = clock_.nowNs() - start_ns;
}

void Dw3000Device::applyDgc() {
  if (prf64_) {
    // The DGC table: the chip's own from OTP when it holds one (kick),
    // otherwise the API's LUT for the channel; then the 64 MHz threshold.
    if (report_.dgc_from_otp) {
      const std::uint32_t sel = config_.channel == UwbChannel::k9 ? otp_cfg::kDgcSelCh9 : 0u;
      check(writeMasked(reg::kOtpCfg, AccessMode::kMask32, ~otp_cfg::kDgcSelCh9, sel | otp_cfg::kDgcKick),
            "kicking the DGC table (OTP_CFG)");
    } else {
      const std::uint32_t* lut = dgcLut(config_.channel);
      for (int i = 0; i < 7; ++i) {
        check(write32(reg::kDgcLut0.plus(4 * i), lut[i]), "writing DGC_LUT");
      }
      check(write32(reg::kDgcCfg0, startup::kDgcCfg0Value), "writing DGC_CFG0");
      check(write32(reg::kDgcCfg1, startup::kDgcCfg1Value), "writing DGC_CFG1");
    }
    // THR_64 as the API; RX_TUNE_EN too, which the API leaves at its reset
    // value: the audit and the RX power's DGC term then do not rest on it.
    check(writeMasked(reg::kDgcCfg, AccessMode::kMask16, ~startup::kDgcThr64Mask & 0xFFFFu,
                      (startup::kDgcThr64 << 9) | startup::kDgcRxTuneEn),
          "writing DGC_CFG (THR_64, RX_TUNE_EN)");
  } else {
    check(writeMasked(reg::kDgcCfg, AccessMode::kMask8, ~startup::kDgcRxTuneEn & 0xFFu, 0), "clearing DGC_CFG RX_TUNE_EN");
  }
}

void Dw3000Device::calibratePgf() {
  // dwt_pgf_cal(1): the receiver's LDOs on, calibrate, LDOs back.
  const std::uint32_t ldo_saved = readReg32(reg::kLdoCtrl, "reading LDO_CTRL") & 0xFFFFu;
  check(writeMasked(reg::kLdoCtrl, AccessMode::kMask16, 0xFFFF, startup::kLdoCtrlForPgf), "enabling LDOs for the PGF");
  check(write32(reg::kRxCalCfg, startup::kRxCalCfgPgf), "writing RX_CAL_CFG");
  check(writeMasked(reg::kRxCalCfg, AccessMode::kMask8, 0xFF, startup::kRxCalEnable), "starting the PGF calibration");
  const std::int64_t deadline_ns = clock_.nowNs() + config_.pgf_timeout_ns;
  for (;;) {
    report_.pgf_done = readReg8(reg::kRxCalSts, "reading RX_CAL_STS") == 1;
    if (report_.pgf_done || clock_.nowNs() >= deadline_ns) break;
    clock_.sleepForNs(std::min<std::int64_t>(config_.poll_interval_ns, 20'000));
  }
  check(write8(reg::kRxCalCfg, 0), "RX_CAL_CFG back to normal mode");
  check(write8(reg::kRxCalSts, 1), "clearing RX_CAL_STS");
  check(writeMasked(reg::kRxCalCfg.plus(2), AccessMode::kMask8, 0xFF, 0x01),
        "enabling the calibration result read");
  report_.pgf_result_i = readReg32(reg::kRxCalResI, "reading RX_CAL_RESI");
  report_.pgf_result_q = readReg32(reg::kRxCalResQ, "reading RX_CAL_RESQ");
  check(writeMasked(reg::kLdoCtrl, AccessMode::kMask16, ldo_saved, 0), "restoring LDO_CTRL");
  if (!report_.pgf_done || report_.pgf_result_i == startup::kRxCalFailed ||
      report_.pgf_result_q == startup::kRxCalFailed) {
    fail(Dw3000Error::Kind::kCalibration,
         std::string("PGF calibration ") + (report_.pgf_done ? "failed" : "did not finish within " +
                                                                  msText(config_.pgf_timeout_ns)) +
             " (RX_CAL_RESI " + hex32(report_.pgf_result_i) + ", RX_CAL_RESQ " + hex32(report_.pgf_result_q) +
             "): the receiver would be badly degraded; reset and try again" +
             firstStepNotInEffect(BringUpStep::kReset, BringUpStep::kPgfCalibration));
  }
}

void Dw3000Device::applyTxRf() {
  check(write8(reg::kTxCtrlHi, config_.tx_pg_delay), "writing TX_CTRL_HI (PG_DELAY)");
  check(write32(reg::kTxPower, config_.tx_power), "writing TX_POWER");
}

void Dw3000Device::applyCiaDiagnostics() {
  check(writeMasked(reg::kCiaConf.plus(2), AccessMode::kMask8, ~(startup::kCiaMinDiag >> 16) & 0xFFu, 0),
        "clearing CIA_CONF MINDIAG");
  check(write8(reg::kRdbDiagMode, 0), "writing RDB_DIAG_MODE");  // DW_CIA_DIAG_LOG_ALL >> 1
}

void Dw3000Device::applySiteWrites() {
  for (const RegisterWrite& w : config_.extra_init_writes) {
    std::array<std::uint8_t, 4> bytes{};
    for (std::size_t i = 0; i < 4; ++i) bytes[i] = static_cast<std::uint8_t>((w.value >> (8 * i)) & 0xFFu);
    check(write(w.addr, {bytes.data(), w.length}), "applying extra_init_writes");
  }
}

// --- Ours ------------------------------------------------------------------------

void Dw3000Device::applyExchangeTiming() {
  check(write16(reg::kTxAntd, config_.tx_antenna_delay), "writing TX_ANTD");
  check(writeMasked(reg::kCiaConf, AccessMode::kMask16, 0x0000, config_.rx_antenna_delay), "writing CIA_CONF");
  check(writeMasked(reg::kAckResp, AccessMode::kMask32, ~0xFFFFFu, uwbMicrosecondsFromUs(config_.rx_after_tx_delay_us)),
        "writing ACK_RESP (W4R_TIM)");
  check(writeMasked(reg::kRxFwto, AccessMode::kMask32, ~0xFFFFFu, uwbMicrosecondsFromUs(config_.rx_timeout_us)),
        "writing RX_FWTO");
}

void Dw3000Device::applyInterrupts() {
  // Clear everything, then unmask only what ends an exchange.
  check(clearAllStatus(), "clearing SYS_STATUS");
  irq_mask_ = exchangeInterrupts();
  check(write32(reg::kSysEnable, irq_mask_), "writing SYS_ENABLE");
  check(write16(reg::kSysEnableHi, 0), "writing SYS_ENABLE (high)");
  if (crc_enabled_) {
    const std::uint32_t st = readReg32(reg::kSysStatus, "reading SYS_STATUS");
    if ((st & status::kSpiCrcE) != 0) {
      fail(Dw3000Error::Kind::kSpiCrc,
           "SPI CRC error reported during configuration (SYS_STATUS " + hex32(st) + "): check SPI signal integrity");
    }
  }
  bool high = false;
  if (const std::error_code e = irq_.readLevel(high)) {
    fail(Dw3000Error::Kind::kIrqStuck, "cannot read IRQ line " + irq_.path() + ": " + e.message());
  }
  if (high) {
    fail(Dw3000Error::Kind::kIrqStuck, "IRQ line " + irq_.path() +
                                           " is high with SYS_STATUS cleared: check the IRQ wiring and polarity "
                                           "(active high expected)");
  }
}

void Dw3000Device::raiseSpiClock() {
  if (const std::error_code e = spi_.setSpeedHz(config_.spi_fast_hz)) {
    fail(Dw3000Error::Kind::kFastSpi, "cannot set the fast SPI clock (" + std::to_string(config_.spi_fast_hz) +
                                          " Hz): " + e.message());
  }
  std::uint32_t fast_id = 0;
  const std::error_code e = read32(reg::kDevId, fast_id);
  if (e || fast_id != dev_id_) {
    fail(Dw3000Error::Kind::kFastSpi,
         "DEV_ID reads " + hex32(fast_id) + (e ? " (" + e.message() + ")" : std::string()) + " at spi_fast_hz = " +
             std::to_string(config_.spi_fast_hz) + " Hz (" + hex32(dev_id_) + " at the slow clock): lower spi_fast_hz");
  }
}

// ---------------------------------------------------------------------------
// The audit

std::string Dw3000Device::firstStepNotInEffect(BringUpStep from, BringUpStep to) {
  if (!config_.startup_audit) return {};
  try {
    for (int i = static_cast<int>(from); i < static_cast<int>(to); ++i) {
      const auto step = static_cast<BringUpStep>(i);
      const std::string what = auditStep(step);
      if (!what.empty()) {
        const bool left_out = (left_out_ & stepBit(step)) != 0;
        return std::string("; step '") + stepName(step) + "' (" + stepReference(step) + ") " +
               (left_out ? "was left out" : "did not take") + ": " + what;
      }
    }
  } catch (const Dw3000Error& e) {
    // A failed read must not hide the failure that asked for the audit.
    return std::string("; the audit could not read the registers (") + e.what() + ")";
  }
  return {};
}

std::string Dw3000Device::auditStep(BringUpStep step) {
  switch (step) {
    case BringUpStep::kLdoBiasTrims: {
      if (!report_.ldo_bias_from_otp) return {};  // not programmed: the chip's defaults stand
      const std::uint32_t lo = readReg32(reg::kLdoTuneLo, "reading LDO_TUNE_LO");
      if (lo != report_.otp_ldo_tune_lo) return mismatch("LDO_TUNE_LO", lo, report_.otp_ldo_tune_lo, hex32);
      const std::uint32_t hi = readReg32(reg::kLdoTuneHi, "reading LDO_TUNE_HI");
      if (hi != report_.otp_ldo_tune_hi) return mismatch("LDO_TUNE_HI", hi, report_.otp_ldo_tune_hi, hex32);
      const std::uint8_t bias = readReg8(reg::kBiasCtrl, "reading BIAS_CTRL") & 0x1Fu;
      if (bias != report_.otp_bias_tune) return mismatch("BIAS_CTRL bias", bias, report_.otp_bias_tune, hex8);
      return {};
    }
    case BringUpStep::kXtalTrim: {
      const std::uint8_t expected = report_.xtal_trim;
      const std::uint8_t xtal = readReg8(reg::kXtalTrim, "reading XTAL") & 0x7Fu;
      return xtal == expected ? std::string() : mismatch("XTAL trim", xtal, expected, hex8);
    }
    case BringUpStep::kFrameFormat: {
      const std::uint32_t chan = readReg32(reg::kChanCtrl, "reading CHAN_CTRL") & 0x1FFFu;
      const std::uint32_t want_chan = (config_.channel == UwbChannel::k9 ? 1u : 0u) |
                                      (static_cast<std::uint32_t>(config_.sfd_type) << 1) |
                                      (static_cast<std::uint32_t>(config_.preamble_code) << 3) |
                                      (static_cast<std::uint32_t>(config_.preamble_code) << 8);
      if (chan != want_chan) return mismatch("CHAN_CTRL", chan, want_chan, hex16);
      const std::uint32_t fctrl = readReg32(reg::kTxFctrl, "reading TX_FCTRL") & 0xFC00u;
      const std::uint32_t want_fctrl =
          (static_cast<std::uint32_t>(preambleLengthCode(config_.preamble_length)) << tx_fctrl::kPsrShift) |
          (config_.data_rate == DataRate::k6M8 ? tx_fctrl::kBr6M8 : 0u) | tx_fctrl::kRanging;
      if (fctrl != want_fctrl) return mismatch("TX_FCTRL bits 15:10", fctrl, want_fctrl, hex16);
      const std::uint8_t fine = readReg8(reg::kTxFctrlHi.plus(1), "reading FINE_PLEN");
      const std::uint8_t want_fine = config_.preamble_length == 72 ? 8 : 0;
      if (fine != want_fine) return mismatch("FINE_PLEN", fine, want_fine, hex8);
      const std::uint32_t sys_cfg = readReg32(reg::kSysCfg, "reading SYS_CFG");
      if ((sys_cfg & sys_cfg::kRxWtoe) == 0) return "SYS_CFG reads " + hex32(sys_cfg) + " without RXWTOE";
      const std::uint32_t pan = readReg32(reg::kPanAdr, "reading PAN_ADR");
      const std::uint32_t want_pan = (static_cast<std::uint32_t>(config_.pan_id) << 16) | config_.tag_address;
      return pan == want_pan ? std::string() : mismatch("PAN_ADR", pan, want_pan, hex32);
    }
    case BringUpStep::kOpsTable: {
      // A kicked set stays selected in OPS_ID; the kick bit clears itself.
      // (The long set's id is 0, the reset value: only the short set shows.)
      const std::uint32_t cfg = readReg32(reg::kOtpCfg, "reading OTP_CFG") & otp_cfg::kOpsIdMask;
      return cfg == opsSet(config_) ? std::string() : mismatch("OTP_CFG OPS_ID", cfg, opsSet(config_), hex16);
    }
    case BringUpStep::kRxTuning: {
      const std::uint8_t pac = readReg8(reg::kDtune0, "reading DTUNE0") & 0x3u;
      const auto want_pac = static_cast<std::uint8_t>(pacCode(config_.pac_symbols));
      if (pac != want_pac) return mismatch("DTUNE0 PAC", pac, want_pac, hex8);
      const std::uint32_t sfd = (readReg32(reg::kDtune0, "reading DTUNE0") >> 16) & 0xFFFFu;
      if (sfd != sfdTimeoutSymbols(config_)) return mismatch("DTUNE0 SFD timeout", sfd, sfdTimeoutSymbols(config_), hex16);
      const std::uint32_t dtune3 = readReg32(reg::kDtune3, "reading DTUNE3");
      if (dtune3 != startup::kDtune3Default) return mismatch("DTUNE3", dtune3, startup::kDtune3Default, hex32);
      const std::uint8_t sts = readReg8(reg::kStsCfg0, "reading STS_CFG0");
      return sts == startup::kStsCfg0Len64 ? std::string() : mismatch("STS_CFG0", sts, startup::kStsCfg0Len64, hex8);
    }
    case BringUpStep::kRfPll: {
      const bool ch9 = config_.channel == UwbChannel::k9;
      const std::uint32_t pll = readReg32(reg::kPllCfg, "reading PLL_CFG") & 0xFFFFu;
      const std::uint32_t want_pll = ch9 ? startup::kPllCfgCh9 : startup::kPllCfgCh5;
      if (pll != want_pll) return mismatch("PLL_CFG", pll, want_pll, hex16);
      // PG_DELAY (bits 5:0) belongs to the TX step.
      const std::uint32_t tx = readReg32(reg::kTxCtrlHi, "reading TX_CTRL_HI") & ~0xFFu;
      const std::uint32_t want_tx = (ch9 ? startup::kTxCtrlHiCh9 : startup::kTxCtrlHiCh5) & ~0xFFu;
      if (tx != want_tx) return mismatch("TX_CTRL_HI bits 31:8", tx, want_tx, hex32);
      if (ch9) {
        const std::uint32_t rx = readReg32(reg::kRxCtrlHi, "reading RX_CTRL_HI");
        if (rx != startup::kRxCtrlHiCh9) return mismatch("RX_CTRL_HI", rx, startup::kRxCtrlHiCh9, hex32);
      }
      const std::uint8_t rload = readReg8(reg::kLdoRload.plus(1), "reading LDO_RLOAD");
      if (rload != startup::kLdoRloadByte1) return mismatch("LDO_RLOAD byte 1", rload, startup::kLdoRloadByte1, hex8);
      const std::uint8_t txlo = readReg8(reg::kTxCtrlLo.plus(2), "reading TX_CTRL_LO");
      if (txlo != startup::kTxCtrlLoByte2) return mismatch("TX_CTRL_LO byte 2", txlo, startup::kTxCtrlLoByte2, hex8);
      const std::uint8_t cal = readReg8(reg::kPllCal, "reading PLL_CAL");
      return cal == startup::kPllCalByte0 ? std::string() : mismatch("PLL_CAL", cal, startup::kPllCalByte0, hex8);
    }
    case BringUpStep::kPllLock: {
      const std::uint32_t seq = readReg32(reg::kSeqCtrl, "reading SEQ_CTRL");
      if ((seq & startup::kAinit2Idle) == 0) return "SEQ_CTRL reads " + hex32(seq) + " without AINIT2IDLE";
      const std::uint32_t clk = readReg32(reg::kClkCtrl, "reading CLK_CTRL") & 0xFFFFu;
      return clk == startup::kAutoClocks ? std::string() : mismatch("CLK_CTRL", clk, startup::kAutoClocks, hex16);
    }
    case BringUpStep::kDgc: {
      const std::uint32_t cfg = readReg32(reg::kDgcCfg, "reading DGC_CFG");
      if (!prf64_) {
        return (cfg & startup::kDgcRxTuneEn) == 0 ? std::string()
                                                  : "DGC_CFG reads " + hex32(cfg) + " with RX_TUNE_EN at 16 MHz PRF";
      }
      if ((cfg & startup::kDgcRxTuneEn) == 0) return "DGC_CFG reads " + hex32(cfg) + " without RX_TUNE_EN";
      const std::uint32_t thr = (cfg & startup::kDgcThr64Mask) >> 9;
      if (thr != startup::kDgcThr64) return mismatch("DGC_CFG THR_64", thr, startup::kDgcThr64, hex8);
      if (report_.dgc_from_otp) {
        // The part's own table, whatever its values: the kick selected the channel's.
        const std::uint32_t sel = readReg32(reg::kOtpCfg, "reading OTP_CFG") & otp_cfg::kDgcSelCh9;
        const std::uint32_t want = config_.channel == UwbChannel::k9 ? otp_cfg::kDgcSelCh9 : 0u;
        if (sel != want) return mismatch("OTP_CFG DGC_SEL", sel, want, hex16);
        const std::uint32_t lut0 = readReg32(reg::kDgcLut0, "reading DGC_LUT_0");
        return lut0 != 0 ? std::string() : "DGC_LUT_0 reads 0 after the DGC kick (no table loaded from OTP)";
      }
      const std::uint32_t cfg0 = readReg32(reg::kDgcCfg0, "reading DGC_CFG0");
      if (cfg0 != startup::kDgcCfg0Value) return mismatch("DGC_CFG0", cfg0, startup::kDgcCfg0Value, hex32);
      const std::uint32_t lut0 = readReg32(reg::kDgcLut0, "reading DGC_LUT_0");
      const std::uint32_t want_lut0 = dgcLut(config_.channel)[0];
      return lut0 == want_lut0 ? std::string() : mismatch("DGC_LUT_0", lut0, want_lut0, hex32);
    }
    case BringUpStep::kPgfCalibration: {
      const std::uint32_t i = readReg32(reg::kRxCalResI, "reading RX_CAL_RESI");
      const std::uint32_t q = readReg32(reg::kRxCalResQ, "reading RX_CAL_RESQ");
      if (i == startup::kRxCalFailed || q == startup::kRxCalFailed) {
        return "RX_CAL_RESI/RESQ read " + hex32(i) + "/" + hex32(q) + " (no calibration result)";
      }
      const std::uint8_t mode = readReg8(reg::kRxCalCfg, "reading RX_CAL_CFG") & 0x3u;
      return mode == 0 ? std::string() : mismatch("RX_CAL_CFG CAL_MODE", mode, 0, hex8);
    }
    case BringUpStep::kTxRf: {
      const std::uint8_t pg = readReg8(reg::kTxCtrlHi, "reading TX_CTRL_HI");
      if (pg != config_.tx_pg_delay) return mismatch("TX_CTRL_HI PG_DELAY", pg, config_.tx_pg_delay, hex8);
      const std::uint32_t power = readReg32(reg::kTxPower, "reading TX_POWER");
      return power == config_.tx_power ? std::string() : mismatch("TX_POWER", power, config_.tx_power, hex32);
    }
    case BringUpStep::kCiaDiagnostics: {
      const std::uint32_t cia = readReg32(reg::kCiaConf, "reading CIA_CONF");
      return (cia & startup::kCiaMinDiag) == 0 ? std::string()
                                               : "CIA_CONF reads " + hex32(cia) + " with MINDIAG set (no IP_DIAG logged)";
    }
    case BringUpStep::kExchangeTiming: {
      const std::uint32_t tx_antd = readReg32(reg::kTxAntd, "reading TX_ANTD") & 0xFFFFu;
      if (tx_antd != config_.tx_antenna_delay) return mismatch("TX_ANTD", tx_antd, config_.tx_antenna_delay, hex16);
      const std::uint32_t rx_antd = readReg32(reg::kCiaConf, "reading CIA_CONF") & 0xFFFFu;
      if (rx_antd != config_.rx_antenna_delay) return mismatch("CIA_CONF RXANTD", rx_antd, config_.rx_antenna_delay, hex16);
      const std::uint32_t w4r = readReg32(reg::kAckResp, "reading ACK_RESP") & 0xFFFFFu;
      const std::uint32_t want_w4r = uwbMicrosecondsFromUs(config_.rx_after_tx_delay_us);
      if (w4r != want_w4r) return mismatch("ACK_RESP W4R_TIM", w4r, want_w4r, hex32);
      const std::uint32_t fwto = readReg32(reg::kRxFwto, "reading RX_FWTO") & 0xFFFFFu;
      const std::uint32_t want_fwto = uwbMicrosecondsFromUs(config_.rx_timeout_us);
      return fwto == want_fwto ? std::string() : mismatch("RX_FWTO", fwto, want_fwto, hex32);
    }
    case BringUpStep::kInterrupts: {
      const std::uint32_t enabled = readReg32(reg::kSysEnable, "reading SYS_ENABLE");
      const std::uint32_t want = exchangeInterrupts();
      return enabled == want ? std::string() : mismatch("SYS_ENABLE", enabled, want, hex32);
    }
    default: return {};  // reset, IDLE_RC, DEV_ID, SPI CRC, site writes, fast SPI: checked where they run
  }
}

}  // namespace rilo::dw3000
