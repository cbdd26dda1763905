#pragma once
// The DW3000 start-up as a list of named steps, in the order of Qorvo's
// public C0 API (v04.00.00: dwt_softreset, dwt_initialise, dwt_configure,
// dwt_configuretxrf, dwt_configciadiag), plus ours (SPI CRC, exchange
// timing, interrupts, fast SPI). Dw3000Device::bringUp() runs them and then
// audits every configuration step by reading its registers back, so a step
// that did not take (or was left out) fails the bring-up with its name.
// docs/uwb-protocol.md section 9 lists the steps with their references.
#include <cstdint>
#include <string>

namespace rilo::dw3000 {

enum class BringUpStep : std::uint8_t {
  kReset,             ///< reset line, or the API's soft reset (AON cleared, FOSC forced, SOFT_RST once)
  kIdleRc,            ///< SPIRDY and RCINIT: the chip is in IDLE_RC
  kDevId,             ///< DEV_ID is a DW3110 or DW3120
  kSpiCrc,            ///< optional: SPI CRC on every access from here on
  kLdoBiasTrims,      ///< OTP LDO and bias trims: LDO/BIAS kick, BIAS_CTRL
  kXtalTrim,          ///< OTP crystal trim (0x2E when not programmed) into XTAL
  kFrameFormat,       ///< SYS_CFG, CHAN_CTRL, TX_FCTRL, FINE_PLEN, PAN_ADR
  kOpsTable,          ///< OTP_CFG: kick the operating-parameter set for the preamble length
  kRxTuning,          ///< DTUNE0 (PAC, SFD timeout), DTUNE3, STS_CFG0
  kRfPll,             ///< TX_CTRL_HI, PLL_CFG, RX_CTRL_HI (channel 9), LDO_RLOAD, TX_CTRL_LO, PLL_CAL
  kPllLock,           ///< auto clocks, SEQ_CTRL AINIT2IDLE, then CP_LOCK (IDLE_PLL)
  kDgc,               ///< 64 MHz PRF: DGC table (OTP kick or LUT) and threshold; 16 MHz: DGC off
  kPgfCalibration,    ///< receiver PGF calibration (RX_CAL_*), LDOs on for it
  kTxRf,              ///< TX power and pulse-generator delay
  kCiaDiagnostics,    ///< CIA_CONF MINDIAG cleared: the RX/first-path powers are logged
  kSiteWrites,        ///< extra_init_writes (a site's override, after the vendor's steps)
  kExchangeTiming,    ///< antenna delays, W4R_TIM, RX_FWTO
  kInterrupts,        ///< SYS_STATUS cleared, SYS_ENABLE, IRQ line low
  kFastSpi,           ///< the fast SPI clock, proven by DEV_ID
  kCount,
};

/// A set of steps (bit i = step i).
using BringUpSteps = std::uint32_t;
constexpr BringUpSteps stepBit(BringUpStep s) { return BringUpSteps{1} << static_cast<unsigned>(s); }

/// Short name used in messages ("PLL lock").
const char* stepName(BringUpStep step) noexcept;
/// Where the step comes from: the vendor API function it follows, or "rilo".
const char* stepReference(BringUpStep step) noexcept;

/// What a bring-up engineer needs from one start-up (rilo probe prints it).
struct BringUpReport {
  // OTP (dwt_initialise): raw words and what was applied.
  std::uint32_t otp_ldo_tune_lo = 0;
  std::uint32_t otp_ldo_tune_hi = 0;
  std::uint8_t otp_bias_tune = 0;
  bool ldo_bias_from_otp = false;  ///< false: a word was 0 (not programmed), the chip's defaults stand
  std::uint8_t xtal_trim = 0;      ///< written to XTAL
  bool xtal_trim_from_otp = false; ///< false: OTP held none, the API's default 0x2E
  std::uint32_t otp_part_id = 0;
  std::uint32_t otp_lot_id = 0;
  std::uint8_t otp_revision = 0;
  // PLL
  std::int64_t pll_lock_ns = -1;   ///< AINIT2IDLE to CP_LOCK seen (poll resolution); -1 = not locked
  // DGC
  bool dgc_on = false;             ///< DGC_CFG RX_TUNE_EN after start-up (64 MHz PRF)
  bool dgc_from_otp = false;       ///< the table came from OTP (kick), not from the driver's LUT
  // PGF calibration
  bool pgf_done = false;           ///< RX_CAL_STS read 1
  std::uint32_t pgf_result_i = 0;  ///< RX_CAL_RESI (0x1FFFFFFF = failed)
  std::uint32_t pgf_result_q = 0;  ///< RX_CAL_RESQ
  /// Steps left out on purpose (Dw3000Device::leaveOut).
  BringUpSteps left_out = 0;
};

/// "LDO trims ... from OTP; XTAL trim 0x2E (default: OTP empty); PLL lock
/// ...; DGC ...; PGF calibration ...; part ..., lot ..., OTP revision ..." in
/// one line, for logs
/// (rilod and rilo record log it at every start-up of the chip).
std::string describe(const BringUpReport& report);

}  // namespace rilo::dw3000
