#pragma once
// Counters of the DWM3000 source, readable from any thread while run() is
// going (relaxed atomics: each is a tally, no ordering between them).
#include <atomic>
#include <cstdint>

namespace rilo::dw3000 {

struct Dw3000Stats {
  using Counter = std::atomic<std::uint64_t>;
  Counter exchanges{0};           ///< polls sent (or attempted)
  Counter ranges{0};              ///< RangeSamples pushed
  Counter diagnostics_read_failures{0};  ///< ranges pushed without RX / first-path power (read failed)
  Counter discovery_polls{0};     ///< polls of anchors outside the active set
  // Link faults
  Counter rx_timeouts{0};
  Counter rx_errors{0};           ///< RXPHE, RXFCE, RXFSL, RXSTO, ARFE, CIAERR, RXOVRR
  Counter bad_frames{0};
  Counter implausible_ranges{0};
  Counter anchors_dropped{0};     ///< active anchors dropped after repeated failures
  // Device faults
  Counter spi_errors{0};
  Counter spi_crc_errors{0};
  Counter irq_wait_errors{0};
  Counter tx_failures{0};         ///< poll never transmitted (no TXFRS)
  Counter host_timeouts{0};
  Counter irq_stuck{0};           ///< line still high after a full clear (re-init follows)
  Counter irq_stuck_recovered{0}; ///< line high after the normal clear, low after the full clear
  Counter irq_missed_edges{0};    ///< the chip finished but no edge arrived
  Counter pll_lock_failures{0};   ///< bring-ups that failed on CP_LOCK
  Counter bringups{0};            ///< successful bring-ups (first + re-inits)
  Counter bringup_failures{0};

  static std::uint64_t get(const Counter& c) { return c.load(std::memory_order_relaxed); }
  static void add(Counter& c) { c.fetch_add(1, std::memory_order_relaxed); }
};

}  // namespace rilo::dw3000
