#pragma once
// Settings of the error-state EKF (error_state_ekf.h).
#include "estimation/imu/imu_params.h"
#include "estimation/noise/dynamic_covariance.h"

namespace rilo {

struct EkfParams {
  /// Noise densities, bias processes and gravity, shared with preintegration.
  ImuParams imu;

  /// IMU intervals longer than this are refused (PropagateStatus::kGapTooLarge):
  /// a lost stretch of samples, not something to integrate across (s, > 0).
  double max_imu_dt_s = 0.1;

  /// Chi-square gates on the Mahalanobis distance y^T S^-1 y of the innovation
  /// (prior S, before robust re-weighting), by number of rows. Defaults: the
  /// 99.9 % quantiles (10.83 for 1 dof, 13.82 for 2 dof). +inf disables a gate.
  double gate_chi2_1dof = 10.83;
  double gate_chi2_2dof = 13.82;

  /// Weight evaluations of the robust re-weighting (>= 1): the first at the
  /// whitened residual of the predicted state, each further one at the
  /// residual of the state the previous weight would produce. See error_state_ekf.h.
  int robust_iterations = 2;
  /// A final robust weight below this (the loss calls the measurement an
  /// outlier outright, e.g. a flat NLOS branch) skips the update
  /// (UpdateStatus::kZeroWeight) instead of dividing by ~0. In [0, 1).
  double min_robust_weight = 1e-6;

  /// EkfEstimator: per-link measurement sigmas from DynamicCovariance, fed
  /// with each update's innovation and its predicted variance H P H^T
  /// (estimation/pipeline/measurement_noise.h). The filter itself ignores it.
  DynamicCovarianceOptions dynamic_covariance;

  /// Throws std::invalid_argument naming the first bad field (also ImuParams'
  /// own checks).
  void validate() const;
};

}  // namespace rilo
