#include "hal/bus/clock.h"

#include <cerrno>
#include <ctime>

namespace rilo::hal {

std::int64_t MonotonicClock::nowNs() const noexcept { return monotonicNowNs(); }

void MonotonicClock::sleepForNs(std::int64_t duration_ns) noexcept {
  if (duration_ns <= 0) return;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(duration_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(duration_ns % 1'000'000'000);
  // Restart after signals with the remaining time.
  while (clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, &ts) == EINTR) {
  }
}

}  // namespace rilo::hal
