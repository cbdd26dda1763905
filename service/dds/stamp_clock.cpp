#include "dds/stamp_clock.h"

#include <ctime>
#include <limits>

namespace rilo::dds {
std::int64_t clockNowNs(clockid_t clock) noexcept {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

const char* stampClockName(StampClock clock) noexcept {
  return clock == StampClock::kMonotonic ? "monotonic" : "system";
}

std::int64_t systemMinusMonotonicNs() noexcept {
  std::int64_t best_offset = 0;
  std::int64_t best_span = std::numeric_limits<std::int64_t>::max();
  for (int attempt = 0; attempt < 3; ++attempt) {
    const std::int64_t before = clockNowNs(CLOCK_MONOTONIC);
    const std::int64_t system = clockNowNs(CLOCK_REALTIME);
    const std::int64_t after = clockNowNs(CLOCK_MONOTONIC);
    if (after - before < best_span) {
      best_span = after - before;
      best_offset = system - (before + (after - before) / 2);
    }
  }
  return best_offset;
}

}  // namespace rilo::dds
