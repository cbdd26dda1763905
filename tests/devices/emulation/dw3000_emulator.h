#pragma once
// Register-level DW3000 emulator behind hal::SpiDevice, with simulated SS-TWR
// responders (the anchors' firmware of docs/uwb-protocol.md).
//
// What is modelled:
//  - SPI framing parsed byte by byte per chip-select frame: short/extended
//    headers, plain and masked (AND-OR 8/16/32) writes, fast commands, SPI
//    CRC (CRC-8 on writes, SPI_RD_CRC after reads) once SYS_CFG enables it;
//  - register files with read-only registers, SYS_STATUS write-1-to-clear,
//    IRQ level = any enabled status bit set, driven onto an
//    EmulatedInterruptLine;
//  - reset through an EmulatedOutputLine, or SOFT_RST written 0x00 once (as
//    Qorvo's dwt_softreset): INIT_RC for `boot_ns`, then SPIRDY + RCINIT
//    (IDLE_RC). A soft reset while the system clock runs on the PLL (not
//    forced to FOSC first) hangs the chip until a hard reset. SPI clock
//    limits per state (7 MHz until IDLE_RC) counted as violations;
//  - OTP memory (Dw3000Otp) read through OTP_ADDR / OTP_CFG / OTP_RDATA; the
//    OTP_CFG kicks load the LDO trims (LDO_TUNE_LO/HI), the OPS table and the
//    DGC table (when OTP holds one) and clear themselves;
//  - the start-up's preconditions (the vendor's order, bring_up.h):
//    CP_LOCK only after SEQ_CTRL AINIT2IDLE is set with the clocks on auto
//    and PLL_CFG holding the channel's value (`pll_lock_ns` later, IDLE_PLL);
//    no response received (the receiver times out) unless the LDO/bias
//    trims, the OPS table for the preamble length, DTUNE0/DTUNE3, the RF
//    settings of the channel, the DGC set-up of the PRF and a good PGF
//    calibration (which needs the receiver LDOs on) are all in place; the
//    CIA diagnostics read zero while CIA_CONF MINDIAG is set (its reset
//    value). Register reset values the vendor's code implies but does not
//    state are ours: MINDIAG and DGC_CFG RX_TUNE_EN set, RX_CAL_RESI/RESQ at
//    the failure value 0x1FFFFFFF until a calibration, CLK_CTRL 0x0200;
//  - a 40-bit device clock running `clock_ppm` off the VirtualClock (wraps);
//  - TX_W4R: poll RMARKER, TXFRS, the receiver opening W4R_TIM after the
//    poll, RX_FWTO; the addressed responder receives the poll at the true
//    (possibly time-varying) distance, answers at its reply delay with its
//    own clock offset and antenna delays, quantized like DX_TIME (low 9 bits
//    zero); RX_TIME / TX_TIME / RX buffer / RX_FINFO / CIA_DIAG_0 /
//    DRX_DIAG3 are filled and RXFCG raised at the frame end;
//  - the response's channel: RX level falling 20 log10(d) from the
//    responder's level at 1 m, first-path power below it by the responder's
//    (time-varying) NLOS gap; served as the CIA diagnostics the user manual's
//    formulas read back (IP_DIAG_1..4 and 12, DGC_DBG's decision when the
//    driver set DGC_CFG RX_TUNE_EN), quantized like the chip's registers;
//  - injected faults: RX errors, lost responses, SPI CRC errors on writes or
//    reads, PLL lock failure or loss, a stuck IRQ line, failing transfers,
//    no boot, wrong DEV_ID.
// Air times are fixed parameters (not derived from the configured preamble).
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <string>
#include <system_error>
#include <vector>

#include "devices/emulation/virtual_time.h"
#include "hal/bus/spi_device.h"

namespace rilo::emu {

struct Dw3000ResponderModel {
  std::uint16_t short_address = 0x0001;
  std::uint16_t pan_id = 0xDECA;
  int channel = 5;
  std::uint8_t preamble_code = 9;
  bool present = true;  ///< false: out of range / switched off
  /// True distance (m) at virtual time t_ns.
  std::function<double(std::int64_t t_ns)> distance_m = [](std::int64_t) { return 5.0; };
  double clock_ppm = 0.0;  ///< its crystal vs true time
  std::uint64_t initial_device_time = 0;  ///< its (unwrapped) device time at virtual time 0
  double true_tx_antenna_delay_units = 16385.0;  ///< physical delays (device units)
  double true_rx_antenna_delay_units = 16385.0;
  std::uint16_t tx_antenna_delay = 16385;  ///< its firmware's configured delays
  std::uint16_t rx_antenna_delay = 16385;
  double reply_delay_us = 500.0;  ///< its firmware's poll-RX to response-TX delay
  double processing_us = 150.0;   ///< firmware needs this long to schedule the response
  /// RX level of its response at 1 m (dBm); falls 20 log10(d) (free space).
  /// -63 dBm: -14.3 dBm EIRP (-41.3 dBm/MHz over 500 MHz) minus 48.7 dB at 6.5 GHz.
  double rx_level_at_1m_dbm = -63.0;
  /// RX level minus first-path power (dB) at virtual time t_ns: small in line
  /// of sight, above ~6 dB when the direct path is blocked (APS006).
  std::function<double(std::int64_t t_ns)> nlos_gap_db = [](std::int64_t) { return 2.0; };
  /// DGC_DECISION (0..7) reported while the DGC is on (64 MHz PRF): the chip
  /// lowered its gain by 6 dB per step, the registers read that much less.
  /// 0: full gain, as for the weak signals of most links.
  std::uint8_t dgc_decision = 0;
};

/// The chip's OTP words that the start-up reads (made-up values: real parts
/// differ; 0 = not programmed).
struct Dw3000Otp {
  std::uint32_t ldo_tune_lo = 0x2A6B4C38;   ///< word 0x04
  std::uint32_t ldo_tune_hi = 0x00A75C14;   ///< word 0x05
  std::uint32_t part_id = 0x1C0A2B17;       ///< word 0x06
  std::uint32_t lot_id = 0x0004F3E1;        ///< word 0x07
  std::uint32_t bias_tune_word = 0x0013'0000;  ///< word 0x0A: bias trim 0x13 in bits 20:16
  std::uint32_t xtal_trim = 0x1B;           ///< word 0x1E (bits 6:0)
  std::uint32_t revision = 0x02;            ///< word 0x1F
  bool dgc_table = false;                   ///< word 0x20 holds 0x10000240: the DGC table is in OTP
  /// The part's own DGC table (DGC_LUT_0..6 for channel 5, then 9) that the
  /// kick loads: not the API's (made-up values).
  std::array<std::uint32_t, 14> dgc_lut{0x1C0F1, 0x1C431, 0x1C6B1, 0x1C771, 0x1CF31, 0x1CFB1, 0x1CFF1,
                                        0x2A8F1, 0x2AC31, 0x2A5F1, 0x2AF31, 0x2AF71, 0x2AFB1, 0x2AFB1};
};

struct Dw3000EmulatorParams {
  std::string name = "emu:spidev0.0";
  std::uint32_t dev_id = 0xDECA0302;
  double clock_ppm = 0.0;                 ///< our crystal vs true time
  std::uint64_t initial_device_time = 0;  ///< device time at each boot (set near 2^40 to test wraps)
  double true_tx_antenna_delay_units = 16385.0;
  double true_rx_antenna_delay_units = 16385.0;
  std::int64_t boot_ns = 1'500'000;   ///< reset release -> SPIRDY/RCINIT
  std::int64_t pll_lock_ns = 50'000;  ///< CHAN_CTRL write -> CP_LOCK
  double tx_startup_ns = 5'000.0;     ///< TX_W4R -> start of the preamble
  double shr_ns = 138'400.0;          ///< preamble + SFD (128 + 8 symbols at 64 MHz PRF)
  double phr_ns = 24'700.0;           ///< PHR at 850 kb/s
  double ns_per_byte = 1'350.0;       ///< payload at 6.8 Mb/s with Reed-Solomon parity
  std::uint32_t max_slow_spi_hz = 7'000'000;  ///< until IDLE_RC
  std::uint32_t max_spi_hz = 20'000'000;      ///< afterwards (UNVERIFIED on hardware)
  std::uint32_t preamble_accumulation_count = 119;  ///< IP_DIAG_12 (N) of every response
  Dw3000Otp otp;
  std::int64_t pgf_cal_ns = 15'000;         ///< PGF calibration start -> RX_CAL_STS (the API polls 3 x 20 us)
  std::uint32_t pgf_result_i = 0x0001'2C4A; ///< RX_CAL_RESI / RESQ of a good calibration
  std::uint32_t pgf_result_q = 0x0001'2B97;
};

/// How an injected stuck IRQ is released.
enum class StuckIrq { kUntilFullClear, kUntilReset };

struct Dw3000EmulatorCounters {
  std::uint64_t messages = 0;
  std::uint64_t speed_violations = 0;
  std::uint64_t tx_w4r = 0;
  std::uint64_t tx_while_unlocked = 0;
  std::uint64_t responses_delivered = 0;
  std::uint64_t rx_timeouts = 0;
  std::uint64_t missed_preambles = 0;   ///< response started before our receiver opened
  std::uint64_t write_crc_errors = 0;   ///< SPICRCE raised
  std::uint64_t read_corruptions = 0;
  std::uint64_t status_clears = 0;      ///< writes to SYS_STATUS
  std::uint64_t clr_irqs = 0;
  std::uint64_t trxoff = 0;
  std::uint64_t resets = 0;
  std::uint64_t boots = 0;
  std::uint64_t pll_locks = 0;
  std::uint64_t unsupported = 0;        ///< malformed frames or unknown fast commands
  std::uint64_t otp_reads = 0;
  std::uint64_t pll_refusals = 0;       ///< AINIT2IDLE set without the PLL configuration or auto clocks
  std::uint64_t soft_reset_hangs = 0;   ///< SOFT_RST with the system clock on the PLL
  std::uint64_t pgf_calibrations = 0;
  std::uint64_t rx_unconfigured = 0;    ///< responses the receiver could not take (start-up incomplete)
};

/// Ground truth of the last exchange delivered to the driver.
struct Dw3000ExchangeTruth {
  bool valid = false;
  std::uint16_t responder = 0;
  double distance_m = 0.0;         ///< mean of the two flights
  double reply_s = 0.0;            ///< the responder's reply time, in true seconds
  double clock_offset_ratio = 0.0; ///< 1 - (1 + e_ours) / (1 + e_responder)
  std::int64_t rx_good_ns = 0;     ///< virtual time RXFCG was raised
  double rx_level_dbm = 0.0;       ///< the response's RX level (before register quantization)
  double fp_power_dbm = 0.0;       ///< its first-path power
  std::uint8_t dgc_decision = 0;   ///< DGC_DECISION served (0 with the DGC off)
};

class Dw3000Emulator final : public hal::SpiDevice {
 public:
  enum class State { kReset, kInitRc, kIdleRc, kIdlePll };

  /// `reset` may be null (SOFT_RST only). The chip starts booting at once.
  Dw3000Emulator(VirtualClock& clock, EmulatedInterruptLine& irq, EmulatedOutputLine* reset,
                 Dw3000EmulatorParams params = {});

  std::error_code transfer(std::span<const hal::SpiTransfer> transfers) noexcept override;
  std::error_code setSpeedHz(std::uint32_t speed_hz) noexcept override;
  const std::string& path() const noexcept override { return params_.name; }

  std::size_t addResponder(Dw3000ResponderModel model);
  Dw3000ResponderModel& responder(std::size_t index) { return responders_.at(index); }

  // Fault injection.
  void injectRxErrors(std::uint32_t status_bits, int count) { rx_error_bits_ = status_bits; rx_error_count_ = count; }
  void injectRxTimeouts(int count) { rx_timeout_count_ = count; }
  void injectWriteCrcErrors(int count) { write_crc_error_count_ = count; }
  void injectReadCrcErrors(int count) { read_crc_error_count_ = count; }
  void injectPllLockFailures(int count) { pll_failure_count_ = count; }
  void injectPllLossOfLock();
  /// The next `count` responses arrive with byte `index` XORed with `mask`
  /// (and a good FCS): a foreign or buggy responder.
  void injectResponseCorruption(std::size_t index, std::uint8_t mask, int count) {
    corrupt_index_ = index;
    corrupt_mask_ = mask;
    corrupt_count_ = count;
  }
  /// The line stays high after the next event, however the bits are cleared,
  /// until released as `mode` says.
  void injectStuckIrq(StuckIrq mode) { stuck_armed_ = true; stuck_mode_ = mode; }
  void failNextTransfers(int count, std::error_code error) { fail_count_ = count; fail_error_ = error; }
  /// The next `count` SPI messages that read register (file, offset) fail with `error`.
  void failReadsOf(std::uint8_t file, std::uint8_t offset, int count, std::error_code error) {
    read_fail_file_ = file;
    read_fail_offset_ = offset;
    read_fail_count_ = count;
    read_fail_error_ = error;
  }
  void setNeverBoots(bool never) { never_boots_ = never; }
  void setDevId(std::uint32_t dev_id) { params_.dev_id = dev_id; }

  // Observation.
  State state() const { return state_; }
  std::uint32_t speedHz() const { return speed_hz_; }
  const Dw3000EmulatorCounters& counters() const { return counters_; }
  const Dw3000ExchangeTruth& lastExchange() const { return truth_; }
  std::uint64_t status() const;
  std::uint32_t enabledInterrupts() const;
  bool spiCrcActive() const { return crc_active_; }
  std::uint32_t peek32(std::uint8_t file, std::uint8_t offset) const;
  /// Our device time now (40 bit).
  std::uint64_t deviceTimeNow() const;
  /// The first start-up item the receiver still lacks ("OPS table"), or
  /// nullptr when it can receive.
  const char* receiverNotReady() const;

 private:
  void enterReset();
  void startBoot();
  void processFrame(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx);
  void applyWrite(std::uint8_t file, std::size_t offset, std::span<const std::uint8_t> data);
  std::uint8_t readByte(std::uint8_t file, std::size_t offset) const;
  void fastCommand(std::uint8_t command);
  void startExchange();
  void relockPll();
  void onOtpCfgWrite(std::uint32_t before);
  void onRxCalCfgWrite();
  void onSoftReset();
  void setStatusBits(std::uint64_t bits);
  void clearStatusBits(std::uint64_t bits);
  void updateIrq();
  std::uint32_t reg32(std::uint8_t file, std::size_t offset) const;
  void put(std::uint8_t file, std::size_t offset, std::uint64_t value, std::size_t bytes);
  double ourDeviceUnits(double t_ns) const;        // unwrapped
  double responderDeviceUnits(const Dw3000ResponderModel& r, double t_ns) const;
  double responderTimeOf(const Dw3000ResponderModel& r, double units) const;
  std::uint32_t spiLimitHz() const;

  VirtualClock& clock_;
  EmulatedInterruptLine& irq_;
  Dw3000EmulatorParams params_;
  std::vector<Dw3000ResponderModel> responders_;
  std::array<std::vector<std::uint8_t>, 32> files_;
  State state_ = State::kInitRc;
  std::uint64_t generation_ = 0;  // bumped by reset: stale events do nothing
  std::uint64_t exchange_ = 0;    // bumped by TRXOFF / new exchange
  std::int64_t boot_ns_ = 0;      // virtual time of the last boot
  std::uint32_t speed_hz_ = 1'000'000;
  bool crc_active_ = false;
  Dw3000EmulatorCounters counters_;
  Dw3000ExchangeTruth truth_;

  std::uint32_t rx_error_bits_ = 0;
  int rx_error_count_ = 0;
  int rx_timeout_count_ = 0;
  int write_crc_error_count_ = 0;
  int read_crc_error_count_ = 0;
  int pll_failure_count_ = 0;
  bool stuck_armed_ = false;
  bool stuck_active_ = false;
  StuckIrq stuck_mode_ = StuckIrq::kUntilFullClear;
  int fail_count_ = 0;
  std::error_code fail_error_;
  std::uint8_t read_fail_file_ = 0;
  std::uint8_t read_fail_offset_ = 0;
  int read_fail_count_ = 0;
  std::error_code read_fail_error_;
  bool never_boots_ = false;
  bool hung_ = false;          // a soft reset with the clock on the PLL: only a hard reset helps
  bool ldo_kicked_ = false;
  bool ops_kicked_ = false;
  bool dgc_kicked_ = false;    // the DGC table came from OTP
  std::uint32_t ops_set_ = 0;  // OTP_CFG OPS_ID of the last kick
  std::size_t corrupt_index_ = 0;
  std::uint8_t corrupt_mask_ = 0;
  int corrupt_count_ = 0;
};

}  // namespace rilo::emu
