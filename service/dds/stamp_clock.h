#pragma once
// Which clock the published header stamps are on.
//
// rilo runs on one clock, CLOCK_MONOTONIC (the samples' t_ns): a step of the
// wall clock (NTP, a user's `date`) must not bend the estimator's time base.
// ROS 2 stamps are system time: rviz2 and tf2 compare them with their own
// wall clock and drop "stale" data. So the publisher adds a tracked offset,
// system time minus CLOCK_MONOTONIC, to every stamp it writes, and only
// there. The offset is re-read every status-loop pass (20 ms) and taken when
// it moved by more than 0.1 ms: a wall-clock step shows in the stamps within
// one pass, and never in the estimator.
//
// With `monotonic` the stamps are rilo's clock unchanged (the replay tests
// compare stamps with a recording's ground truth that way). The status
// message carries both: header.stamp on the chosen clock, monotonic_ns on
// rilo's.
#include <cstdint>
#include <ctime>

namespace rilo::dds {

enum class StampClock : std::uint8_t {
  kSystem = 0,     ///< CLOCK_REALTIME (ROS 2 convention), from t_ns + tracked offset
  kMonotonic = 1,  ///< rilo's own clock, t_ns as it is
};

/// "system" / "monotonic".
const char* stampClockName(StampClock clock) noexcept;
/// `clock` now (ns).
std::int64_t clockNowNs(clockid_t clock) noexcept;

/// CLOCK_REALTIME minus CLOCK_MONOTONIC now (ns): the realtime reading
/// between two monotonic ones, taken against their midpoint (a preemption
/// between the reads is caught by retrying the tightest of three tries).
std::int64_t systemMinusMonotonicNs() noexcept;

}  // namespace rilo::dds
