#include "rilod/sensor_gap_monitor.h"

#include <algorithm>
#include <stdexcept>

namespace rilo {

SensorGapMonitor::SensorGapMonitor(std::int64_t imu_timeout_ns, std::int64_t ranging_timeout_ns)
    : imu_timeout_ns_(imu_timeout_ns), ranging_timeout_ns_(ranging_timeout_ns) {
  if (imu_timeout_ns <= 0) throw std::invalid_argument("SensorGapMonitor: imu_timeout_ns must be > 0");
  if (ranging_timeout_ns <= 0) throw std::invalid_argument("SensorGapMonitor: ranging_timeout_ns must be > 0");
}

unsigned SensorGapMonitor::onImu(std::int64_t t_ns) noexcept {
  unsigned events = kNone;
  if (have_imu_ && t_ns - last_imu_ns_ > imu_timeout_ns_) {
    last_imu_gap_ns_ = t_ns - last_imu_ns_;
    events |= kImuGap;
  }
  have_imu_ = true;
  last_imu_ns_ = std::max(last_imu_ns_, t_ns);
  if (have_range_ && !ranging_silent_ && last_imu_ns_ - last_range_ns_ > ranging_timeout_ns_) {
    ranging_silent_ = true;
    events |= kRangingGapStarted;
  }
  return events;
}

std::int64_t SensorGapMonitor::onRange(std::int64_t t_ns) noexcept {
  const std::int64_t pause = ranging_silent_ ? t_ns - last_range_ns_ : 0;
  ranging_silent_ = false;
  have_range_ = true;
  last_range_ns_ = std::max(last_range_ns_, t_ns);
  return pause;
}

std::int64_t SensorGapMonitor::sinceLastRangeNs() const noexcept {
  if (!have_range_ || !have_imu_) return 0;
  return std::max<std::int64_t>(0, last_imu_ns_ - last_range_ns_);
}

}  // namespace rilo
