#pragma once
// The service's health as published on the status topic and logged: state
// machine, counters and latencies. Fixed size (copied through a seqlock).
//
// States (rilod's service.cpp decides them once per status period):
// - initializing: the initializer has not produced a state yet; `reason` is
//   its own status message (why not yet: "waiting: ...", "yaw unobservable ...").
// - tracking: the smoother runs and nothing below is wrong.
// - degraded: tracking, but something is wrong now or went wrong during the
//   last status period; `reason` names it ("no ranging for 12.4 s (IMU only)",
//   "dropped 3 out-of-order samples", ...). Odometry is still published.
// - lost: tracking ended (a failure check fired) and the initializer runs
//   again; `reason` has the failure and the initializer's message. No
//   odometry is published until tracking resumes.
#include <array>
#include <cstdint>

namespace rilo {

enum class TrackingState : std::uint8_t { kInitializing = 0, kTracking = 1, kDegraded = 2, kLost = 3 };

struct ServiceStatus {
  std::int64_t t_ns = 0;                 ///< time of this status (ns, CLOCK_MONOTONIC of the service)
  TrackingState state = TrackingState::kInitializing;
  // Counters since start.
  std::uint64_t imu_samples = 0;         ///< IMU samples accepted at the service's entrance
  std::uint64_t range_samples = 0;       ///< two-way ranges accepted at the service's entrance
  std::uint64_t tdoa_samples = 0;        ///< UWB TDoA rows accepted on entry (the IMU-Ultrasonic-UWB paper's system)
  std::uint64_t ultrasonic_samples = 0;  ///< ultrasonic ranges accepted at the service's entrance
  std::uint64_t queue_overflows = 0;     ///< samples dropped because a queue was full
  std::uint64_t late_updates = 0;        ///< smoother updates slower than ServiceOptions::late_update_ms
  std::uint64_t sensor_faults = 0;       ///< faults reported by sources
  /// A source that delivered nothing at all for longer than its timeout (wall
  /// clock: status.imu_timeout_s for a source carrying IMU, range_timeout_s
  /// otherwise). Counted once per silence.
  std::uint64_t sensor_silences = 0;
  std::uint64_t reinitializations = 0;   ///< tracking lost and initialization restarted
  /// Ranges the tracking estimator did not trust: to an anchor id it does not
  /// know (dropped), or whose robust weight at the newest state right after
  /// the smoother update that took them was below 0.5 (down-weighted as
  /// NLOS/outlier; the range model's own loss, whitened residual). Ranges seen
  /// while initializing are not judged.
  std::uint64_t rejected_ranges = 0;
  /// TDoA rows not used because a packet was deeper in NLOS than
  /// estimator.tdoa.max_power_gap_db (TdoaModel::gated); also counted in
  /// tdoa_samples. A tag that hears only such rows is without ranging.
  std::uint64_t deep_nlos_tdoa_rows = 0;
  std::uint64_t published_odometry = 0;
  // Samples dropped at the service's entrance (sample time, per source and
  // stream), so the estimator and the output predictor only see clean data.
  std::uint64_t non_finite_samples = 0;    ///< a NaN/inf value (IMU axes, range, TDoA difference)
  std::uint64_t duplicate_samples = 0;     ///< same time as the previous sample (IMU), or same time and anchor (ranges)
  std::uint64_t out_of_order_samples = 0;  ///< older than the previous sample of its stream
  // Pauses in the data (sample time), counted once each.
  std::uint64_t imu_gaps = 0;              ///< IMU sample interval longer than status.imu_timeout_s
  std::uint64_t ranging_gaps = 0;          ///< no range for longer than status.range_timeout_s while the IMU ran
  // Rows the estimator's physical screen dropped (Localizer::inputDropped,
  // input_screen.h); its non-finite and non-monotonic drops count above.
  std::uint64_t out_of_bounds_samples = 0;      ///< a range outside (0, max_range_m], a TDoA beyond +-max_range_m
  std::uint64_t beyond_full_scale_samples = 0;  ///< an IMU axis beyond the screen's full scale
  std::uint64_t far_future_samples = 0;         ///< a stamp max_time_jump_s ahead of the IMU (or an unconfirmed IMU jump)
  std::uint64_t time_jumps = 0;                 ///< IMU time jumps taken after confirmation (then re-initialized)
  // Latest smoother update.
  double last_update_ms = 0.0;
  double mean_update_ms = 0.0;
  double max_update_ms = 0.0;
  /// 99th percentile of every smoother update since start (LatencyHistogram:
  /// at most one bucket, ~10 %, above the exact one; 0 before the first).
  double p99_update_ms = 0.0;
  /// Fullest any source's queue to the estimator / to the odometry publisher
  /// has been since start (samples; ServiceOptions::queue_capacity per queue):
  /// how far the consumer fell behind, e.g. during a slow update.
  std::uint32_t estimator_queue_high_water = 0;
  std::uint32_t publisher_queue_high_water = 0;
  std::uint32_t last_cliques_reeliminated = 0;
  std::uint32_t last_relinearized = 0;
  double last_lambda = 0.0;
  /// Worst in-service delay of the IMU-rate path over the last status
  /// period: from the source handing an IMU sample to the service (its
  /// push) to the return of the DDS write of the odometry computed from it
  /// (CLOCK_MONOTONIC, ms). Independent of the samples' own clock; 0 when no
  /// odometry was published in the period.
  double odometry_latency_ms = 0.0;
  /// Age of the newest smoothed pose when it was published: CLOCK_MONOTONIC
  /// at the write minus the state's sample time (ms). Meaningful when sample
  /// times are on CLOCK_MONOTONIC (hardware, or replay with shift_to_now at
  /// speed 1); otherwise it mixes two clocks.
  double pose_latency_ms = 0.0;
  /// Last fault, NUL-terminated, truncated ("dwm3000 /dev/spidev0.0: RX timeout").
  std::array<char, 128> last_fault{};
  /// Why the state is what it is (see the file comment), NUL-terminated,
  /// truncated; empty while tracking without trouble.
  std::array<char, 160> reason{};
};

}  // namespace rilo
