#pragma once
// Whether the published covariance says how far off the published position
// is: the share of poses whose error lies inside the covariance's 95 %
// region, horizontally (the 2D ellipse, chi-square 5.991 on 2 degrees of
// freedom) and vertically (1.96 sigma, chi-square 3.841 on 1), and the mean
// normalized estimation error squared (NEES, e^T P^-1 e over the 3D
// position; 3 when the covariance is consistent). An honest covariance keeps
// about 95 % inside; far fewer means it claims more than the estimate holds.
//
// Poses are paired with the ground truth as the APE pairs them
// (trajectory_metrics.h associateByTime: nearest in time, no interpolation).
// A covariance that is not symmetric positive definite (or not finite) is
// counted apart and left out of every figure.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "hal/recording/recording.h"
#include "math/types.h"

namespace rilo {

/// A published position and its covariance (world frame).
struct TimedPositionCovariance {
  std::int64_t t_ns = 0;
  Vec3 p_w = Vec3::Zero();          ///< m
  Mat3 cov_p_w = Mat3::Identity();  ///< m^2
  bool position_only = false;       ///< a fix published while initializing (orientation unknown)
};

struct CovarianceConsistency {
  std::size_t poses = 0;                  ///< paired with the truth, with a usable covariance
  std::size_t not_positive_definite = 0;  ///< paired, covariance unusable: in no figure
  double horizontal_in_95 = 0.0;          ///< share of poses inside the 95 % horizontal ellipse
  double vertical_in_95 = 0.0;            ///< share of poses with |e_z| <= 1.96 sigma_z
  double nees_mean = 0.0;                 ///< mean e^T P^-1 e (3D; 3 when consistent)
  /// Per axis, root mean square over the poses: the claimed sigma
  /// (sqrt(mean (P_xx + P_yy) / 2), sqrt(mean P_zz)) against the error
  /// (sqrt(mean (e_x^2 + e_y^2) / 2), sqrt(mean e_z^2)), m.
  double sigma_horizontal_m = 0.0, error_horizontal_m = 0.0;
  double sigma_vertical_m = 0.0, error_vertical_m = 0.0;
};

/// `truth` in strictly increasing time order (the recording reader
/// guarantees it); `published` in any order. Throws std::invalid_argument
/// if max_dt_ns < 0.
CovarianceConsistency covarianceConsistency(const std::vector<TimedPositionCovariance>& published,
                                            const std::vector<GroundTruthPose>& truth, std::int64_t max_dt_ns);

}  // namespace rilo
