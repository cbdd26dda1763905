#include "hal/dw3000/dw3000_device.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "hal/dw3000/clock_offset.h"
#include "hal/dw3000/registers.h"
#include "hal/dw3000/text.h"
#include "hal/dw3000/timestamp.h"

namespace rilo::dw3000 {
namespace {

class Dw3000Category final : public std::error_category {
 public:
  const char* name() const noexcept override { return "dw3000"; }
  std::string message(int value) const override {
    switch (static_cast<Dw3000Errc>(value)) {
      case Dw3000Errc::kReadCrcMismatch: return "SPI read CRC mismatch";
      case Dw3000Errc::kTooManyBytes: return "SPI access longer than the driver's buffers";
    }
    return "unknown dw3000 error";
  }
};

std::uint32_t le32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}

void putLe(std::uint32_t v, std::uint8_t* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) p[i] = static_cast<std::uint8_t>((v >> (8 * i)) & 0xFFu);
}

// Events that end an exchange (the interrupt mask, SPICRCE added with CRC).
constexpr std::uint32_t kExchangeEnd = status::kRxFcg | status::kAllRxErrors | status::kAllRxTimeouts;

}  // namespace

const std::error_category& dw3000Category() noexcept {
  static const Dw3000Category category;
  return category;
}

std::error_code make_error_code(Dw3000Errc e) noexcept { return {static_cast<int>(e), dw3000Category()}; }

const char* toString(ExchangeStatus status) noexcept {
  switch (status) {
    case ExchangeStatus::kOk: return "ok";
    case ExchangeStatus::kRxTimeout: return "RX timeout";
    case ExchangeStatus::kRxError: return "RX error";
    case ExchangeStatus::kBadFrame: return "unexpected frame";
    case ExchangeStatus::kImplausibleRange: return "implausible range";
    case ExchangeStatus::kSpiError: return "SPI error";
    case ExchangeStatus::kSpiCrcError: return "SPI CRC error";
    case ExchangeStatus::kIrqWaitError: return "IRQ wait error";
    case ExchangeStatus::kTxFailed: return "poll not transmitted";
    case ExchangeStatus::kHostTimeout: return "no IRQ and no RX event";
  }
  return "?";
}

Dw3000Device::Dw3000Device(const Dw3000Config& config, hal::SpiDevice& spi, hal::InterruptLine& irq,
                           hal::OutputLine* reset, hal::Clock& clock)
    : config_(config), spi_(spi), irq_(irq), reset_(reset), clock_(clock) {
  validateConfig(config_);
  prf64_ = config_.preamble_code >= 9;  // codes 9..24 are the 64 MHz PRF ones
  const double budget_us = shrDurationUs(config_) + payloadAirtimeUs(config_, kPollLength + kFcsLength) +
                           config_.rx_after_tx_delay_us + config_.rx_timeout_us;
  exchange_timeout_ns_ = static_cast<std::int64_t>(std::ceil(budget_us * 1e3)) + config_.irq_wait_margin_ns;
}

// ---------------------------------------------------------------------------
// Register access

std::error_code Dw3000Device::read(RegAddr addr, std::span<std::uint8_t> out) noexcept {
  if (out.size() > kMaxAccess) return make_error_code(Dw3000Errc::kTooManyBytes);
  const SpiHeader header = encodeHeader(addr, false);
  const std::array<hal::SpiTransfer, 2> xfers{{{header.bytes.data(), nullptr, header.size, false},
                                               {nullptr, out.data(), out.size(), false}}};
  if (const std::error_code e = spi_.transfer(xfers)) return e;
  if (crc_enabled_ && !(addr == reg::kSpiRdCrc)) {
    // The chip keeps the CRC of the last read (header and data) in SPI_RD_CRC.
    const std::uint8_t expected = crc8(out, crc8(header.view()));
    std::uint8_t reported = 0;
    if (const std::error_code e = read(reg::kSpiRdCrc, {&reported, 1})) return e;
    if (reported != expected) return make_error_code(Dw3000Errc::kReadCrcMismatch);
  }
  return {};
}

std::error_code Dw3000Device::write(RegAddr addr, std::span<const std::uint8_t> data) noexcept {
  if (data.size() > kMaxAccess) return make_error_code(Dw3000Errc::kTooManyBytes);
  const SpiHeader header = encodeHeader(addr, true);
  std::uint8_t crc = 0;
  std::size_t count = 2;
  if (crc_enabled_) {
    crc = crc8(data, crc8(header.view()));
    count = 3;
  }
  const std::array<hal::SpiTransfer, 3> xfers{{{header.bytes.data(), nullptr, header.size, false},
                                               {data.data(), nullptr, data.size(), false},
                                               {&crc, nullptr, 1, false}}};
  return spi_.transfer(std::span<const hal::SpiTransfer>(xfers.data(), count));
}

std::error_code Dw3000Device::writeMasked(RegAddr addr, AccessMode mode, std::uint32_t and_mask,
                                          std::uint32_t or_mask) noexcept {
  const std::size_t body_size = maskedBodySize(mode);
  if (body_size == 0) return std::make_error_code(std::errc::invalid_argument);
  const std::size_t width = body_size / 2;
  const SpiHeader header = encodeHeader(addr, true, mode);
  std::array<std::uint8_t, 9> body{};
  putLe(and_mask, body.data(), width);
  putLe(or_mask, body.data() + width, width);
  std::size_t size = body_size;
  if (crc_enabled_) body[size++] = crc8({body.data(), body_size}, crc8(header.view()));
  const std::array<hal::SpiTransfer, 2> xfers{{{header.bytes.data(), nullptr, header.size, false},
                                               {body.data(), nullptr, size, false}}};
  return spi_.transfer(xfers);
}

std::error_code Dw3000Device::fastCommand(std::uint8_t command) noexcept {
  const std::uint8_t byte = encodeFastCommand(command);
  const std::array<hal::SpiTransfer, 1> xfers{{{&byte, nullptr, 1, false}}};
  return spi_.transfer(xfers);
}

std::error_code Dw3000Device::read32(RegAddr addr, std::uint32_t& value) noexcept {
  std::array<std::uint8_t, 4> bytes{};
  const std::error_code e = read(addr, bytes);
  value = le32(bytes.data());
  return e;
}

std::error_code Dw3000Device::write32(RegAddr addr, std::uint32_t value) noexcept {
  std::array<std::uint8_t, 4> bytes{};
  putLe(value, bytes.data(), 4);
  return write(addr, bytes);
}

std::error_code Dw3000Device::write16(RegAddr addr, std::uint16_t value) noexcept {
  std::array<std::uint8_t, 2> bytes{};
  putLe(value, bytes.data(), 2);
  return write(addr, bytes);
}

std::uint32_t Dw3000Device::exchangeInterrupts() const noexcept {
  return kExchangeEnd | (crc_enabled_ ? status::kSpiCrcE : 0u);
}

// ---------------------------------------------------------------------------
// Bring-up helpers (the steps are in bring_up.cpp)

void Dw3000Device::fail(Dw3000Error::Kind kind, const std::string& what) const {
  throw Dw3000Error(kind, "dw3000 " + spi_.path() + ": " + what);
}

void Dw3000Device::check(std::error_code e, const char* step) const {
  if (!e) return;
  const auto kind = e == Dw3000Errc::kReadCrcMismatch ? Dw3000Error::Kind::kSpiCrc : Dw3000Error::Kind::kSpi;
  fail(kind, std::string("SPI failed while ") + step + ": " + e.message());
}

std::uint32_t Dw3000Device::waitStatus(std::uint32_t bits, std::int64_t timeout_ns, const char* step) {
  const std::int64_t deadline_ns = clock_.nowNs() + timeout_ns;
  std::uint32_t st = 0;
  for (;;) {
    check(read32(reg::kSysStatus, st), step);
    if ((st & bits) == bits || clock_.nowNs() >= deadline_ns) return st;
    clock_.sleepForNs(config_.poll_interval_ns);
  }
}

std::error_code Dw3000Device::clearAllStatus() noexcept {
  if (const std::error_code e = write32(reg::kSysStatus, 0xFFFF'FFFFu)) return e;
  return write16(reg::kSysStatusHi, 0xFFFF);
}

std::error_code Dw3000Device::drainEdges() noexcept {
  // Stale edges (from before the last clear) would end the next wait early.
  hal::EdgeEvent event;
  std::error_code error;
  for (int i = 0; i < 32; ++i) {
    const hal::WaitResult w = irq_.waitEdge(std::chrono::nanoseconds(0), event, error);
    if (w == hal::WaitResult::kError) return error ? error : std::make_error_code(std::errc::io_error);
    if (w != hal::WaitResult::kEdge) break;
  }
  return {};
}

// ---------------------------------------------------------------------------
// Ranging

IrqCheck Dw3000Device::clearAndCheckIrq(std::uint32_t seen_status) noexcept {
  // Every bit we saw, every event an exchange can raise and every enabled
  // bit: an enabled bit left set holds the line high and no edge ever comes.
  (void)write32(reg::kSysStatus, seen_status | status::kAllTxRxEvents | status::kSpiCrcE | irq_mask_);
  bool high = false;
  if (irq_.readLevel(high) || !high) return IrqCheck::kOk;
  // Stuck high: clear every bit of both words and the IRQ summary.
  (void)clearAllStatus();
  (void)fastCommand(fast_cmd::kClrIrqs);
  if (irq_.readLevel(high) || !high) return IrqCheck::kRecovered;
  return IrqCheck::kStuck;
}

void Dw3000Device::abortExchange(ExchangeResult& r, std::uint32_t seen_status) noexcept {
  (void)fastCommand(fast_cmd::kTxRxOff);
  r.irq = clearAndCheckIrq(seen_status);
}

void Dw3000Device::readResponse(const AnchorConfig& anchor, std::uint8_t sequence, ExchangeResult& r) noexcept {
  const auto spiFault = [&r](std::error_code e) {
    r.error = e;
    r.status = e == Dw3000Errc::kReadCrcMismatch ? ExchangeStatus::kSpiCrcError : ExchangeStatus::kSpiError;
  };
  std::uint32_t finfo = 0;
  if (const std::error_code e = read32(reg::kRxFinfo, finfo)) return spiFault(e);
  const std::size_t length = finfo & 0x3FFu;
  if (length != kResponseLength + kFcsLength) {
    r.status = ExchangeStatus::kBadFrame;
    r.frame_error = FrameError::kWrongLength;
    return;
  }
  std::array<std::uint8_t, kResponseLength> frame_bytes{};
  if (const std::error_code e = read(reg::kRxBuffer0, frame_bytes)) return spiFault(e);
  ResponseFrame response;
  r.frame_error = decodeResponse(frame_bytes, response);
  if (r.frame_error == FrameError::kOk) {
    if (response.pan_id != config_.pan_id || response.destination != config_.tag_address ||
        response.source != anchor.short_address) {
      r.frame_error = FrameError::kWrongAddress;
    } else if (response.sequence != sequence) {
      r.frame_error = FrameError::kWrongSequence;
    }
  }
  if (r.frame_error != FrameError::kOk) {
    r.status = ExchangeStatus::kBadFrame;
    return;
  }

  std::array<std::uint8_t, 5> stamp{};
  if (const std::error_code e = read(reg::kTxTime, stamp)) return spiFault(e);
  r.stamps.poll_tx = readTimestamp40(stamp.data());
  if (const std::error_code e = read(reg::kRxTime, stamp)) return spiFault(e);
  r.stamps.resp_rx = readTimestamp40(stamp.data());
  r.stamps.poll_rx = response.poll_rx;
  r.stamps.resp_tx = response.resp_tx;

  switch (config_.clock_offset_source) {
    case ClockOffsetSource::kCiaDiag0: {
      std::array<std::uint8_t, 2> raw{};
      if (const std::error_code e = read(reg::kCiaDiag0, raw)) return spiFault(e);
      r.clock_offset_ratio = clockOffsetFromCiaDiag0(static_cast<std::uint32_t>(raw[0] | (raw[1] << 8)));
      break;
    }
    case ClockOffsetSource::kCarrierIntegrator: {
      std::array<std::uint8_t, 3> raw{};  // all 21 bits, not one byte
      if (const std::error_code e = read(reg::kDrxDiag3, raw)) return spiFault(e);
      r.clock_offset_ratio =
          clockOffsetFromCarrierIntegrator(carrierIntegratorFromBytes(raw[0], raw[1], raw[2]), config_.channel);
      break;
    }
    case ClockOffsetSource::kNone: r.clock_offset_ratio = 0.0; break;
  }

  r.twr = computeSsTwr(r.stamps, r.clock_offset_ratio);
  r.range_m = r.twr.range_m;
  if (!(r.range_m >= config_.min_range_m && r.range_m <= config_.max_range_m)) {
    r.status = ExchangeStatus::kImplausibleRange;
    return;
  }
  r.status = ExchangeStatus::kOk;
}

void Dw3000Device::readRxPower(ExchangeResult& r) noexcept {
  // IP_DIAG_1..IP_DIAG_12 in one burst (48 bytes): one SPI message instead
  // of five; the 28 unused bytes in between cost ~11 us at 20 MHz.
  std::array<std::uint8_t, kIpDiagBlockBytes> block{};
  if (const std::error_code e = read(reg::kIpDiag1, block)) {
    r.diagnostics_error = e;
    return;
  }
  std::uint32_t dgc_dbg = 0;
  if (dgc_enabled_) {
    if (const std::error_code e = read32(reg::kDgcDbg, dgc_dbg)) {
      r.diagnostics_error = e;
      return;
    }
  }
  r.diagnostics = decodeRxDiagnostics(block, dgc_dbg);
  r.rx_power = rxPowerFromDiagnostics(r.diagnostics, prf64_);
}

ExchangeResult Dw3000Device::range(const AnchorConfig& anchor) noexcept {
  ExchangeResult r;
  const auto spiFault = [&](std::error_code e, std::uint32_t seen) {
    r.error = e;
    r.status = e == Dw3000Errc::kReadCrcMismatch ? ExchangeStatus::kSpiCrcError : ExchangeStatus::kSpiError;
    r.t_ns = clock_.nowNs();
    abortExchange(r, seen);
    return r;
  };
  if (const std::error_code e = drainEdges()) {
    r.status = ExchangeStatus::kIrqWaitError;
    r.error = e;
    r.t_ns = clock_.nowNs();
    return r;
  }

  // Poll frame, its length, then TX and wait-for-response in one command.
  const std::uint8_t sequence = sequence_++;
  std::array<std::uint8_t, kPollLength> poll{};
  encodePoll(PollFrame{sequence, config_.pan_id, anchor.short_address, config_.tag_address}, poll);
  if (const std::error_code e = write(reg::kTxBuffer, poll)) return spiFault(e, 0);
  if (const std::error_code e = writeMasked(reg::kTxFctrl, AccessMode::kMask16, ~tx_fctrl::kLengthMask & 0xFFFFu,
                                            static_cast<std::uint32_t>(kPollLength + kFcsLength))) {
    return spiFault(e, 0);
  }
  if (const std::error_code e = fastCommand(fast_cmd::kTxW4r)) return spiFault(e, 0);

  // Wait for an event that ends the exchange; other edges are ignored.
  const std::uint32_t end_bits = irq_mask_ | kExchangeEnd;
  const std::int64_t deadline_ns = clock_.nowNs() + exchange_timeout_ns_;
  std::uint32_t st = 0;
  for (;;) {
    const std::int64_t remaining_ns = std::max<std::int64_t>(0, deadline_ns - clock_.nowNs());
    hal::EdgeEvent edge;
    std::error_code wait_error;
    const hal::WaitResult w = irq_.waitEdge(std::chrono::nanoseconds(remaining_ns), edge, wait_error);
    if (w == hal::WaitResult::kError) {
      r.status = ExchangeStatus::kIrqWaitError;
      r.error = wait_error;
      r.t_ns = clock_.nowNs();
      (void)read32(reg::kSysStatus, st);
      r.sys_status = st;
      abortExchange(r, st);
      return r;
    }
    if (const std::error_code e = read32(reg::kSysStatus, st)) return spiFault(e, 0);
    if ((st & end_bits) != 0) {
      r.missed_edge = w != hal::WaitResult::kEdge;
      r.t_ns = r.missed_edge ? clock_.nowNs() : edge.t_ns;
      break;
    }
    if (w == hal::WaitResult::kTimeout) {
      // The chip never ended the exchange: either the poll never went out or
      // the receiver/IRQ is wedged. Both are device faults.
      r.status = (st & status::kTxFrs) == 0 ? ExchangeStatus::kTxFailed : ExchangeStatus::kHostTimeout;
      r.t_ns = clock_.nowNs();
      r.sys_status = st;
      abortExchange(r, st);
      return r;
    }
  }
  r.sys_status = st;

  if ((st & status::kSpiCrcE) != 0) {
    r.status = ExchangeStatus::kSpiCrcError;  // one of our writes was dropped by the chip
    abortExchange(r, st);
    return r;
  }
  if ((st & status::kAllRxErrors) != 0) {
    r.status = ExchangeStatus::kRxError;
    abortExchange(r, st);
    return r;
  }
  if ((st & status::kAllRxTimeouts) != 0 || (st & status::kRxFcg) == 0) {
    r.status = ExchangeStatus::kRxTimeout;
    abortExchange(r, st);
    return r;
  }

  readResponse(anchor, sequence, r);
  if (isDeviceFault(r.status)) {
    abortExchange(r, st);
    return r;
  }
  if (r.status == ExchangeStatus::kOk) readRxPower(r);  // before the clear: valid until the next reception
  r.irq = clearAndCheckIrq(st);
  return r;
}

}  // namespace rilo::dw3000
