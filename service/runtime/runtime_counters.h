#pragma once
// Event counters bumped by the service threads (sensor, estimator, publisher)
// and copied into rilo::ServiceStatus for the status topic. Relaxed atomics:
// each counter is an independent statistic, no other data is published through
// it. Each sits on its own cache line because different threads bump them at
// IMU rate and must not slow each other down.
#include <atomic>
#include <cstdint>

#include "runtime/cpu_hints.h"
#include "runtime/service_status.h"

namespace rilo {

class alignas(kCacheLineBytes) EventCounter {
 public:
  void add(std::uint64_t n = 1) noexcept { value_.fetch_add(n, std::memory_order_relaxed); }
  std::uint64_t load() const noexcept { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::uint64_t> value_{0};
};

struct RuntimeCounters {
  EventCounter imu_samples;
  EventCounter range_samples;
  EventCounter tdoa_samples;
  EventCounter ultrasonic_samples;
  EventCounter queue_overflows;     ///< pushes rejected by a full queue
  EventCounter late_updates;        ///< smoother updates slower than the ranging period
  EventCounter sensor_faults;
  EventCounter sensor_silences;
  EventCounter reinitializations;
  EventCounter rejected_ranges;
  EventCounter deep_nlos_tdoa_rows;
  EventCounter published_odometry;
  EventCounter non_finite_samples;
  EventCounter duplicate_samples;
  EventCounter out_of_order_samples;
  EventCounter imu_gaps;
  EventCounter ranging_gaps;
  EventCounter out_of_bounds_samples;
  EventCounter beyond_full_scale_samples;
  EventCounter far_future_samples;
  EventCounter time_jumps;

  /// Copies every counter into the matching ServiceStatus field (other fields untouched).
  void fill(ServiceStatus& status) const noexcept {
    status.imu_samples = imu_samples.load();
    status.range_samples = range_samples.load();
    status.tdoa_samples = tdoa_samples.load();
    status.ultrasonic_samples = ultrasonic_samples.load();
    status.queue_overflows = queue_overflows.load();
    status.late_updates = late_updates.load();
    status.sensor_faults = sensor_faults.load();
    status.sensor_silences = sensor_silences.load();
    status.reinitializations = reinitializations.load();
    status.rejected_ranges = rejected_ranges.load();
    status.deep_nlos_tdoa_rows = deep_nlos_tdoa_rows.load();
    status.published_odometry = published_odometry.load();
    status.non_finite_samples = non_finite_samples.load();
    status.duplicate_samples = duplicate_samples.load();
    status.out_of_order_samples = out_of_order_samples.load();
    status.imu_gaps = imu_gaps.load();
    status.ranging_gaps = ranging_gaps.load();
    status.out_of_bounds_samples = out_of_bounds_samples.load();
    status.beyond_full_scale_samples = beyond_full_scale_samples.load();
    status.far_future_samples = far_future_samples.load();
    status.time_jumps = time_jumps.load();
  }
};

}  // namespace rilo
