#pragma once
// The service's health as published on the status topic and logged: state
// machine, counters and latencies. Fixed size (copied through a seqlock).
#include <array>
#include <cstdint>

namespace rilo {

enum class TrackingState : std::uint8_t { kInitializing = 0, kTracking = 1, kDegraded = 2, kLost = 3 };

struct ServiceStatus {
  std::int64_t t_ns = 0;                 ///< time of this status (ns, one clock)
  TrackingState state = TrackingState::kInitializing;
  // Counters since start.
  std::uint64_t imu_samples = 0;
  std::uint64_t range_samples = 0;
  std::uint64_t tdoa_samples = 0;        ///< UWB TDoA rows (seed 002's system)
  std::uint64_t ultrasonic_samples = 0;  ///< ultrasonic ranges
  std::uint64_t queue_overflows = 0;     ///< samples dropped because a queue was full
  std::uint64_t late_updates = 0;        ///< smoother updates slower than the ranging period
  std::uint64_t sensor_faults = 0;       ///< faults reported by sources
  std::uint64_t sensor_silences = 0;     ///< a source quiet for longer than its timeout
  std::uint64_t reinitializations = 0;
  std::uint64_t rejected_ranges = 0;     ///< ranges down-weighted as NLOS/outliers
  std::uint64_t published_odometry = 0;
  // Latest smoother update.
  double last_update_ms = 0.0;
  double mean_update_ms = 0.0;
  double max_update_ms = 0.0;
  std::uint32_t last_cliques_reeliminated = 0;
  std::uint32_t last_relinearized = 0;
  double last_lambda = 0.0;
  // Latencies: sensor time to publish (ms).
  double odometry_latency_ms = 0.0;
  double pose_latency_ms = 0.0;
  /// Last fault, NUL-terminated, truncated ("dwm3000 /dev/spidev0.0: RX timeout").
  std::array<char, 128> last_fault{};
};

}  // namespace rilo
