#pragma once
// Virtual time for device emulators: a clock that only moves when the driver
// under test sleeps or waits, with device events (a frame arriving, a sample
// becoming ready) scheduled at absolute times. Tests of timeouts, back-off and
// 800 Hz streams run instantly and deterministically.
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <string>
#include <system_error>

#include "hal/bus/clock.h"
#include "hal/bus/gpio_line.h"

namespace rilo::emu {

class VirtualClock final : public hal::Clock {
 public:
  explicit VirtualClock(std::int64_t t0_ns = 1'000'000'000) : now_ns_(t0_ns) {}

  std::int64_t nowNs() const noexcept override { return now_ns_; }
  void sleepForNs(std::int64_t duration_ns) noexcept override { advanceTo(now_ns_ + duration_ns); }

  /// Run `action` when time reaches t_ns (now if t_ns is in the past).
  /// Actions scheduled for the same time run in the order scheduled.
  void schedule(std::int64_t t_ns, std::function<void()> action);
  /// Move time to t_ns, running due actions in time order; each action sees
  /// nowNs() equal to its own time.
  void advanceTo(std::int64_t t_ns);
  /// Time of the next pending action (INT64_MAX if none).
  std::int64_t nextEventNs() const;
  std::size_t pendingEvents() const { return events_.size(); }

 private:
  std::int64_t now_ns_;
  std::uint64_t sequence_ = 0;
  std::map<std::pair<std::int64_t, std::uint64_t>, std::function<void()>> events_;
};

/// An interrupt input driven by a device model: the model sets the level, a
/// low-to-high transition queues a rising edge stamped with the virtual time
/// plus an optional injected latency (IRQ jitter). waitEdge() advances the
/// virtual clock through scheduled device events until an edge or the timeout.
class EmulatedInterruptLine final : public hal::InterruptLine {
 public:
  EmulatedInterruptLine(VirtualClock& clock, std::string name) : clock_(clock), name_(std::move(name)) {}

  void setLevel(bool high);
  bool level() const { return level_; }
  /// Added to each edge's timestamp (e.g. random IRQ latency in tests).
  void setTimestampJitter(std::function<std::int64_t()> jitter_ns) { jitter_ns_ = std::move(jitter_ns); }
  /// The next `count` waits fail with `error` (EIO-style back-end failures).
  void failNextWaits(int count, std::error_code error) { fail_count_ = count; fail_error_ = error; }
  std::size_t queuedEdges() const { return edges_.size(); }

  hal::WaitResult waitEdge(std::chrono::nanoseconds timeout, hal::EdgeEvent& event,
                           std::error_code& error) noexcept override;
  std::error_code readLevel(bool& high) noexcept override { high = level_; return {}; }
  const std::string& path() const noexcept override { return name_; }

 private:
  static constexpr std::size_t kKernelQueueDepth = 16;  // events the kernel keeps per line
  VirtualClock& clock_;
  std::string name_;
  bool level_ = false;
  std::deque<hal::EdgeEvent> edges_;
  std::function<std::int64_t()> jitter_ns_;
  int fail_count_ = 0;
  std::error_code fail_error_;
};

/// An output (reset pin): records the level and tells the device model.
class EmulatedOutputLine final : public hal::OutputLine {
 public:
  explicit EmulatedOutputLine(std::string name) : name_(std::move(name)) {}
  void onChange(std::function<void(bool high)> callback) { on_change_ = std::move(callback); }
  bool level() const { return level_; }
  std::error_code set(bool high) noexcept override;
  const std::string& path() const noexcept override { return name_; }

 private:
  std::string name_;
  bool level_ = true;
  std::function<void(bool)> on_change_;
};

}  // namespace rilo::emu
