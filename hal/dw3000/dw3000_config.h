#pragma once
// Configuration of the DWM3000 SS-TWR initiator: radio, addressing, timing,
// calibration, SPI, bring-up, scheduling and fault handling. Defaults are
// starting points; items marked UNVERIFIED must be checked on the board.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "hal/dw3000/anchor_scheduler.h"
#include "hal/dw3000/clock_offset.h"
#include "hal/dw3000/registers.h"

namespace rilo::dw3000 {

enum class DataRate : std::uint8_t { k850k, k6M8 };

/// Where the clock offset ratio used by SS-TWR comes from.
enum class ClockOffsetSource : std::uint8_t {
  kCiaDiag0,           ///< CIA_DIAG_0, 13-bit / 2^26
  kCarrierIntegrator,  ///< DRX_DIAG3, 21-bit carrier integrator
  kNone,               ///< uncorrected (diagnostics only)
};

struct AnchorConfig {
  std::uint32_t id = 0;             ///< RangeSample::anchor_id (anchors.csv id)
  std::uint16_t short_address = 0;  ///< 802.15.4 short address of its responder
};

/// A register write applied at bring-up after the vendor's start-up steps,
/// in order: a site's override of what bring_up.cpp writes (the trims
/// themselves come from the chip's OTP). Empty by default.
struct RegisterWrite {
  RegAddr addr{};
  std::uint32_t value = 0;
  std::uint8_t length = 4;  ///< 1..4 bytes, little-endian
};

struct Dw3000Config {
  // Radio
  UwbChannel channel = UwbChannel::k5;
  std::uint8_t preamble_code = 9;        ///< TX and RX code; 9-12 are the 64 MHz PRF codes
  std::uint16_t preamble_length = 128;   ///< symbols: 32, 64, 72, 128, 256, 512, 1024, 1536, 2048, 4096
  DataRate data_rate = DataRate::k6M8;
  std::uint8_t sfd_type = 1;             ///< CHAN_CTRL SFD_TYPE 0..3 (1 = Decawave 8-symbol, UNVERIFIED choice)
  /// Preamble acquisition chunk (symbols: 4, 8, 16, 32; DTUNE0). The API's
  /// guidance: 8 for 128-symbol preambles, 16-32 for longer ones.
  std::uint8_t pac_symbols = 8;
  /// SFD detection timeout (symbols; DTUNE0). 0: preamble length + 1 +
  /// SFD length - PAC, the API examples' formula (129 at 128 symbols, PAC 8).
  std::uint16_t sfd_timeout_symbols = 0;

  // Addressing: our short address and the anchors' (their responders must
  // run the protocol of docs/uwb-protocol.md with the same PAN id).
  std::uint16_t pan_id = 0xDECA;
  std::uint16_t tag_address = 0x8000;
  std::uint32_t tag_id = 0;  ///< RangeSample::tag_id (tags.csv id, 0 = single antenna)
  std::vector<AnchorConfig> anchors;

  // Calibration: antenna delays in device units (15.65 ps), written to
  // TX_ANTD and CIA_CONF; the chip applies them to TX_TIME / RX_TIME.
  std::uint16_t tx_antenna_delay = 16385;
  std::uint16_t rx_antenna_delay = 16385;

  // Transmitter (dwt_configuretxrf): pulse-generator delay (TX_CTRL_HI bits
  // 5:0) and TX_POWER (four 8-bit settings: CP, SHR, PHR, data). Defaults are
  // the API examples' for channel 5; UNVERIFIED against the regulatory mask
  // of a given board and antenna.
  std::uint8_t tx_pg_delay = 0x34;
  std::uint32_t tx_power = 0xFDFDFDFD;
  ClockOffsetSource clock_offset_source = ClockOffsetSource::kCiaDiag0;

  // Exchange timing. The responder sends its response `reply_delay_us` after
  // receiving the poll (RMARKER to RMARKER); the anchors must use the same
  // value. The range error from a residual clock offset grows with it
  // (c * Treply * e / 2). Our receiver opens `rx_after_tx_delay_us` after the
  // poll is sent and waits at most `rx_timeout_us` for the response.
  double reply_delay_us = 500.0;
  double rx_after_tx_delay_us = 250.0;
  double rx_timeout_us = 500.0;
  /// Extra host-side wait for the IRQ beyond the chip's own timeout.
  std::int64_t irq_wait_margin_ns = 2'000'000;

  // SPI: slow until the chip is configured (<= 7 MHz), then fast.
  std::uint32_t spi_slow_hz = 2'000'000;
  std::uint32_t spi_fast_hz = 16'000'000;  ///< UNVERIFIED maximum (~20 MHz per the notes)
  bool spi_crc = false;                    ///< SYS_CFG SPI_CRC: CRC-8 on writes and checked reads

  // Bring-up
  std::int64_t reset_low_ns = 1'000'000;      ///< RSTn held low
  std::int64_t boot_timeout_ns = 10'000'000;  ///< for SPIRDY and RCINIT after release (~2 ms typical)
  /// AINIT2IDLE -> CP_LOCK. The C0 API polls 6 x 20 us; Qorvo's newer driver
  /// allows ~1 ms ("on some corners with ch9 it can take ~900us").
  std::int64_t pll_lock_timeout_ns = 2'000'000;
  std::int64_t pgf_timeout_ns = 1'000'000;       ///< PGF calibration start -> RX_CAL_STS (the API: 3 x 20 us)
  std::int64_t poll_interval_ns = 100'000;    ///< status polling during bring-up
  /// Read every start-up step's registers back and fail the bring-up on a
  /// difference (bring_up.h). The read-backs are proven on the emulator only:
  /// false lets a board whose chip reads some register back differently come
  /// up while that is investigated (the PLL lock and PGF checks stay).
  bool startup_audit = true;
  std::vector<RegisterWrite> extra_init_writes;

  // Plausible range window: anything outside is discarded and counted.
  double min_range_m = -1.0;
  double max_range_m = 300.0;

  // Scheduling (strongest-N, rediscovery, per-anchor back-off).
  AnchorSchedulerParams scheduler;

  // Device faults (SPI, SPI CRC, PLL, IRQ): back-off doubling from the
  // initial delay; re-initialize after this many consecutive faults (PLL and
  // a stuck IRQ re-initialize at once).
  std::int64_t device_backoff_initial_ns = 10'000'000;
  std::int64_t device_backoff_max_ns = 5'000'000'000;
  int device_faults_before_reinit = 3;
  int startup_attempts = 3;     ///< bring-up attempts before run() gives up (fatal)
  int max_reinit_failures = 0;  ///< consecutive failed re-inits before giving up; 0 = never
};

/// Throws std::invalid_argument naming the first bad parameter.
void validateConfig(const Dw3000Config& config);

/// Estimated air times (802.15.4z HRP, +-10%): the synchronization header
/// (preamble + SFD) before the RMARKER, and PHR + payload after it for a
/// frame of `bytes_with_fcs`. Used to check that the receiver opens before
/// the response's preamble starts.
double shrDurationUs(const Dw3000Config& config) noexcept;
double payloadAirtimeUs(const Dw3000Config& config, std::size_t bytes_with_fcs) noexcept;

/// TX_FCTRL TXPSR code of a preamble length (Qorvo driver codes), or -1.
int preambleLengthCode(std::uint16_t preamble_length) noexcept;
/// DTUNE0 PRE_PAC_SYM code of a PAC size (8 -> 0, 16 -> 1, 32 -> 2, 4 -> 3), or -1.
int pacCode(std::uint8_t pac_symbols) noexcept;
/// The SFD timeout written to DTUNE0 (symbols), sfd_timeout_symbols or its default.
std::uint16_t sfdTimeoutSymbols(const Dw3000Config& config) noexcept;

}  // namespace rilo::dw3000
