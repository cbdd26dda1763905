#include "hal/dw3000/dw3000_source.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>

#include "hal/dw3000/registers.h"
#include "hal/dw3000/text.h"

namespace rilo::dw3000 {
namespace {

/// Names of the RX error / timeout bits set in `st` ("RXPHE|RXFCE").
std::string rxBitNames(std::uint32_t st) {
  static constexpr struct {
    std::uint32_t bit;
    const char* name;
  } kBits[] = {{status::kRxPhe, "RXPHE"},   {status::kRxFce, "RXFCE"},   {status::kRxFsl, "RXFSL"},
               {status::kRxSto, "RXSTO"},   {status::kArfe, "ARFE"},     {status::kCiaErr, "CIAERR"},
               {status::kRxOvrr, "RXOVRR"}, {status::kRxFto, "RXFTO"},   {status::kRxPto, "RXPTO"},
               {status::kSpiCrcE, "SPICRCE"}};
  std::string names;
  for (const auto& b : kBits) {
    if ((st & b.bit) == 0) continue;
    if (!names.empty()) names += '|';
    names += b.name;
  }
  return names.empty() ? std::string("none") : names;
}

constexpr std::int64_t kMaxSleepChunkNs = 50'000'000;  // stop is checked at least this often

}  // namespace

Dw3000Source::Dw3000Source(const Dw3000Config& config, hal::SpiDevice& spi, hal::InterruptLine& irq,
                           hal::OutputLine* reset, hal::Clock& clock)
    : config_(config),
      clock_(clock),
      device_(config_, spi, irq, reset, clock),
      scheduler_(config_.anchors.size(), config_.scheduler) {}

std::string Dw3000Source::describe() const {
  char rate[32];
  std::snprintf(rate, sizeof rate, "%g Hz", config_.scheduler.range_rate_hz);
  return "dwm3000 " + device_.path() + " (channel " + std::to_string(static_cast<int>(config_.channel)) + ", " +
         std::to_string(config_.anchors.size()) + " anchors, strongest " +
         std::to_string(config_.scheduler.max_active) + " at " + rate + ")";
}

std::string Dw3000Source::anchorName(std::size_t index) const {
  char text[48];
  std::snprintf(text, sizeof text, "%u (0x%04X)", static_cast<unsigned>(config_.anchors[index].id),
                static_cast<unsigned>(config_.anchors[index].short_address));
  return text;
}

void Dw3000Source::report(SampleSink& sink, const std::string& what, bool fatal) {
  sink.fault(SourceFault{clock_.nowNs(), device_.path(), what, fatal});
}

void Dw3000Source::sleepInterruptible(std::int64_t duration_ns, const std::atomic<bool>& stop, SampleSink& sink) {
  while (duration_ns > 0 && !stop.load(std::memory_order_relaxed)) {
    const std::int64_t chunk_ns = std::min(duration_ns, kMaxSleepChunkNs);
    clock_.sleepForNs(chunk_ns);
    duration_ns -= chunk_ns;
    sink.idle();  // a back-off of seconds is the loop waiting, not stuck (the service's watchdog)
  }
}

std::int64_t Dw3000Source::deviceBackoffNs(int faults) const noexcept {
  std::int64_t delay = config_.device_backoff_initial_ns;
  for (int i = 1; i < faults && delay < config_.device_backoff_max_ns; ++i) delay *= 2;
  return std::min(delay, config_.device_backoff_max_ns);
}

void Dw3000Source::noteStartUp(SampleSink& sink, bool at_startup) noexcept {
  // What the start-up read and applied (OTP trims, PLL lock, DGC, PGF): the
  // first thing a board bring-up looks for in the journal. Only a note: a
  // failure to build it must not count as a failed bring-up.
  try {
    const std::string prefix = at_startup ? "started: " : "re-initialized: ";
    sink.note(SourceNote{clock_.nowNs(), device_.path(), prefix + ::rilo::dw3000::describe(device_.bringUpReport())});
  } catch (...) {
  }
}

bool Dw3000Source::bringUp(SampleSink& sink, bool at_startup) {
  try {
    device_.bringUp();
    Dw3000Stats::add(stats_.bringups);
    noteStartUp(sink, at_startup);
    return true;
  } catch (const Dw3000Error& e) {
    if (e.kind() == Dw3000Error::Kind::kPllLock) Dw3000Stats::add(stats_.pll_lock_failures);
    last_bringup_error_ = e.what();
  } catch (const std::exception& e) {
    last_bringup_error_ = e.what();
  }
  Dw3000Stats::add(stats_.bringup_failures);
  report(sink, std::string(at_startup ? "bring-up failed: " : "re-initialization failed: ") + last_bringup_error_);
  return false;
}

bool Dw3000Source::reinitialize(SampleSink& sink, const std::atomic<bool>& stop) {
  while (!stop.load(std::memory_order_relaxed)) {
    if (bringUp(sink, false)) {
      consecutive_device_faults_ = 0;
      consecutive_reinit_failures_ = 0;
      return true;
    }
    ++consecutive_reinit_failures_;
    if (config_.max_reinit_failures > 0 && consecutive_reinit_failures_ >= config_.max_reinit_failures) {
      report(sink,
             "giving up after " + std::to_string(consecutive_reinit_failures_) +
                 " failed re-initializations: " + last_bringup_error_,
             true);
      return false;
    }
    sleepInterruptible(deviceBackoffNs(consecutive_reinit_failures_), stop, sink);
  }
  return true;
}

void Dw3000Source::handleLinkFault(SampleSink& sink, std::size_t index, bool discovery, const ExchangeResult& r) {
  std::string detail;
  switch (r.status) {
    case ExchangeStatus::kRxTimeout:
      Dw3000Stats::add(stats_.rx_timeouts);
      detail = " (" + rxBitNames(r.sys_status) + ")";
      break;
    case ExchangeStatus::kRxError:
      Dw3000Stats::add(stats_.rx_errors);
      detail = " (" + rxBitNames(r.sys_status) + ")";
      break;
    case ExchangeStatus::kBadFrame:
      Dw3000Stats::add(stats_.bad_frames);
      detail = std::string(" (") + toString(r.frame_error) + ")";
      break;
    case ExchangeStatus::kImplausibleRange: {
      Dw3000Stats::add(stats_.implausible_ranges);
      char text[64];
      std::snprintf(text, sizeof text, " (%.3f m)", r.range_m);
      detail = text;
      break;
    }
    default: break;
  }
  const bool was_active = scheduler_.state(index) == AnchorScheduler::State::kActive;
  const bool dropped = scheduler_.reportFailure(index, clock_.nowNs());
  if (!was_active || discovery) return;  // absent anchors are expected: counted only
  const int failures = scheduler_.consecutiveFailures(index);
  std::string what = std::string(toString(r.status)) + " from anchor " + anchorName(index) + detail;
  if (dropped) {
    Dw3000Stats::add(stats_.anchors_dropped);
    what += "; dropped from the ranging set after " + std::to_string(failures) + " failures in a row";
  } else {
    what += "; retry in " + msText(scheduler_.backoffNs(failures));
  }
  report(sink, what);
}

bool Dw3000Source::handleDeviceFault(SampleSink& sink, const ExchangeResult& r, const std::atomic<bool>& stop) {
  ++consecutive_device_faults_;
  std::string what;
  if (isDeviceFault(r.status)) {
    switch (r.status) {
      case ExchangeStatus::kSpiError: Dw3000Stats::add(stats_.spi_errors); break;
      case ExchangeStatus::kSpiCrcError: Dw3000Stats::add(stats_.spi_crc_errors); break;
      case ExchangeStatus::kIrqWaitError: Dw3000Stats::add(stats_.irq_wait_errors); break;
      case ExchangeStatus::kTxFailed: Dw3000Stats::add(stats_.tx_failures); break;
      case ExchangeStatus::kHostTimeout: Dw3000Stats::add(stats_.host_timeouts); break;
      default: break;
    }
    what = toString(r.status);
    if (r.error) what += ": " + r.error.message();
    what += " (SYS_STATUS " + hex32(r.sys_status) + ")";
  }
  const bool stuck = r.irq == IrqCheck::kStuck;
  if (stuck) {
    Dw3000Stats::add(stats_.irq_stuck);
    if (!what.empty()) what += "; ";
    what += "IRQ line stuck high after a full clear of SYS_STATUS";
  }
  const bool reinit = stuck || r.status == ExchangeStatus::kTxFailed ||
                      consecutive_device_faults_ >= config_.device_faults_before_reinit;
  const std::int64_t backoff_ns = deviceBackoffNs(consecutive_device_faults_);
  what += "; " + std::to_string(consecutive_device_faults_) + " device fault(s) in a row, " +
          (reinit ? "re-initializing" : "retrying") + " in " + msText(backoff_ns);
  report(sink, what);
  sleepInterruptible(backoff_ns, stop, sink);
  if (stop.load(std::memory_order_relaxed) || !reinit) return true;
  return reinitialize(sink, stop);
}

SourceEnd Dw3000Source::run(SampleSink& sink, const std::atomic<bool>& stop) {
  bool up = false;
  for (int attempt = 1; attempt <= config_.startup_attempts && !stop.load(std::memory_order_relaxed); ++attempt) {
    if (bringUp(sink, true)) {
      up = true;
      break;
    }
    if (attempt < config_.startup_attempts) sleepInterruptible(deviceBackoffNs(attempt), stop, sink);
  }
  if (!up) {
    if (stop.load(std::memory_order_relaxed)) return SourceEnd::kStopped;
    report(sink,
           "giving up after " + std::to_string(config_.startup_attempts) +
               " bring-up attempt(s): " + last_bringup_error_,
           true);
    return SourceEnd::kFailed;
  }

  while (!stop.load(std::memory_order_relaxed)) {
    sink.idle();  // the loop went round (the watchdog watches this thread too)
    const std::int64_t now_ns = clock_.nowNs();
    const AnchorScheduler::Pick pick = scheduler_.next(now_ns);
    if (pick.at_ns > now_ns) {
      sleepInterruptible(pick.at_ns - now_ns, stop, sink);
      continue;
    }
    if (pick.discovery) Dw3000Stats::add(stats_.discovery_polls);
    Dw3000Stats::add(stats_.exchanges);
    const ExchangeResult r = device_.range(config_.anchors[pick.index]);
    if (r.missed_edge) Dw3000Stats::add(stats_.irq_missed_edges);
    if (r.irq == IrqCheck::kRecovered) {
      Dw3000Stats::add(stats_.irq_stuck_recovered);
      report(sink, "IRQ line stayed high after clearing SYS_STATUS " + hex32(r.sys_status) +
                       "; a full clear (all bits and CLR_IRQS) brought it low");
    }

    if (isDeviceFault(r.status)) {
      if (!handleDeviceFault(sink, r, stop)) return SourceEnd::kFailed;
      continue;
    }
    consecutive_device_faults_ = 0;  // the chip and the bus worked
    if (r.status == ExchangeStatus::kOk) {
      RangeSample sample;
      sample.t_ns = r.t_ns;
      sample.anchor_id = config_.anchors[pick.index].id;
      sample.tag_id = config_.tag_id;
      sample.range_m = r.range_m;
      sample.rssi_dbm = r.rx_power.rssi_dbm;
      sample.fp_power_dbm = r.rx_power.fp_power_dbm;
      if (r.diagnostics_error) Dw3000Stats::add(stats_.diagnostics_read_failures);  // range kept, powers NaN
      sink.push(sample);
      Dw3000Stats::add(stats_.ranges);
      scheduler_.reportSuccess(pick.index, clock_.nowNs(), AnchorScheduler::strengthFromRangeDb(r.range_m));
    } else {
      handleLinkFault(sink, pick.index, pick.discovery, r);
    }
    if (r.irq == IrqCheck::kStuck && !handleDeviceFault(sink, r, stop)) return SourceEnd::kFailed;
  }
  return SourceEnd::kStopped;
}

}  // namespace rilo::dw3000
