#pragma once
// Liveness of the real-time loop: the loop beats once per iteration, a watchdog
// thread checks the age of the last beat before telling systemd WATCHDOG=1, so
// a stuck loop (not just a live process) makes systemd restart the service.
#include <atomic>
#include <cstdint>

#include "runtime/cpu_hints.h"

namespace rilo {

class Heartbeat {
 public:
  /// Called by the monitored loop with its current time (ns, the service clock).
  /// Wait-free, no allocation.
  void beat(std::int64_t now_ns) noexcept {
    last_beat_ns_.store(now_ns, std::memory_order_relaxed);
    count_.fetch_add(1, std::memory_order_release);  // a reader seeing count > 0 sees a beat time
  }

  /// True if the loop has beaten at all and its last beat is at most
  /// max_age_ns old at now_ns. A beat stamped after now_ns (the watchdog read its
  /// clock first) counts as fresh.
  bool isAlive(std::int64_t now_ns, std::int64_t max_age_ns) const noexcept {
    if (count_.load(std::memory_order_acquire) == 0) return false;
    return now_ns - last_beat_ns_.load(std::memory_order_relaxed) <= max_age_ns;
  }

  std::uint64_t count() const noexcept { return count_.load(std::memory_order_relaxed); }
  /// Time of the last beat (ns); meaningless while count() == 0.
  std::int64_t lastBeatNs() const noexcept { return last_beat_ns_.load(std::memory_order_relaxed); }

 private:
  // Own line: the loop writes these at loop rate, the watchdog only reads.
  alignas(kCacheLineBytes) std::atomic<std::int64_t> last_beat_ns_{0};
  std::atomic<std::uint64_t> count_{0};
};

}  // namespace rilo
