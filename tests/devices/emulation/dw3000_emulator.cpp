#include "devices/emulation/dw3000_emulator.h"

#include <algorithm>
#include <cmath>

namespace rilo::emu {
namespace {

// Register map transcribed from docs/hardware-notes.md independently of the
// driver's registers.h, so a wrong address there shows up as a failing test.
constexpr std::uint8_t kGen = 0x00;            // general file
constexpr std::size_t kDevId = 0x00;
constexpr std::size_t kSysCfg = 0x10;
constexpr std::size_t kSpiRdCrc = 0x18;
constexpr std::size_t kSysTime = 0x1C;
constexpr std::size_t kTxFctrl = 0x24;
constexpr std::size_t kRxFwto = 0x34;
constexpr std::size_t kSysEnable = 0x3C;       // 4 bytes + 2 at 0x40
constexpr std::size_t kSysStatus = 0x44;       // 6 bytes
constexpr std::size_t kRxFinfo = 0x4C;
constexpr std::size_t kRxTime = 0x64;
constexpr std::size_t kTxTime = 0x74;
constexpr std::uint8_t kFileGen2 = 0x01;
constexpr std::size_t kTxAntd = 0x04;
constexpr std::size_t kAckResp = 0x08;
constexpr std::size_t kChanCtrl = 0x14;
constexpr std::uint8_t kFileDgc = 0x03;
constexpr std::size_t kDgcCfg = 0x18;          // RX_TUNE_EN b0
constexpr std::size_t kDgcDbg = 0x60;          // DGC_DECISION bits 30:28
constexpr std::uint8_t kFileDrx = 0x06;
constexpr std::size_t kDrxDiag3 = 0x29;
constexpr std::uint8_t kFileCia = 0x0C;
constexpr std::size_t kCiaDiag0 = 0x20;
constexpr std::size_t kIpDiag1 = 0x2C;         // C, bits 16:0
constexpr std::size_t kIpDiag2 = 0x30;         // F1..F3 at 0x30/0x34/0x38, bits 21:0, 2 fractional bits
constexpr std::size_t kIpDiag12 = 0x58;        // N, bits 11:0
constexpr std::uint8_t kFileCiaConf = 0x0E;
constexpr std::uint32_t kCiaConfMinDiag = 1u << 20;
constexpr std::uint8_t kFileRst = 0x11;
// Start-up registers (Qorvo's C0 API deca_regs.h / deca_vals.h), written
// down again here rather than taken from the driver's registers.h.
constexpr std::uint8_t kFileRxCal = 0x04;
constexpr std::size_t kRxCalCfg = 0x0C;        // CAL_MODE 1:0, CAL_EN b4
constexpr std::size_t kRxCalResI = 0x14;
constexpr std::size_t kRxCalResQ = 0x1C;
constexpr std::size_t kRxCalSts = 0x20;
constexpr std::size_t kDtune0 = 0x00;          // in file 0x06: PAC 1:0, SFD timeout 31:16
constexpr std::size_t kDtune3 = 0x0C;
constexpr std::uint8_t kFileRfTx = 0x07;
constexpr std::size_t kRxCtrlHi = 0x10;
constexpr std::size_t kTxCtrlHi = 0x1C;
constexpr std::size_t kLdoTuneLo = 0x40;
constexpr std::size_t kLdoTuneHi = 0x44;
constexpr std::size_t kLdoCtrl = 0x48;
constexpr std::uint8_t kFilePll = 0x09;        // PLL_CFG at 0x00 (16 bits)
constexpr std::uint8_t kFileOtp = 0x0B;
constexpr std::size_t kOtpAddr = 0x04;
constexpr std::size_t kOtpCfg = 0x08;
constexpr std::size_t kOtpRdata = 0x10;
constexpr std::size_t kClkCtrl = 0x04;         // in file 0x11
constexpr std::size_t kSeqCtrl = 0x08;         // in file 0x11, AINIT2IDLE b8
constexpr std::size_t kBiasCtrl = 0x1F;        // in file 0x11, bits 4:0
constexpr std::size_t kDgcCfg0 = 0x1C;
constexpr std::size_t kDgcCfg1 = 0x20;
constexpr std::size_t kDgcLut0 = 0x38;

constexpr std::uint32_t kPllCfgCh5 = 0x1F3C;
constexpr std::uint32_t kPllCfgCh9 = 0x0F3C;
constexpr std::uint32_t kTxCtrlHiCh5 = 0x1C071134;
constexpr std::uint32_t kTxCtrlHiCh9 = 0x1C010034;
constexpr std::uint32_t kRxCtrlHiCh9 = 0x08B5A833;
constexpr std::uint32_t kDgcCfg0Value = 0x10000240;
constexpr std::uint32_t kDgcCfg1Value = 0x1B6DA489;
constexpr std::array<std::uint32_t, 7> kDgcLutCh5{0x1C0FD, 0x1C43E, 0x1C6BE, 0x1C77E, 0x1CF36, 0x1CFB5, 0x1CFF5};
constexpr std::array<std::uint32_t, 7> kDgcLutCh9{0x2A8FE, 0x2AC36, 0x2A5FE, 0x2AF3E, 0x2AF7D, 0x2AFB5, 0x2AFB5};
constexpr std::uint32_t kRxCalFailed = 0x1FFFFFFF;
constexpr std::uint32_t kOtpManual = 1u << 0;
constexpr std::uint32_t kOtpRead = 1u << 1;
constexpr std::uint32_t kOtpDgcKick = 1u << 6;
constexpr std::uint32_t kOtpLdoKick = 1u << 7;
constexpr std::uint32_t kOtpBiasKick = 1u << 8;
constexpr std::uint32_t kOtpOpsKick = 1u << 10;
constexpr std::uint32_t kOtpOpsId = 0x3u << 11;
constexpr std::uint32_t kOtpDgcSel = 1u << 13;

/// Preamble length (symbols) of a TX_FCTRL TXPSR code (FINE_PLEN aside).
int preambleSymbols(std::uint32_t txpsr) {
  switch (txpsr) {
    case 0x04: return 32;
    case 0x01: return 64;
    case 0x07: return 72;
    case 0x05: return 128;
    case 0x09: return 256;
    case 0x0D: return 512;
    case 0x02: return 1024;
    case 0x06: return 1536;
    case 0x0A: return 2048;
    case 0x03: return 4096;
    default: return 0;
  }
}
constexpr std::uint8_t kFileRxBuf = 0x12;
constexpr std::uint8_t kFileTxBuf = 0x14;

constexpr std::uint32_t kSysCfgSpiCrc = 0x40;
constexpr std::uint32_t kSysCfgRxWtoe = 1u << 9;

constexpr std::uint64_t kCpLock = 1u << 1;
constexpr std::uint64_t kSpiCrcE = 1u << 2;
constexpr std::uint64_t kTxFrs = 1u << 7;
constexpr std::uint64_t kRxPrd = 1u << 8;
constexpr std::uint64_t kRxSfdd = 1u << 9;
constexpr std::uint64_t kCiaDone = 1u << 10;
constexpr std::uint64_t kRxPhd = 1u << 11;
constexpr std::uint64_t kRxFr = 1u << 13;
constexpr std::uint64_t kRxFcg = 1u << 14;
constexpr std::uint64_t kRxFto = 1u << 17;
constexpr std::uint64_t kSpiRdy = 1u << 23;
constexpr std::uint64_t kRcInit = 1u << 24;

constexpr double kClockHz = 499.2e6 * 128.0;
constexpr double kUusNs = 512.0 / 499.2e6 * 1e9;
constexpr double kLightMps = 299702547.0;
constexpr std::uint64_t kMask40 = (std::uint64_t{1} << 40) - 1;

std::uint8_t crc8(std::span<const std::uint8_t> bytes, std::uint8_t crc) {
  for (const std::uint8_t b : bytes) {
    crc ^= b;
    for (int i = 0; i < 8; ++i) crc = static_cast<std::uint8_t>((crc & 0x80u) ? (crc << 1) ^ 0x07u : crc << 1);
  }
  return crc;
}

/// Register values that make the user manual's formulas (sections 4.7.1 and
/// 4.7.2) give back `rx_level_dbm` and `fp_power_dbm` (to the registers'
/// rounding), with `dgc_decision` steps of 6 dB taken off by the receiver.
struct CiaDiagnostics {
  std::uint32_t c = 0;
  std::array<std::uint32_t, 3> f{};
};
CiaDiagnostics diagnosticsFor(double rx_level_dbm, double fp_power_dbm, std::uint32_t n, int dgc_decision,
                              bool prf64) {
  const double a_db = prf64 ? 121.7 : 113.8;
  const double n2 = static_cast<double>(n) * static_cast<double>(n);
  const double gain_db = a_db - 6.0 * dgc_decision;
  CiaDiagnostics d;
  const double c = std::pow(10.0, (rx_level_dbm + gain_db) / 10.0) * n2 / 2097152.0;
  d.c = static_cast<std::uint32_t>(std::clamp<double>(std::round(c), 0.0, 0x1FFFF));
  // The first-path energy spread over the three amplitudes around the edge.
  const double energy = std::pow(10.0, (fp_power_dbm + gain_db) / 10.0) * n2;
  constexpr std::array<double, 3> kShare{0.5, 0.3, 0.2};
  for (std::size_t i = 0; i < 3; ++i) {
    const double f = 4.0 * std::sqrt(kShare[i] * energy);  // 2 fractional bits
    d.f[i] = static_cast<std::uint32_t>(std::clamp<double>(std::round(f), 0.0, 0x3FFFFF));
  }
  return d;
}

std::uint64_t le(std::span<const std::uint8_t> bytes) {
  std::uint64_t v = 0;
  for (std::size_t i = bytes.size(); i-- > 0;) v = (v << 8) | bytes[i];
  return v;
}

bool readOnly(std::uint8_t file, std::size_t offset) {
  if (file != kGen) return false;
  return offset < 4 || offset == kSpiRdCrc || (offset >= kSysTime && offset < kSysTime + 4) ||
         (offset >= kRxFinfo && offset < kRxFinfo + 4) || (offset >= kRxTime && offset < kRxTime + 5) ||
         (offset >= kTxTime && offset < kTxTime + 5);
}

}  // namespace

Dw3000Emulator::Dw3000Emulator(VirtualClock& clock, EmulatedInterruptLine& irq, EmulatedOutputLine* reset,
                               Dw3000EmulatorParams params)
    : clock_(clock), irq_(irq), params_(std::move(params)) {
  for (std::size_t f = 0; f < files_.size(); ++f) {
    files_[f].assign((f >= kFileRxBuf && f <= kFileTxBuf) ? 1024 : 256, 0);
  }
  if (reset != nullptr) {
    reset->onChange([this](bool high) {
      if (high) {
        startBoot();
      } else {
        hung_ = false;  // only the reset line brings a hung chip back
        enterReset();
      }
    });
  }
  enterReset();
  startBoot();
}

std::size_t Dw3000Emulator::addResponder(Dw3000ResponderModel model) {
  responders_.push_back(std::move(model));
  return responders_.size() - 1;
}

// ---------------------------------------------------------------------------
// State

void Dw3000Emulator::enterReset() {
  ++generation_;
  ++exchange_;
  ++counters_.resets;
  state_ = State::kReset;
  crc_active_ = false;
  stuck_active_ = false;
  stuck_armed_ = false;
  for (auto& file : files_) std::fill(file.begin(), file.end(), 0);
  // Reset values the start-up relies on (see the header).
  put(kFileCiaConf, 0x00, kCiaConfMinDiag, 4);
  put(kFileDgc, kDgcCfg, 0x1, 4);
  put(kFileRxCal, kRxCalResI, kRxCalFailed, 4);
  put(kFileRxCal, kRxCalResQ, kRxCalFailed, 4);
  put(kFileRst, kClkCtrl, 0x0200, 2);
  ldo_kicked_ = false;
  dgc_kicked_ = false;
  ops_kicked_ = false;
  ops_set_ = 0;
  updateIrq();
}

void Dw3000Emulator::startBoot() {
  if (state_ != State::kReset) return;
  state_ = State::kInitRc;
  const std::uint64_t generation = generation_;
  if (never_boots_ || hung_) return;
  clock_.schedule(clock_.nowNs() + params_.boot_ns, [this, generation] {
    if (generation != generation_) return;
    state_ = State::kIdleRc;
    boot_ns_ = clock_.nowNs();
    ++counters_.boots;
    put(kGen, kDevId, params_.dev_id, 4);
    setStatusBits(kSpiRdy | kRcInit);
  });
}

void Dw3000Emulator::relockPll() {
  if (state_ != State::kIdleRc && state_ != State::kIdlePll) return;
  state_ = State::kIdleRc;
  // dwt_setdwstate(DWT_DW_IDLE): the PLL calibrates for the channel
  // PLL_CFG was set up for, and only with the clocks on auto.
  const int channel = (reg32(kFileGen2, kChanCtrl) & 1u) != 0 ? 9 : 5;
  const std::uint32_t pll_cfg = reg32(kFilePll, 0x00) & 0xFFFFu;
  const bool clocks_auto = (reg32(kFileRst, kClkCtrl) & 0x3u) == 0;
  if (pll_cfg != (channel == 9 ? kPllCfgCh9 : kPllCfgCh5) || !clocks_auto) {
    ++counters_.pll_refusals;
    return;
  }
  if (pll_failure_count_ > 0) {
    --pll_failure_count_;
    return;  // never locks
  }
  const std::uint64_t generation = generation_;
  clock_.schedule(clock_.nowNs() + params_.pll_lock_ns, [this, generation] {
    if (generation != generation_ || state_ != State::kIdleRc) return;
    state_ = State::kIdlePll;
    ++counters_.pll_locks;
    setStatusBits(kCpLock);
  });
}

void Dw3000Emulator::injectPllLossOfLock() {
  if (state_ == State::kIdlePll) state_ = State::kIdleRc;
  ++exchange_;
}

std::uint32_t Dw3000Emulator::spiLimitHz() const {
  return (state_ == State::kReset || state_ == State::kInitRc) ? params_.max_slow_spi_hz : params_.max_spi_hz;
}

// ---------------------------------------------------------------------------
// Registers

std::uint32_t Dw3000Emulator::reg32(std::uint8_t file, std::size_t offset) const {
  return static_cast<std::uint32_t>(le({files_[file].data() + offset, 4}));
}

std::uint32_t Dw3000Emulator::peek32(std::uint8_t file, std::uint8_t offset) const { return reg32(file, offset); }

void Dw3000Emulator::put(std::uint8_t file, std::size_t offset, std::uint64_t value, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; ++i) files_[file][offset + i] = static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFu);
}

std::uint64_t Dw3000Emulator::status() const { return le({files_[kGen].data() + kSysStatus, 6}); }

std::uint32_t Dw3000Emulator::enabledInterrupts() const { return reg32(kGen, kSysEnable); }

void Dw3000Emulator::setStatusBits(std::uint64_t bits) {
  put(kGen, kSysStatus, status() | bits, 6);
  if (stuck_armed_ && (bits & enabledInterrupts()) != 0) {
    stuck_armed_ = false;
    stuck_active_ = true;
  }
  updateIrq();
}

void Dw3000Emulator::clearStatusBits(std::uint64_t bits) {
  put(kGen, kSysStatus, status() & ~bits, 6);
  updateIrq();
}

void Dw3000Emulator::updateIrq() {
  const std::uint64_t enabled = le({files_[kGen].data() + kSysEnable, 6});
  irq_.setLevel(stuck_active_ || (status() & enabled) != 0);
}

double Dw3000Emulator::ourDeviceUnits(double t_ns) const {
  return static_cast<double>(params_.initial_device_time) +
         (t_ns - static_cast<double>(boot_ns_)) * 1e-9 * kClockHz * (1.0 + params_.clock_ppm * 1e-6);
}

double Dw3000Emulator::responderDeviceUnits(const Dw3000ResponderModel& r, double t_ns) const {
  return static_cast<double>(r.initial_device_time) + t_ns * 1e-9 * kClockHz * (1.0 + r.clock_ppm * 1e-6);
}

double Dw3000Emulator::responderTimeOf(const Dw3000ResponderModel& r, double units) const {
  return (units - static_cast<double>(r.initial_device_time)) / (kClockHz * (1.0 + r.clock_ppm * 1e-6)) * 1e9;
}

std::uint64_t Dw3000Emulator::deviceTimeNow() const {
  return static_cast<std::uint64_t>(std::llround(ourDeviceUnits(static_cast<double>(clock_.nowNs())))) & kMask40;
}

std::uint8_t Dw3000Emulator::readByte(std::uint8_t file, std::size_t offset) const {
  if (file == kGen && offset >= kSysTime && offset < kSysTime + 4) {
    // SYS_TIME: device time bits 39:8, bit 0 always zero.
    const std::uint64_t t = (deviceTimeNow() >> 8) & 0xFFFF'FFFEu;
    return static_cast<std::uint8_t>((t >> (8 * (offset - kSysTime))) & 0xFFu);
  }
  return offset < files_[file].size() ? files_[file][offset] : 0;
}

void Dw3000Emulator::applyWrite(std::uint8_t file, std::size_t offset, std::span<const std::uint8_t> data) {
  bool status_written = false;
  bool soft_reset = false;
  bool ainit2idle = false;
  bool otp_cfg_written = false;
  bool rx_cal_cfg_written = false;
  const std::uint32_t otp_cfg_before = reg32(kFileOtp, kOtpCfg);
  std::uint64_t clear_bits = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const std::size_t at = offset + i;
    if (at >= files_[file].size()) break;
    if (readOnly(file, at)) continue;
    if (file == kGen && at >= kSysStatus && at < kSysStatus + 6) {
      clear_bits |= static_cast<std::uint64_t>(data[i]) << (8 * (at - kSysStatus));
      status_written = true;
      continue;
    }
    if (file == kFileRst && at == 0) soft_reset = data[i] == 0x00;  // DWT_RESET_ALL
    if (file == kFileRst && at == kSeqCtrl + 1 && (data[i] & 0x01u) != 0) ainit2idle = true;
    if (file == kFileOtp && at >= kOtpCfg && at < kOtpCfg + 4) otp_cfg_written = true;
    if (file == kFileRxCal && at >= kRxCalCfg && at < kRxCalCfg + 4) rx_cal_cfg_written = true;
    if (file == kFileRxCal && at == kRxCalSts) {  // write 1 to clear
      files_[file][at] = static_cast<std::uint8_t>(files_[file][at] & ~data[i]);
      continue;
    }
    files_[file][at] = data[i];
  }
  if (status_written) {
    ++counters_.status_clears;
    clearStatusBits(clear_bits);
  }
  if (file == kGen) crc_active_ = (reg32(kGen, kSysCfg) & kSysCfgSpiCrc) != 0;
  if (otp_cfg_written) onOtpCfgWrite(otp_cfg_before);
  if (rx_cal_cfg_written) onRxCalCfgWrite();
  if (ainit2idle && state_ == State::kIdleRc) relockPll();
  if (soft_reset) onSoftReset();
  updateIrq();
}

void Dw3000Emulator::onSoftReset() {
  // The reset switches the PLL off: a system clock still on the PLL (not
  // forced to FOSC first, as dwt_softreset does) leaves the chip hung.
  const bool on_pll = state_ == State::kIdlePll && (reg32(kFileRst, kClkCtrl) & 0x3u) != 0x3u;
  if (on_pll) {
    ++counters_.soft_reset_hangs;
    hung_ = true;
  }
  enterReset();
  startBoot();  // boots by itself (no second write), unless hung
}

void Dw3000Emulator::onOtpCfgWrite(std::uint32_t before) {
  const std::uint32_t cfg = reg32(kFileOtp, kOtpCfg);
  const Dw3000Otp& otp = params_.otp;
  if ((cfg & kOtpRead) != 0 && (before & kOtpManual) != 0) {
    // _dwt_otpread: manual mode first, then the address, then the strobe.
    std::uint32_t word = 0;
    switch (reg32(kFileOtp, kOtpAddr) & 0x7FFu) {
      case 0x04: word = otp.ldo_tune_lo; break;
      case 0x05: word = otp.ldo_tune_hi; break;
      case 0x06: word = otp.part_id; break;
      case 0x07: word = otp.lot_id; break;
      case 0x0A: word = otp.bias_tune_word; break;
      case 0x1E: word = otp.xtal_trim; break;
      case 0x1F: word = otp.revision; break;
      case 0x20: word = otp.dgc_table ? kDgcCfg0Value : 0u; break;
      default: break;
    }
    put(kFileOtp, kOtpRdata, word, 4);
    ++counters_.otp_reads;
  }
  if ((cfg & kOtpLdoKick) != 0) {
    put(kFileRfTx, kLdoTuneLo, otp.ldo_tune_lo, 4);
    put(kFileRfTx, kLdoTuneHi, otp.ldo_tune_hi, 4);
    ldo_kicked_ = true;
  }
  if ((cfg & kOtpOpsKick) != 0) {
    ops_kicked_ = true;
    ops_set_ = cfg & kOtpOpsId;
  }
  if ((cfg & kOtpDgcKick) != 0 && otp.dgc_table) {
    const std::size_t first = (cfg & kOtpDgcSel) != 0 ? 7 : 0;
    for (std::size_t i = 0; i < 7; ++i) put(kFileDgc, kDgcLut0 + 4 * i, otp.dgc_lut[first + i], 4);
    put(kFileDgc, kDgcCfg0, kDgcCfg0Value, 4);
    put(kFileDgc, kDgcCfg1, kDgcCfg1Value, 4);
    dgc_kicked_ = true;
  }
  // The kicks clear themselves.
  put(kFileOtp, kOtpCfg, cfg & ~(kOtpDgcKick | kOtpLdoKick | kOtpBiasKick | kOtpOpsKick), 4);
}

void Dw3000Emulator::onRxCalCfgWrite() {
  const std::uint32_t cfg = reg32(kFileRxCal, kRxCalCfg);
  if ((cfg & 0x10u) == 0 || (cfg & 0x3u) != 1) return;  // CAL_EN in PGF mode starts one
  // The PGF calibration needs the receiver's LDOs (VDDIF2, VDDMS3, VDDMS1) on.
  const bool ldos_on = (reg32(kFileRfTx, kLdoCtrl) & 0x0105u) == 0x0105u;
  const std::uint64_t generation = generation_;
  ++counters_.pgf_calibrations;
  clock_.schedule(clock_.nowNs() + params_.pgf_cal_ns, [this, generation, ldos_on] {
    if (generation != generation_) return;
    put(kFileRxCal, kRxCalResI, ldos_on ? params_.pgf_result_i : kRxCalFailed, 4);
    put(kFileRxCal, kRxCalResQ, ldos_on ? params_.pgf_result_q : kRxCalFailed, 4);
    files_[kFileRxCal][kRxCalSts] = 1;
  });
}

const char* Dw3000Emulator::receiverNotReady() const {
  const Dw3000Otp& otp = params_.otp;
  const std::uint32_t bias = (otp.bias_tune_word >> 16) & 0x1Fu;
  if (otp.ldo_tune_lo != 0 && otp.ldo_tune_hi != 0 && bias != 0) {
    if (!ldo_kicked_ || (files_[kFileRst][kBiasCtrl] & 0x1Fu) != bias) return "LDO and bias trims";
  }
  const int symbols = preambleSymbols((reg32(kGen, kTxFctrl) >> 12) & 0xFu);
  if (!ops_kicked_ || ops_set_ != (symbols >= 256 ? 0x0u : (0x2u << 11))) return "OPS table";
  const std::uint32_t dtune3 = reg32(kFileDrx, kDtune3);
  if ((dtune3 != 0xAF5F584Cu && dtune3 != 0xAF5F35CCu) || (reg32(kFileDrx, kDtune0) >> 16) == 0) {
    return "receiver tuning";
  }
  const bool ch9 = (reg32(kFileGen2, kChanCtrl) & 1u) != 0;
  if ((reg32(kFileRfTx, kTxCtrlHi) & ~0xFFu) != ((ch9 ? kTxCtrlHiCh9 : kTxCtrlHiCh5) & ~0xFFu) ||
      (ch9 && reg32(kFileRfTx, kRxCtrlHi) != kRxCtrlHiCh9)) {
    return "RF configuration";
  }
  const std::uint32_t dgc = reg32(kFileDgc, kDgcCfg);
  const bool prf64 = ((reg32(kFileGen2, kChanCtrl) >> 8) & 0x1Fu) >= 9;
  if (prf64) {
    const auto& lut = ch9 ? kDgcLutCh9 : kDgcLutCh5;
    const bool table = dgc_kicked_ || (reg32(kFileDgc, kDgcCfg0) == kDgcCfg0Value && reg32(kFileDgc, kDgcLut0) == lut[0]);
    if ((dgc & 1u) == 0 || ((dgc >> 9) & 0x3Fu) != 0x32u || !table) return "DGC";
  } else if ((dgc & 1u) != 0) {
    return "DGC";
  }
  if (reg32(kFileRxCal, kRxCalResI) == kRxCalFailed || reg32(kFileRxCal, kRxCalResQ) == kRxCalFailed ||
      (reg32(kFileRxCal, kRxCalCfg) & 0x3u) != 0) {
    return "PGF calibration";
  }
  return nullptr;
}

// ---------------------------------------------------------------------------
// SPI

std::error_code Dw3000Emulator::setSpeedHz(std::uint32_t speed_hz) noexcept {
  speed_hz_ = speed_hz;
  return {};
}

std::error_code Dw3000Emulator::transfer(std::span<const hal::SpiTransfer> transfers) noexcept {
  if (fail_count_ > 0) {
    --fail_count_;
    return fail_error_;
  }
  if (read_fail_count_ > 0 && !transfers.empty() && transfers[0].tx != nullptr && transfers[0].len >= 1) {
    const std::uint8_t b0 = transfers[0].tx[0];
    const bool extended = (b0 & 0x40u) != 0;
    const bool is_read = (b0 & 0x80u) == 0 && (extended || (b0 & 0x01u) == 0);
    std::size_t offset = 0;
    if (extended && transfers[0].len >= 2) offset = static_cast<std::size_t>(((b0 & 0x01u) << 6) | (transfers[0].tx[1] >> 2));
    if (is_read && ((b0 >> 1) & 0x1Fu) == read_fail_file_ && offset == read_fail_offset_) {
      --read_fail_count_;
      return read_fail_error_;
    }
  }
  // Split into chip-select frames (cs_change ends one) and run each.
  std::vector<std::uint8_t> tx;
  std::vector<std::uint8_t> rx;
  std::vector<const hal::SpiTransfer*> parts;
  const auto flush = [&] {
    if (tx.empty()) return;
    rx.assign(tx.size(), 0);
    processFrame(tx, rx);
    std::size_t at = 0;
    for (const hal::SpiTransfer* t : parts) {
      if (t->rx != nullptr) std::copy_n(rx.begin() + static_cast<std::ptrdiff_t>(at), t->len, t->rx);
      at += t->len;
    }
    tx.clear();
    parts.clear();
  };
  for (const hal::SpiTransfer& t : transfers) {
    for (std::size_t i = 0; i < t.len; ++i) tx.push_back(t.tx != nullptr ? t.tx[i] : 0);
    parts.push_back(&t);
    if (t.cs_change) flush();
  }
  flush();
  return {};
}

void Dw3000Emulator::processFrame(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) {
  ++counters_.messages;
  if (speed_hz_ > spiLimitHz()) {
    // Too fast for the current state: the chip samples garbage.
    ++counters_.speed_violations;
    std::fill(rx.begin(), rx.end(), 0xFF);
    return;
  }
  const std::uint8_t b0 = tx[0];
  std::size_t header = 1;
  std::uint8_t file = static_cast<std::uint8_t>((b0 >> 1) & 0x1Fu);
  std::size_t offset = 0;
  int mode = 0;
  const bool write = (b0 & 0x80u) != 0;
  if ((b0 & 0x40u) != 0) {
    if (tx.size() < 2) {
      ++counters_.unsupported;
      return;
    }
    header = 2;
    offset = static_cast<std::size_t>(((b0 & 0x01u) << 6) | (tx[1] >> 2));
    mode = tx[1] & 0x03;
  } else if ((b0 & 0x01u) != 0) {
    if (state_ == State::kReset || state_ == State::kInitRc) return;
    if (!write || tx.size() != 1) {
      ++counters_.unsupported;
      return;
    }
    fastCommand(static_cast<std::uint8_t>((b0 >> 1) & 0x1Fu));
    updateIrq();
    return;
  }

  // Held in reset or still in INIT_RC: the SPI does not answer (reads 0).
  if (state_ == State::kReset || state_ == State::kInitRc) return;

  if (!write) {
    if (mode != 0) {
      ++counters_.unsupported;
      return;
    }
    for (std::size_t i = header; i < tx.size(); ++i) rx[i] = readByte(file, offset + (i - header));
    if (crc_active_ && !(file == kGen && offset == kSpiRdCrc)) {
      files_[kGen][kSpiRdCrc] = crc8(rx.subspan(header), crc8(tx.first(header), 0));
      if (read_crc_error_count_ > 0 && tx.size() > header) {
        --read_crc_error_count_;
        ++counters_.read_corruptions;
        rx[header] ^= 0x10;  // flipped on the wire, after the chip computed its CRC
      }
    }
    return;
  }

  std::span<const std::uint8_t> body = tx.subspan(header);
  if (crc_active_) {
    if (body.empty()) {
      ++counters_.unsupported;
      return;
    }
    const std::uint8_t sent = body.back();
    body = body.first(body.size() - 1);
    const bool corrupted = write_crc_error_count_ > 0;
    if (corrupted) --write_crc_error_count_;
    if (corrupted || crc8(body, crc8(tx.first(header), 0)) != sent) {
      ++counters_.write_crc_errors;
      setStatusBits(kSpiCrcE);  // the write is dropped
      return;
    }
  }
  if (mode == 0) {
    applyWrite(file, offset, body);
    return;
  }
  const std::size_t width = mode == 1 ? 1 : (mode == 2 ? 2 : 4);
  if (body.size() != 2 * width) {
    ++counters_.unsupported;
    return;
  }
  const std::uint64_t and_mask = le(body.first(width));
  const std::uint64_t or_mask = le(body.subspan(width, width));
  std::uint64_t current = 0;
  for (std::size_t i = 0; i < width; ++i) current |= static_cast<std::uint64_t>(readByte(file, offset + i)) << (8 * i);
  std::uint64_t value = (current & and_mask) | or_mask;
  if (file == kGen && offset >= kSysStatus && offset < kSysStatus + 6) value = or_mask;  // W1C: ones clear
  std::array<std::uint8_t, 4> bytes{};
  for (std::size_t i = 0; i < width; ++i) bytes[i] = static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFu);
  applyWrite(file, offset, {bytes.data(), width});
}

void Dw3000Emulator::fastCommand(std::uint8_t command) {
  switch (command) {
    case 0x00:  // TXRXOFF
      ++counters_.trxoff;
      ++exchange_;
      break;
    case 0x0C:  // TX_W4R
      ++counters_.tx_w4r;
      startExchange();
      break;
    case 0x12:  // CLR_IRQS
      ++counters_.clr_irqs;
      if (stuck_active_ && stuck_mode_ == StuckIrq::kUntilFullClear) stuck_active_ = false;
      clearStatusBits(~std::uint64_t{0});
      break;
    default:
      ++counters_.unsupported;
      break;
  }
}

// ---------------------------------------------------------------------------
// The exchange: our poll, the responder's firmware, the response

void Dw3000Emulator::startExchange() {
  const std::uint64_t exchange = ++exchange_;
  if (state_ != State::kIdlePll) {
    ++counters_.tx_while_unlocked;  // the PLL is not locked: nothing is sent
    return;
  }
  const auto alive = [this, exchange, generation = generation_] {
    return generation == generation_ && exchange == exchange_;
  };
  const double t0 = static_cast<double>(clock_.nowNs());
  const std::size_t length = reg32(kGen, kTxFctrl) & 0x3FFu;  // with FCS
  std::vector<std::uint8_t> poll(files_[kFileTxBuf].begin(),
                                 files_[kFileTxBuf].begin() + static_cast<std::ptrdiff_t>(length >= 2 ? length - 2 : 0));

  // Our transmission.
  const double t_rmarker = t0 + params_.tx_startup_ns + params_.shr_ns;
  const std::int64_t tx_units = std::llround(ourDeviceUnits(t_rmarker));
  const std::uint16_t tx_antd = static_cast<std::uint16_t>(reg32(kFileGen2, kTxAntd) & 0xFFFFu);
  const std::uint64_t tx_time = static_cast<std::uint64_t>(tx_units + tx_antd) & kMask40;
  const double t_departure = t_rmarker + params_.true_tx_antenna_delay_units / kClockHz * 1e9;
  const double t_tx_end = t_rmarker + params_.phr_ns + static_cast<double>(length) * params_.ns_per_byte;
  clock_.schedule(static_cast<std::int64_t>(std::ceil(t_tx_end)), [this, alive, tx_time] {
    if (!alive()) return;
    put(kGen, kTxTime, tx_time, 5);
    setStatusBits(kTxFrs);
  });

  // Our receiver: opens W4R_TIM after the TX end, closes after RX_FWTO.
  const double t_rx_on = t_tx_end + static_cast<double>(reg32(kFileGen2, kAckResp) & 0xFFFFFu) * kUusNs;
  const std::uint32_t fwto = reg32(kGen, kRxFwto) & 0xFFFFFu;
  const bool timeout_enabled = (reg32(kGen, kSysCfg) & kSysCfgRxWtoe) != 0 && fwto > 0;
  const double t_rx_deadline =
      timeout_enabled ? t_rx_on + static_cast<double>(fwto) * kUusNs : std::numeric_limits<double>::infinity();
  const auto timeOut = [this, alive, t_rx_deadline] {
    ++counters_.rx_timeouts;
    if (!std::isfinite(t_rx_deadline)) return;  // receiver stays open: only the host's timeout ends it
    clock_.schedule(static_cast<std::int64_t>(std::ceil(t_rx_deadline)), [this, alive] {
      if (alive()) setStatusBits(kRxFto);
    });
  };

  // The responder's firmware: a poll of our format addressed to it.
  const bool is_poll = poll.size() == 11 && poll[0] == 0x41 && poll[1] == 0x88 && poll[9] == 0xA0 && poll[10] == 1;
  const std::uint16_t pan = is_poll ? static_cast<std::uint16_t>(poll[3] | (poll[4] << 8)) : 0;
  const std::uint16_t dst = is_poll ? static_cast<std::uint16_t>(poll[5] | (poll[6] << 8)) : 0;
  const std::uint16_t src = is_poll ? static_cast<std::uint16_t>(poll[7] | (poll[8] << 8)) : 0;
  const std::uint32_t chan_ctrl = reg32(kFileGen2, kChanCtrl);
  const int channel = (chan_ctrl & 1u) != 0 ? 9 : 5;
  const auto tx_code = static_cast<std::uint8_t>((chan_ctrl >> 3) & 0x1Fu);
  const auto rx_code = static_cast<std::uint8_t>((chan_ctrl >> 8) & 0x1Fu);
  const Dw3000ResponderModel* responder = nullptr;
  for (const Dw3000ResponderModel& r : responders_) {
    if (is_poll && r.present && r.short_address == dst && r.pan_id == pan && r.channel == channel &&
        r.preamble_code == tx_code && r.preamble_code == rx_code) {
      responder = &r;
    }
  }
  if (responder == nullptr || rx_timeout_count_ > 0) {
    if (responder != nullptr) --rx_timeout_count_;
    timeOut();
    return;
  }
  if (receiverNotReady() != nullptr) {  // the start-up left the receiver unable to take the response
    ++counters_.rx_unconfigured;
    timeOut();
    return;
  }
  const Dw3000ResponderModel& r = *responder;
  const double d1 = r.distance_m(static_cast<std::int64_t>(t_departure));
  const double t_arrival_r = t_departure + d1 / kLightMps * 1e9;
  const std::int64_t rx_units_r =
      std::llround(responderDeviceUnits(r, t_arrival_r + r.true_rx_antenna_delay_units / kClockHz * 1e9));
  const std::int64_t poll_rx = rx_units_r - r.rx_antenna_delay;  // unwrapped, its clock
  const std::int64_t reply_units = std::llround(r.reply_delay_us * 1e-6 * kClockHz);
  if (r.reply_delay_us < r.processing_us) {  // its firmware cannot make the deadline
    timeOut();
    return;
  }
  // DX_TIME holds bits 39:8 with bit 8 cleared: the RMARKER leaves on a
  // 512-unit boundary, and the firmware predicts the stamp the same way.
  const std::int64_t tx_raw_r = (poll_rx + reply_units) & ~std::int64_t{0x1FF};
  const std::int64_t resp_tx = tx_raw_r + r.tx_antenna_delay;
  const double t_departure_r = responderTimeOf(r, static_cast<double>(tx_raw_r)) +
                               r.true_tx_antenna_delay_units / kClockHz * 1e9;
  const double d2 = r.distance_m(static_cast<std::int64_t>(t_departure_r));
  const double t_arrival = t_departure_r + d2 / kLightMps * 1e9;
  const std::uint16_t rx_antd = static_cast<std::uint16_t>(reg32(kFileCiaConf, 0x00) & 0xFFFFu);
  const std::int64_t rx_units =
      std::llround(ourDeviceUnits(t_arrival + params_.true_rx_antenna_delay_units / kClockHz * 1e9));
  const std::uint64_t rx_time = static_cast<std::uint64_t>(rx_units - rx_antd) & kMask40;

  const double t_preamble = t_arrival - params_.shr_ns;
  const std::size_t response_length = 21 + 2;
  const double t_frame_end = t_arrival + params_.phr_ns + static_cast<double>(response_length) * params_.ns_per_byte;
  if (t_preamble < t_rx_on) {
    ++counters_.missed_preambles;
    timeOut();
    return;
  }
  if (t_frame_end > t_rx_deadline) {
    timeOut();
    return;
  }

  // The response as the anchors' firmware builds it (docs/uwb-protocol.md).
  std::array<std::uint8_t, 23> frame{};
  frame[0] = 0x41;
  frame[1] = 0x88;
  frame[2] = poll[2];
  frame[3] = static_cast<std::uint8_t>(pan & 0xFFu);
  frame[4] = static_cast<std::uint8_t>(pan >> 8);
  frame[5] = static_cast<std::uint8_t>(src & 0xFFu);
  frame[6] = static_cast<std::uint8_t>(src >> 8);
  frame[7] = static_cast<std::uint8_t>(r.short_address & 0xFFu);
  frame[8] = static_cast<std::uint8_t>(r.short_address >> 8);
  frame[9] = 0xA1;
  frame[10] = 1;
  for (int i = 0; i < 5; ++i) {
    frame[11 + i] = static_cast<std::uint8_t>((static_cast<std::uint64_t>(poll_rx) >> (8 * i)) & 0xFFu);
    frame[16 + i] = static_cast<std::uint8_t>((static_cast<std::uint64_t>(resp_tx) >> (8 * i)) & 0xFFu);
  }

  if (corrupt_count_ > 0 && corrupt_index_ < 21) {
    --corrupt_count_;
    frame[corrupt_index_] ^= corrupt_mask_;
  }

  // Clock offset as our receiver measures it: positive when we are slower.
  const double ratio = 1.0 - (1.0 + params_.clock_ppm * 1e-6) / (1.0 + r.clock_ppm * 1e-6);
  const std::int64_t cia = std::clamp<std::int64_t>(std::llround(ratio * 67108864.0), -4096, 4095);
  const double hz_per_lsb = 998.4e6 / 2.0 / 1024.0 / 131072.0;
  const double ppm_per_hz = channel == 9 ? -1e6 / 7987.2e6 : -1e6 / 6489.6e6;
  const std::int64_t carrier = std::llround(ratio * 1e6 / (hz_per_lsb * ppm_per_hz));
  // Reserved bits above the fields set, so a driver that does not mask fails.
  const std::uint64_t cia_raw = (static_cast<std::uint64_t>(cia) & 0x1FFFu) | (0x5u << 13);
  const std::uint64_t carrier_raw = (static_cast<std::uint64_t>(carrier) & 0x1FFFFFu) | (0x5u << 21) | (0xA5u << 24);

  std::uint32_t error_bits = 0;
  if (rx_error_count_ > 0) {
    --rx_error_count_;
    error_bits = rx_error_bits_;
  }
  Dw3000ExchangeTruth truth;
  truth.valid = true;
  truth.responder = r.short_address;
  truth.distance_m = 0.5 * (d1 + d2);
  truth.reply_s = static_cast<double>(resp_tx - poll_rx) / (kClockHz * (1.0 + r.clock_ppm * 1e-6));
  truth.clock_offset_ratio = ratio;

  // The response's channel, as its CIA diagnostics.
  truth.rx_level_dbm = r.rx_level_at_1m_dbm - 20.0 * std::log10(std::max(d2, 0.1));
  truth.fp_power_dbm = truth.rx_level_dbm - r.nlos_gap_db(static_cast<std::int64_t>(t_arrival));
  const bool dgc_on = (reg32(kFileDgc, kDgcCfg) & 1u) != 0;
  truth.dgc_decision = dgc_on ? static_cast<std::uint8_t>(std::min<int>(r.dgc_decision, 7)) : 0;
  const bool min_diag = (reg32(kFileCiaConf, 0x00) & kCiaConfMinDiag) != 0;  // IP_DIAG not logged
  const CiaDiagnostics diag = min_diag ? CiaDiagnostics{} : diagnosticsFor(truth.rx_level_dbm, truth.fp_power_dbm,
                                             params_.preamble_accumulation_count & 0xFFFu, truth.dgc_decision,
                                             rx_code >= 9);
  clock_.schedule(static_cast<std::int64_t>(std::ceil(t_frame_end)),
                  [this, alive, frame, rx_time, cia_raw, carrier_raw, error_bits, truth, diag, min_diag]() mutable {
                    if (!alive()) return;
                    if (error_bits != 0) {
                      setStatusBits(kRxPrd | kRxSfdd | error_bits);
                      return;
                    }
                    std::copy(frame.begin(), frame.end(), files_[kFileRxBuf].begin());
                    put(kGen, kRxFinfo, frame.size() | (1u << 15), 4);
                    put(kGen, kRxTime, rx_time, 5);
                    put(kFileCia, kCiaDiag0, cia_raw, 4);
                    put(kFileDrx, kDrxDiag3, carrier_raw, 4);
                    // Reserved bits set above every field, and the diagnostics
                    // between F3 and N filled, so unmasked or misaligned reads fail.
                    if (min_diag) {
                      for (std::size_t at = kIpDiag1; at < kIpDiag12 + 4; ++at) files_[kFileCia][at] = 0;
                    } else {
                      put(kFileCia, kIpDiag1, diag.c | (0xA5u << 24), 4);
                      for (std::size_t i = 0; i < 3; ++i) put(kFileCia, kIpDiag2 + 4 * i, diag.f[i] | (0x2Du << 24), 4);
                      for (std::size_t at = kIpDiag2 + 12; at < kIpDiag12; ++at) files_[kFileCia][at] = 0x5A;
                      put(kFileCia, kIpDiag12, (params_.preamble_accumulation_count & 0xFFFu) | (0x3Cu << 16), 4);
                    }
                    put(kFileDgc, kDgcDbg, (std::uint32_t{truth.dgc_decision} << 28) | 0x8123'4567u, 4);
                    truth.rx_good_ns = clock_.nowNs();
                    truth_ = truth;
                    ++counters_.responses_delivered;
                    setStatusBits(kRxPrd | kRxSfdd | kRxPhd | kRxFr | kCiaDone | kRxFcg);
                  });
}

}  // namespace rilo::emu
