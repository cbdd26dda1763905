#pragma once
// Sensor samples as every source emits them (hardware drivers, replay of a
// recording, the simulator). One clock: t_ns on CLOCK_MONOTONIC on the device,
// the recording's clock in replay. Plain values, fixed size, no heap.
#include <cstdint>

#include <Eigen/Core>

namespace rilo {

struct ImuSample {
  std::int64_t t_ns = 0;                            ///< sample time (ns)
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();   ///< angular rate, body frame (rad/s)
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();   ///< specific force, body frame (m/s^2)
};

struct RangeSample {
  std::int64_t t_ns = 0;     ///< time of the range (ns)
  std::uint32_t anchor_id = 0;
  std::uint32_t tag_id = 0;  ///< antenna on the body (index into the tag lever arms)
  double range_m = 0.0;      ///< measured distance (m)
  double rssi_dbm = 0.0;     ///< received power, if known (NaN otherwise)
  int los = -1;              ///< ground truth from a simulator: 1 LOS, 0 NLOS, -1 unknown. Estimators never read it.
};

}  // namespace rilo
