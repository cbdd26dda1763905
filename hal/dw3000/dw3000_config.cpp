#include "hal/dw3000/dw3000_config.h"

#include <cmath>
#include <set>
#include <stdexcept>
#include <string>

#include "hal/dw3000/timestamp.h"
#include "hal/dw3000/twr_frame.h"

namespace rilo::dw3000 {
namespace {

void require(bool ok, const std::string& parameter, const std::string& what) {
  if (!ok) throw std::invalid_argument("dw3000 config: " + parameter + " " + what);
}

}  // namespace

int preambleLengthCode(std::uint16_t preamble_length) noexcept {
  switch (preamble_length) {
    case 32: return 0x04;
    case 64: return 0x01;
    case 72: return 0x07;
    case 128: return 0x05;
    case 256: return 0x09;
    case 512: return 0x0D;
    case 1024: return 0x02;
    case 1536: return 0x06;
    case 2048: return 0x0A;
    case 4096: return 0x03;
    default: return -1;
  }
}

int pacCode(std::uint8_t pac_symbols) noexcept {
  switch (pac_symbols) {
    case 8: return 0;
    case 16: return 1;
    case 32: return 2;
    case 4: return 3;
    default: return -1;
  }
}

std::uint16_t sfdTimeoutSymbols(const Dw3000Config& c) noexcept {
  if (c.sfd_timeout_symbols != 0) return c.sfd_timeout_symbols;
  const int sfd_symbols = c.sfd_type == 2 ? 16 : 8;
  return static_cast<std::uint16_t>(c.preamble_length + 1 + sfd_symbols - c.pac_symbols);
}

double shrDurationUs(const Dw3000Config& c) noexcept {
  // Preamble symbol: 1017.6 ns at 64 MHz PRF (codes 9-24), 993.6 ns at 16 MHz.
  const double symbol_us = c.preamble_code >= 9 ? 1.01763 : 0.99359;
  const double sfd_symbols = c.sfd_type == 2 ? 16.0 : 8.0;
  return (c.preamble_length + sfd_symbols) * symbol_us;
}

double payloadAirtimeUs(const Dw3000Config& c, std::size_t bytes_with_fcs) noexcept {
  // PHR: 21 bits at 850 kb/s (standard PHR rate); payload with Reed-Solomon
  // parity (48 bits per 330-bit block).
  const double phr_us = 21.0 / 0.85;
  const double bits = 8.0 * static_cast<double>(bytes_with_fcs);
  const double coded_bits = bits + 48.0 * std::ceil(bits / 330.0);
  const double rate_mbps = c.data_rate == DataRate::k6M8 ? 6.8 : 0.85;
  return phr_us + coded_bits / rate_mbps;
}

void validateConfig(const Dw3000Config& c) {
  require(c.channel == UwbChannel::k5 || c.channel == UwbChannel::k9, "channel", "must be 5 or 9");
  require(c.preamble_code >= 1 && c.preamble_code <= 24, "preamble_code", "must be in 1..24");
  require(preambleLengthCode(c.preamble_length) >= 0, "preamble_length",
          "must be one of 32, 64, 72, 128, 256, 512, 1024, 1536, 2048, 4096");
  require(c.sfd_type <= 3, "sfd_type", "must be in 0..3");
  require(pacCode(c.pac_symbols) >= 0, "pac_symbols", "must be one of 4, 8, 16, 32");
  require(c.tx_pg_delay <= 0x3F, "tx_pg_delay", "must fit TX_CTRL_HI's 6-bit PG_DELAY (0..0x3F)");
  require(c.pgf_timeout_ns > 0, "pgf_timeout_ns", "must be > 0");
  require(c.tag_address != kBroadcastAddress, "tag_address", "must not be the broadcast address 0xFFFF");
  require(!c.anchors.empty(), "anchors", "must list at least one anchor");
  std::set<std::uint16_t> addresses;
  std::set<std::uint32_t> ids;
  for (std::size_t i = 0; i < c.anchors.size(); ++i) {
    const AnchorConfig& a = c.anchors[i];
    const std::string name = "anchors[" + std::to_string(i) + "]";
    require(a.short_address != kBroadcastAddress, name + ".short_address", "must not be the broadcast address 0xFFFF");
    require(a.short_address != c.tag_address, name + ".short_address", "must differ from tag_address");
    require(addresses.insert(a.short_address).second, name + ".short_address", "is listed twice");
    require(ids.insert(a.id).second, name + ".id", "is listed twice");
  }
  require(std::isfinite(c.reply_delay_us) && c.reply_delay_us >= 100.0 && c.reply_delay_us <= 100'000.0,
          "reply_delay_us", "must be in [100, 100000] us");
  require(std::isfinite(c.rx_after_tx_delay_us) && c.rx_after_tx_delay_us >= 0.0 &&
              c.rx_after_tx_delay_us < c.reply_delay_us,
          "rx_after_tx_delay_us", "must be in [0, reply_delay_us)");
  {
    const double opens_us = payloadAirtimeUs(c, kPollLength + kFcsLength) + c.rx_after_tx_delay_us;
    const double preamble_us = c.reply_delay_us - shrDurationUs(c);
    require(opens_us < preamble_us, "rx_after_tx_delay_us",
            "opens the receiver after the response preamble starts (poll airtime + delay = " +
                std::to_string(opens_us) + " us >= reply_delay_us - preamble/SFD = " + std::to_string(preamble_us) +
                " us)");
  }
  require(uwbMicrosecondsFromUs(c.rx_after_tx_delay_us) <= 0xFFFFF, "rx_after_tx_delay_us",
          "exceeds the 20-bit W4R_TIM field");
  require(std::isfinite(c.rx_timeout_us) && c.rx_timeout_us > 0.0, "rx_timeout_us", "must be > 0");
  require(uwbMicrosecondsFromUs(c.rx_timeout_us) >= 1 && uwbMicrosecondsFromUs(c.rx_timeout_us) <= 0xFFFFF,
          "rx_timeout_us", "must fit the 20-bit RX_FWTO field (1..1075 ms)");
  {
    // Receiver deadline vs the end of the response (2 us of flight covers 300 m).
    const double closes_us = payloadAirtimeUs(c, kPollLength + kFcsLength) + c.rx_after_tx_delay_us + c.rx_timeout_us;
    const double response_end_us = c.reply_delay_us + payloadAirtimeUs(c, kResponseLength + kFcsLength) + 2.0;
    require(closes_us > response_end_us, "rx_timeout_us",
            "closes the receiver before the response ends (" + std::to_string(closes_us) + " us <= " +
                std::to_string(response_end_us) + " us after the poll)");
  }
  require(c.irq_wait_margin_ns > 0, "irq_wait_margin_ns", "must be > 0");
  require(c.spi_slow_hz >= 100'000 && c.spi_slow_hz <= 7'000'000, "spi_slow_hz",
          "must be in [100 kHz, 7 MHz] (the chip's limit before IDLE)");
  require(c.spi_fast_hz >= c.spi_slow_hz && c.spi_fast_hz <= 50'000'000, "spi_fast_hz",
          "must be in [spi_slow_hz, 50 MHz]");
  require(c.reset_low_ns > 0, "reset_low_ns", "must be > 0");
  require(c.boot_timeout_ns > 0, "boot_timeout_ns", "must be > 0");
  require(c.pll_lock_timeout_ns > 0, "pll_lock_timeout_ns", "must be > 0");
  require(c.poll_interval_ns > 0, "poll_interval_ns", "must be > 0");
  for (std::size_t i = 0; i < c.extra_init_writes.size(); ++i) {
    const RegisterWrite& w = c.extra_init_writes[i];
    const std::string name = "extra_init_writes[" + std::to_string(i) + "]";
    require(w.addr.file <= 0x1F && w.addr.offset <= 0x7F, name + ".addr", "must be file <= 0x1F, offset <= 0x7F");
    require(w.length >= 1 && w.length <= 4, name + ".length", "must be 1..4 bytes");
  }
  require(std::isfinite(c.min_range_m) && std::isfinite(c.max_range_m) && c.min_range_m < c.max_range_m,
          "min_range_m/max_range_m", "must be finite with min_range_m < max_range_m");
  require(c.device_backoff_initial_ns > 0, "device_backoff_initial_ns", "must be > 0");
  require(c.device_backoff_max_ns >= c.device_backoff_initial_ns, "device_backoff_max_ns",
          "must be >= device_backoff_initial_ns");
  require(c.device_faults_before_reinit >= 1, "device_faults_before_reinit", "must be at least 1");
  require(c.startup_attempts >= 1, "startup_attempts", "must be at least 1");
  require(c.max_reinit_failures >= 0, "max_reinit_failures", "must be >= 0 (0 = never give up)");
  // The scheduler checks its own parameters (and names them).
  AnchorScheduler check(c.anchors.size(), c.scheduler);
  (void)check;
}

}  // namespace rilo::dw3000
