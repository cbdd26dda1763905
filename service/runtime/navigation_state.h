#pragma once
// What the estimator hands to the publisher and the publisher sends out: a
// navigation state with covariance at one time. Plain fixed-size values so it
// can be copied through a seqlock/triple buffer and built per IMU sample
// without allocation.
#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rilo {

struct NavigationState {
  std::int64_t t_ns = 0;                                        ///< state time (ns, one clock)
  Eigen::Quaterniond q_w_b = Eigen::Quaterniond::Identity();    ///< body orientation in world
  Eigen::Vector3d p_w_b = Eigen::Vector3d::Zero();              ///< body position in world (m)
  Eigen::Vector3d v_w_b = Eigen::Vector3d::Zero();              ///< body velocity in world (m/s)
  Eigen::Vector3d omega_b = Eigen::Vector3d::Zero();            ///< bias-corrected body rate (rad/s)
  Eigen::Vector3d accel_bias_m_s2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();
  /// Pose covariance in ROS order (x, y, z, rot x, rot y, rot z): position in
  /// world, rotation as a perturbation in the body frame.
  Eigen::Matrix<double, 6, 6> pose_covariance = Eigen::Matrix<double, 6, 6>::Identity();
  /// Twist covariance in ROS order (linear world velocity, angular body rate).
  Eigen::Matrix<double, 6, 6> twist_covariance = Eigen::Matrix<double, 6, 6>::Identity();
  bool valid = false;   ///< false until the estimator is initialized
};

}  // namespace rilo
