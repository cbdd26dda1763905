#pragma once
// Time source for drivers: CLOCK_MONOTONIC on the board, a virtual clock in
// emulator tests (so tests of timeouts and back-off run instantly and
// deterministically).
#include <cstdint>
#include <ctime>

namespace rilo::hal {

/// CLOCK_MONOTONIC now (ns): the one clock of the system.
inline std::int64_t monotonicNowNs() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

class Clock {
 public:
  virtual ~Clock() = default;
  virtual std::int64_t nowNs() const noexcept = 0;
  virtual void sleepForNs(std::int64_t duration_ns) noexcept = 0;
};

/// CLOCK_MONOTONIC and clock_nanosleep.
class MonotonicClock final : public Clock {
 public:
  std::int64_t nowNs() const noexcept override;
  void sleepForNs(std::int64_t duration_ns) noexcept override;
};

}  // namespace rilo::hal
