#pragma once
// IMU preintegration factors (Forster et al., TRO 2017).
//
// Error (frame i, g_w = (0, 0, -g), corrected deltas from
// PreintegratedImu::biasCorrectedDelta(b_i), T = preintegrated time):
//   r_R = Log(dR_corr^T R_i^T R_j)
//   r_p = R_i^T (p_j - p_i - v_i T - 1/2 g_w T^2) - dP_corr
//   r_v = R_i^T (v_j - v_i - g_w T) - dV_corr
//   r_b = b_j - Phi b_i,  Phi = diag(exp(-T/tau)) (identity for a random walk)   [combined only]
//
// Whitening: r = L^-1 e with L L^T = G P G^T, P the preintegration covariance
// (9x9, or the 15x15 combined one) and G = blockdiag(Jr(theta), I): P is the
// covariance of the tangent vector xi = [theta; p; v], while r_R perturbs
// dR = Exp(theta) on the right, d r_R = Jr(theta) d theta. L^-1 is computed
// once at construction.
//
// Jacobians are in rilo's retraction charts: pose tangent [phi; rho] with
// R' = R Exp(phi), p' = p + R rho; velocity and bias additive (bias order
// [accel, gyro]).
#include "estimation/graph/factor.h"
#include "estimation/imu/preintegration.h"

namespace rilo {

/// Unwhitened 9-dim preintegration error [r_R; r_p; r_v] and, optionally, its
/// Jacobians (shared by ImuFactor and CombinedImuFactor).
struct ImuErrorJacobians {
  Eigen::Matrix<double, 9, 6> J_pose_i;  ///< d e / d [phi_i; rho_i]
  Eigen::Matrix<double, 9, 3> J_vel_i;   ///< d e / d v_i
  Eigen::Matrix<double, 9, 6> J_pose_j;  ///< d e / d [phi_j; rho_j]
  Eigen::Matrix<double, 9, 3> J_vel_j;   ///< d e / d v_j
  Eigen::Matrix<double, 9, 6> J_bias_i;  ///< d e / d [b_a; b_g] at i
};
Vec9 imuPreintegrationError(const PreintegratedImu& pim, const Pose3& T_w_i, const Vec3& v_w_i, const ImuBias& b_i,
                            const Pose3& T_w_j, const Vec3& v_w_j, ImuErrorJacobians* J);

/// 9-dim factor on keys {X_i, V_i, X_j, V_j, B_i}; pair it with a
/// BiasGaussMarkovFactor between B_i and B_j.
class ImuFactor final : public Factor {
 public:
  /// Throws std::invalid_argument if pim holds no samples, does not keep the
  /// 9x9 covariance, or its covariance is not positive definite.
  ImuFactor(Key pose_i, Key vel_i, Key pose_j, Key vel_j, Key bias_i, const PreintegratedImu& pim);

  int dim() const override { return 9; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  const PreintegratedImu& preintegrated() const { return pim_; }
  Vec9 unwhitenedError(const Values& x) const;
  const Mat9& sqrtInformation() const { return sqrt_info_; }  ///< L^-1 (lower triangular)

 private:
  PreintegratedImu pim_;
  Mat9 sqrt_info_;
};

/// 15-dim factor on keys {X_i, V_i, B_i, X_j, V_j, B_j}: preintegration plus
/// the bias process, with the combined covariance.
class CombinedImuFactor final : public Factor {
 public:
  /// Throws std::invalid_argument if pim holds no samples, does not keep the
  /// combined covariance, or it is not positive definite.
  CombinedImuFactor(Key pose_i, Key vel_i, Key bias_i, Key pose_j, Key vel_j, Key bias_j,
                    const PreintegratedImu& pim);

  int dim() const override { return 15; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  const PreintegratedImu& preintegrated() const { return pim_; }
  Vec15 unwhitenedError(const Values& x) const;
  const Mat15& sqrtInformation() const { return sqrt_info_; }  ///< L^-1 (lower triangular)
  const Vec6& biasTransition() const { return phi_; }          ///< diag(Phi), [accel, gyro]

 private:
  Vec15 computeError(const Values& x, ImuErrorJacobians* J) const;

  PreintegratedImu pim_;
  Vec6 phi_;
  Mat15 sqrt_info_;
};

}  // namespace rilo
