#pragma once
// The DWM3000 as a rilo::SampleSource: brings the chip up, then ranges the
// configured anchors with the strongest-N scheduler, pushing one RangeSample
// per good exchange (t_ns = kernel CLOCK_MONOTONIC time of the RX-good IRQ
// edge; rssi_dbm / fp_power_dbm from the response's CIA diagnostics, NaN and
// counted in stats().diagnostics_read_failures when that read failed). Faults are counted (stats()), retried with back-off on hal::Clock
// and reported through SampleSink::fault(); they never escape as exceptions.
//
// Fault policy (docs/uwb-protocol.md, "Faults"):
//  - link faults (RX timeout, RX error, unexpected frame, implausible range)
//    belong to one anchor: reported if the anchor was active, retried after
//    the scheduler's exponential back-off, the anchor dropped after
//    `scheduler.max_failures` in a row; on discovery polls they are only counted;
//  - device faults (SPI, SPI CRC, IRQ wait, poll not sent, no RX event, IRQ
//    stuck high) are reported, followed by a device back-off, and the chip is
//    re-initialized after `device_faults_before_reinit` in a row (at once for
//    a stuck IRQ or a poll that never went out);
//  - a failed re-initialization (e.g. PLL lock) is reported and retried with
//    back-off, until `max_reinit_failures` (0 = forever) ends run() as kFailed;
//  - start-up: `startup_attempts` bring-ups, then a fatal fault and kFailed.
#include <atomic>
#include <cstdint>
#include <string>

#include "hal/bus/clock.h"
#include "hal/bus/gpio_line.h"
#include "hal/bus/spi_device.h"
#include "hal/dw3000/anchor_scheduler.h"
#include "hal/dw3000/dw3000_config.h"
#include "hal/dw3000/dw3000_device.h"
#include "hal/dw3000/dw3000_stats.h"
#include "hal/source.h"

namespace rilo::dw3000 {

class Dw3000Source final : public SampleSource {
 public:
  /// Buses are borrowed (must outlive the source). Throws
  /// std::invalid_argument for a bad configuration.
  Dw3000Source(const Dw3000Config& config, hal::SpiDevice& spi, hal::InterruptLine& irq, hal::OutputLine* reset,
               hal::Clock& clock);

  SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) override;
  std::string describe() const override;

  const Dw3000Stats& stats() const noexcept { return stats_; }
  /// For tests and diagnostics; not synchronized with run().
  const AnchorScheduler& scheduler() const noexcept { return scheduler_; }
  const Dw3000Device& device() const noexcept { return device_; }

 private:
  bool bringUp(SampleSink& sink, bool at_startup);
  /// Tells the sink what the last bring-up read and applied (SourceNote).
  void noteStartUp(SampleSink& sink, bool at_startup) noexcept;
  bool reinitialize(SampleSink& sink, const std::atomic<bool>& stop);
  void handleLinkFault(SampleSink& sink, std::size_t index, bool discovery, const ExchangeResult& r);
  /// Returns false if run() must end (re-initialization gave up).
  bool handleDeviceFault(SampleSink& sink, const ExchangeResult& r, const std::atomic<bool>& stop);
  void report(SampleSink& sink, const std::string& what, bool fatal = false);
  void sleepInterruptible(std::int64_t duration_ns, const std::atomic<bool>& stop, SampleSink& sink);
  std::int64_t deviceBackoffNs(int faults) const noexcept;
  std::string anchorName(std::size_t index) const;

  Dw3000Config config_;
  hal::Clock& clock_;
  Dw3000Device device_;
  AnchorScheduler scheduler_;
  Dw3000Stats stats_;
  int consecutive_device_faults_ = 0;
  int consecutive_reinit_failures_ = 0;
  std::string last_bringup_error_;
};

}  // namespace rilo::dw3000
