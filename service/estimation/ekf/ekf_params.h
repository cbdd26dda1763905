#pragma once
// Settings of the error-state EKF (error_state_ekf.h).
#include "estimation/imu/imu_params.h"
#include "estimation/noise/dynamic_covariance.h"

namespace rilo {

/// EkfParams::velocity_noise_density `rilo replay` uses with TDoA rows (m/s^2/sqrt(Hz)).
inline constexpr double kEkfTdoaVelocityNoiseDensity = 0.1;

struct EkfParams {
  /// Noise densities, bias processes and gravity, shared with preintegration.
  ImuParams imu;

  /// IMU intervals longer than this are refused (PropagateStatus::kGapTooLarge):
  /// a lost stretch of samples, not something to integrate across (s, > 0).
  /// Shorter intervals above ImuParams::gap_threshold_s are bridged with the
  /// held sample and the gap's input variance (as preintegration does). The
  /// default is the Localizer's max_imu_gap_s: up to it the graph bridges a
  /// gap too (with 0.1 s a 0.2 s gap left the filter refusing every later
  /// sample, its time stuck before the gap).
  double max_imu_dt_s = 1.0;

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

  /// TDoA rows of one update group (EkfEstimator: the rows the graph puts on
  /// one state) as ONE update (ErrorStateEkf::updateTdoaGroup) instead of one
  /// by one: a chi-square gate on the whole group, iterated robust
  /// re-weighting with relinearization at the current state, and the
  /// correlation of rows that share an anchor. false: sequential scalar updates.
  bool tdoa_group_update = true;
  /// Share of a TDoA row's error variance that belongs to its two paths (half
  /// each: the NLOS excess and antenna delay of anchor a's and b's path), the
  /// rest row-specific noise. Rows of a group sharing an anchor are
  /// correlated through it: +-share/2 (same side: +, a and b swapped: -). In [0, 1).
  double tdoa_path_share = 0.8;
  /// Gate of a group: the 99.9 % chi-square quantile of its row count times
  /// this factor (> 0; +inf: no gate). A group above it loses its row of the
  /// largest normalized innovation until the rest passes.
  double gate_group_scale = 1.0;
  /// Iterations of the group update (>= 1): each re-weights the rows at the
  /// residuals of the current iterate and relinearizes there (an iterated
  /// EKF: Gauss-Newton on prior + robust likelihood, the prior fixed).
  int group_iterations = 3;

  /// Unmodelled acceleration (m/s^2/sqrt(Hz), >= 0): white acceleration
  /// noise added to the propagation on top of the IMU's densities (per axis,
  /// Q_v += q^2 dt, Q_pv += q^2 dt^2/2, Q_p += q^2 dt^3/3). 0 (default): none.
  /// Why: on TDoA the NLOS errors persist for seconds; taken as white they
  /// teach the filter a tilt / accelerometer bias it then trusts (office sim
  /// 11: tilt 1-2 deg and yaw 13-23 deg off against claimed sigmas of 0.1-0.2
  /// and 3-4.6 deg, velocity 1.5 m/s off against a claimed 0.06-0.1 m/s), and
  /// the IMU-integrated velocity runs away. A velocity that may wander lets the
  /// rows correct it. `rilo replay` sets kEkfTdoaVelocityNoiseDensity when TDoA
  /// rows are used; two-way ranges keep 0 (0.1 made office / hall TWR worse).
  double velocity_noise_density = 0.0;

  /// Gate recovery of the TDoA group update (ErrorStateEkf::updateTdoaGroup):
  /// the share of a group's rows the gate refused is averaged exponentially
  /// over recovery_window_groups groups (alpha = 1 / window); while that
  /// average is above recovery_gated_share, the rows the gate refuses in the
  /// next group are applied all the same (robust-weighted like the others),
  /// and that group counts as refusing none. Why: a filter that is off gates
  /// the rows that would bring it back (office sim 11: 30-50 % of the rows
  /// gated for 25 s while the error grew to 88 m). In (0, 1); 1 or more: off.
  double recovery_gated_share = 0.3;
  double recovery_window_groups = 20.0;  ///< >= 1

  /// EkfEstimator: per-link measurement sigmas from DynamicCovariance, fed
  /// with each update's innovation and its predicted variance H P H^T
  /// (estimation/assembly/measurement_noise.h). The filter itself ignores it.
  DynamicCovarianceOptions dynamic_covariance;

  /// Throws std::invalid_argument naming the first bad field (also ImuParams'
  /// own checks).
  void validate() const;
};

}  // namespace rilo
