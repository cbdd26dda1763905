#pragma once
// One navigation state as an estimator reports it: what the graph stream,
// the smoothers' hand-over and the EKF exchange. Its own header so the EKF
// (estimation/ekf) needs nothing of the graph's building.
#include <cstdint>

#include "math/imu_bias.h"
#include "math/pose3.h"
#include "math/types.h"

namespace rilo {

/// The smoother's current estimate of one state (the last one the stream emitted).
struct StateEstimate {
  std::uint64_t index = 0;  ///< state index i (keys X(i), V(i), B(i))
  std::int64_t t_ns = 0;    ///< state time (ns)
  Pose3 T_w_b;              ///< world-from-body pose
  Vec3 v_w = Vec3::Zero();  ///< velocity, world frame (m/s)
  ImuBias bias;             ///< IMU bias (accel m/s^2, gyro rad/s)
};

}  // namespace rilo
