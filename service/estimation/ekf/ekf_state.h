#pragma once
// Nominal state of the error-state EKF and its 15-dim error chart.
//
// Nominal x = (R_w_b, p_w_b, v_w, b_a, b_g). Error dx = [dtheta, dp, dv, dba, dbg]
// (rad, m, m/s, m/s^2, rad/s), with the truth x_true = x (+) dx:
//   R_true = R_w_b Exp(dtheta)     body-frame (right) rotation error, as Pose3::retract
//   p_true = p_w_b + dp            world frame
//   v_true = v_w + dv              world frame
//   b_true = b + [dba; dbg]        additive, as ImuBias::retract
// Position and velocity errors are in WORLD coordinates (the usual ESKF
// choice: the position covariance is the world covariance the publisher
// wants). The smoother's Pose3 chart has rho = R^T dp in the body frame;
// poseCovarianceInRetractionChart() in error_state_ekf.h converts.
#include "math/imu_bias.h"
#include "math/pose3.h"

namespace rilo {

/// Offsets of the error-state blocks (each 3 wide).
namespace ekf_index {
inline constexpr int kTheta = 0;      ///< dtheta, body frame (rad)
inline constexpr int kPos = 3;        ///< dp, world (m)
inline constexpr int kVel = 6;        ///< dv, world (m/s)
inline constexpr int kAccelBias = 9;  ///< dba, body (m/s^2)
inline constexpr int kGyroBias = 12;  ///< dbg, body (rad/s)
inline constexpr int kDim = 15;
}  // namespace ekf_index

struct EkfState {
  Mat3 R_w_b = Mat3::Identity();  ///< rotation world-from-body
  Vec3 p_w_b = Vec3::Zero();      ///< body origin in world (m)
  Vec3 v_w = Vec3::Zero();        ///< velocity in world (m/s)
  ImuBias bias;                   ///< IMU bias (accel m/s^2, gyro rad/s), body frame

  static constexpr int kDim = ekf_index::kDim;

  EkfState() = default;
  EkfState(const Pose3& T_w_b, const Vec3& v_w_in, const ImuBias& bias_in)
      : R_w_b(T_w_b.R), p_w_b(T_w_b.p), v_w(v_w_in), bias(bias_in) {}

  Pose3 pose() const { return Pose3(R_w_b, p_w_b); }
  /// x (+) dx (the injection of an error estimate).
  EkfState retract(const Vec15& dx) const;
  /// Inverse of retract: the dx with this->retract(dx) == other (|dtheta| <= pi).
  Vec15 local(const EkfState& other) const;
  bool allFinite() const;
};

}  // namespace rilo
