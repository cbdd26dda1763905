#pragma once
// Pauses in the data, in sample time, on the merged stream the estimator
// consumes: an IMU interval longer than the IMU timeout (a gap: the motion
// model had to bridge it), and ranging quiet for longer than the ranging
// timeout while the IMU kept running (a ranging gap: the estimator runs on the
// IMU alone and drifts). Sample time rather than the wall clock, so a replay
// at any speed reports the same gaps as the live sensors would.
//
// A source that stops delivering anything is a silence of the wall clock
// (the service counts those itself): sample time does not advance then.
// Single-threaded (the estimator thread); no allocation.
#include <cstdint>

namespace rilo {

class SensorGapMonitor {
 public:
  /// What one IMU sample revealed (bit set).
  enum Event : unsigned { kNone = 0, kImuGap = 1u << 0, kRangingGapStarted = 1u << 1 };

  /// Throws std::invalid_argument unless both timeouts are > 0.
  SensorGapMonitor(std::int64_t imu_timeout_ns, std::int64_t ranging_timeout_ns);

  /// An IMU sample (times increase). Returns kImuGap when the interval since
  /// the previous IMU sample exceeded the IMU timeout, and kRangingGapStarted
  /// when ranging has now been quiet for longer than the ranging timeout
  /// (once per pause; only after the first range).
  unsigned onImu(std::int64_t t_ns) noexcept;
  /// A range. Ends a ranging pause; returns its length (ns), 0 if none was open.
  std::int64_t onRange(std::int64_t t_ns) noexcept;

  /// Ranging is quiet beyond its timeout right now (sample time).
  bool rangingSilent() const noexcept { return ranging_silent_; }
  /// Sample time since the last range, at the newest IMU sample (ns); 0 before the first range.
  std::int64_t sinceLastRangeNs() const noexcept;
  /// Length of the last IMU gap (ns).
  std::int64_t lastImuGapNs() const noexcept { return last_imu_gap_ns_; }

 private:
  std::int64_t imu_timeout_ns_, ranging_timeout_ns_;
  bool have_imu_ = false, have_range_ = false, ranging_silent_ = false;
  std::int64_t last_imu_ns_ = 0, last_range_ns_ = 0, last_imu_gap_ns_ = 0;
};

}  // namespace rilo
