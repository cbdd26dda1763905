#pragma once
// DW3000 register access and the SS-TWR exchange, on the bus interfaces
// (hal::SpiDevice, hal::InterruptLine, an optional reset hal::OutputLine,
// hal::Clock so virtual time works in tests).
//
// bringUp(): the vendor's start-up as named steps (bring_up.h): reset, IDLE_RC,
// DEV_ID, SPI CRC, OTP trims, frame format, OPS table, receiver tuning, RF
// and PLL, PLL lock, DGC, PGF calibration, TX power, CIA diagnostics, then
// ours (antenna delays and exchange timing, interrupts, fast SPI), and an
// audit that reads every configuration step back. Throws Dw3000Error with a
// message naming the device, the step and what was seen.
//
// range(): one poll/response exchange (TX_W4R: the chip opens its receiver
// itself, so Linux latency never enters the ranging timing), never throws,
// never allocates; every status bit it can leave behind is cleared and the
// IRQ line is checked low afterwards. A good exchange also reads the CIA
// diagnostics of the response (one burst, plus DGC_DBG when the DGC is on)
// for its RX level and first-path power (rx_power.h); a failed diagnostics
// read keeps the range and leaves the powers NaN.
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <system_error>

#include "hal/bus/clock.h"
#include "hal/bus/gpio_line.h"
#include "hal/bus/spi_device.h"
#include "hal/dw3000/bring_up.h"
#include "hal/dw3000/dw3000_config.h"
#include "hal/dw3000/rx_power.h"
#include "hal/dw3000/spi_framing.h"
#include "hal/dw3000/ss_twr.h"
#include "hal/dw3000/twr_frame.h"

namespace rilo::dw3000 {

/// Errors of this driver that are not errno values.
enum class Dw3000Errc {
  kReadCrcMismatch = 1,  ///< SPI_RD_CRC differs from the CRC of the bytes we read
  kTooManyBytes,         ///< access longer than the driver's fixed buffers
};
const std::error_category& dw3000Category() noexcept;
std::error_code make_error_code(Dw3000Errc e) noexcept;

/// A bring-up failure: what() names the device path and what was read.
class Dw3000Error : public std::runtime_error {
 public:
  enum class Kind {
    kSpi,
    kBootTimeout,
    kWrongDevId,
    kPllLock,
    kSpiCrc,
    kIrqStuck,
    kFastSpi,
    kCalibration,    ///< the PGF calibration did not finish or reported failure
    kConfiguration,  ///< a step's registers read back other than written (or the step was left out)
  };
  Dw3000Error(Kind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  Kind kind() const noexcept { return kind_; }

 private:
  Kind kind_;
};

enum class ExchangeStatus : std::uint8_t {
  kOk,
  // Link faults: the anchor did not give us a usable range.
  kRxTimeout,         ///< RXFTO / RXPTO: nothing (decodable) arrived in time
  kRxError,           ///< RXPHE, RXFCE, RXFSL, RXSTO, ARFE, CIAERR, RXOVRR
  kBadFrame,          ///< a good frame that is not our response
  kImplausibleRange,  ///< outside [min_range_m, max_range_m]
  // Device faults: the chip or the bus misbehaved.
  kSpiError,      ///< the SPI back-end failed (errno in `error`)
  kSpiCrcError,   ///< SPICRCE (a write arrived corrupted) or a read CRC mismatch
  kIrqWaitError,  ///< the interrupt back-end failed (errno in `error`)
  kTxFailed,      ///< no TXFRS and no RX event: the poll never went out (PLL unlocked?)
  kHostTimeout,   ///< poll sent but no RX event and no timeout from the chip
};
const char* toString(ExchangeStatus status) noexcept;
constexpr bool isDeviceFault(ExchangeStatus s) { return s >= ExchangeStatus::kSpiError; }

/// IRQ line check after clearing SYS_STATUS.
enum class IrqCheck : std::uint8_t {
  kOk,         ///< low
  kRecovered,  ///< was high; a full clear (all bits + CLR_IRQS) brought it low
  kStuck,      ///< still high: the chip needs a reset
};

struct ExchangeResult {
  ExchangeStatus status = ExchangeStatus::kOk;
  IrqCheck irq = IrqCheck::kOk;
  bool missed_edge = false;      ///< the chip finished but no IRQ edge came (t_ns is the host read time)
  std::int64_t t_ns = 0;         ///< host time of the RX-good edge (CLOCK_MONOTONIC), or of the failure
  std::uint32_t sys_status = 0;  ///< SYS_STATUS (low word) that ended the exchange
  double range_m = std::numeric_limits<double>::quiet_NaN();
  double clock_offset_ratio = 0.0;
  TwrTimestamps stamps;
  TwrResult twr;
  FrameError frame_error = FrameError::kOk;
  std::error_code error;         ///< SPI / IRQ back-end error
  /// RX level and first-path power of the response (kOk only; NaN if unread).
  RxPower rx_power;
  /// The CIA diagnostics they come from (zero if unread).
  RxDiagnostics diagnostics;
  /// The diagnostics read of a good exchange failed: the range stands, rx_power is NaN.
  std::error_code diagnostics_error;
};

class Dw3000Device {
 public:
  /// Buses are borrowed and must outlive the device; `reset` may be null (a
  /// soft reset of the vendor API is used then: bring_up.cpp).
  /// Throws std::invalid_argument for a bad configuration.
  Dw3000Device(const Dw3000Config& config, hal::SpiDevice& spi, hal::InterruptLine& irq, hal::OutputLine* reset,
               hal::Clock& clock);

  void bringUp();
  ExchangeResult range(const AnchorConfig& anchor) noexcept;

  /// Leave these start-up steps out of the next bring-ups (the audit still
  /// checks them): how the tests prove each step is needed, and a way to
  /// experiment on a board. kIdleRc, kDevId and the audit cannot be left out.
  void leaveOut(BringUpSteps steps) noexcept { left_out_ = steps; }
  /// What the last bring-up read and applied (OTP trims, PLL lock time, DGC,
  /// PGF calibration); filled as far as it got when bringUp() threw.
  const BringUpReport& bringUpReport() const noexcept { return report_; }

  std::uint32_t devId() const noexcept { return dev_id_; }
  std::uint32_t irqMask() const noexcept { return irq_mask_; }
  bool spiCrcEnabled() const noexcept { return crc_enabled_; }
  /// DGC_CFG RX_TUNE_EN read at bring-up: the DGC decision enters the RX power.
  bool dgcEnabled() const noexcept { return dgc_enabled_; }
  const std::string& path() const noexcept { return spi_.path(); }
  const Dw3000Config& config() const noexcept { return config_; }
  /// Host-side wait budget of one exchange (ns).
  std::int64_t exchangeTimeoutNs() const noexcept { return exchange_timeout_ns_; }

  // Register access (one SPI message each; CRC handled when enabled).
  std::error_code read(RegAddr addr, std::span<std::uint8_t> out) noexcept;
  std::error_code write(RegAddr addr, std::span<const std::uint8_t> data) noexcept;
  std::error_code writeMasked(RegAddr addr, AccessMode mode, std::uint32_t and_mask, std::uint32_t or_mask) noexcept;
  std::error_code fastCommand(std::uint8_t command) noexcept;
  std::error_code read32(RegAddr addr, std::uint32_t& value) noexcept;
  std::error_code write32(RegAddr addr, std::uint32_t value) noexcept;
  std::error_code write16(RegAddr addr, std::uint16_t value) noexcept;
  std::error_code write8(RegAddr addr, std::uint8_t value) noexcept { return write(addr, {&value, 1}); }

 private:
  static constexpr std::size_t kMaxAccess = 128;  // longest register/buffer access

  [[noreturn]] void fail(Dw3000Error::Kind kind, const std::string& what) const;
  void check(std::error_code e, const char* step) const;
  // Start-up (bring_up.cpp).
  void runStep(BringUpStep step);
  void resetChip();
  void softReset();
  void readOtpTrimWords();
  void readOtpOtherWords();
  void applyOtpTrims();
  void applyXtalTrim();
  void applyFrameFormat();
  void applyOpsTable();
  void applyRxTuning();
  void applyRfPll();
  void lockPll();
  void applyDgc();
  void calibratePgf();
  void applyTxRf();
  void applyCiaDiagnostics();
  void applySiteWrites();
  void applyExchangeTiming();
  void applyInterrupts();
  void raiseSpiClock();
  /// Empty if the step's registers hold what it writes, else what differs.
  std::string auditStep(BringUpStep step);
  /// "; step 'x' (ref) did not take: ..." for the first step in [from, to)
  /// whose registers differ, or "" (never throws: a failed read is said).
  std::string firstStepNotInEffect(BringUpStep from, BringUpStep to);
  std::uint32_t otpRead(std::uint16_t address, const char* what);
  std::uint32_t exchangeInterrupts() const noexcept;
  std::uint32_t readReg32(RegAddr addr, const char* what);
  std::uint8_t readReg8(RegAddr addr, const char* what);
  std::uint32_t waitStatus(std::uint32_t bits, std::int64_t timeout_ns, const char* step);
  std::error_code clearAllStatus() noexcept;
  std::error_code drainEdges() noexcept;
  IrqCheck clearAndCheckIrq(std::uint32_t seen_status) noexcept;
  void abortExchange(ExchangeResult& r, std::uint32_t seen_status) noexcept;
  void readResponse(const AnchorConfig& anchor, std::uint8_t sequence, ExchangeResult& r) noexcept;
  void readRxPower(ExchangeResult& r) noexcept;

  Dw3000Config config_;
  hal::SpiDevice& spi_;
  hal::InterruptLine& irq_;
  hal::OutputLine* reset_;
  hal::Clock& clock_;
  bool crc_enabled_ = false;
  bool soft_reset_crc_ = false;  // the CRC mode the last soft reset was written in
  bool dgc_enabled_ = false;
  bool prf64_ = true;
  std::uint32_t dev_id_ = 0;
  std::uint32_t irq_mask_ = 0;
  std::uint8_t sequence_ = 0;
  std::int64_t exchange_timeout_ns_ = 0;
  BringUpSteps left_out_ = 0;
  BringUpReport report_;
};

}  // namespace rilo::dw3000

template <>
struct std::is_error_code_enum<rilo::dw3000::Dw3000Errc> : std::true_type {};
