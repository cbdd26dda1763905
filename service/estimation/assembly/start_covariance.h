#pragma once
// Uncertainty of the state a tracking estimator starts from. Without it the
// estimator puts the graph's loose first-state priors on its guess
// (RangeImuGraphParams::first_*: ~1 m, 0.5 rad; right for a guess). After
// initialization the guess is the newest state of a batch solve whose
// marginal covariance is known: handing that over keeps what the window
// learnt (at 1 Hz ranging the loose priors let the first seconds of sparse
// ranges pull a 0.3 m / 3 deg state metres away; issue 4).
//
// The marginals are block-diagonal (pose, velocity, bias, each the batch's
// marginal; the cross-covariances between them are dropped) and conditioned
// by conditionStartCovariance():
//  - inflated by a factor: the batch covariance is the inverse Gauss-Newton
//    Hessian at the solution (robust weights frozen), optimistic once the
//    tracker relinearizes, and dropping the cross blocks is not conservative
//    either (for k blocks, k * blockdiag(C) >= C is the conservative bound);
//  - floored per axis in a whitened sense: each block is scaled by floor
//    sigmas D, eigenvalues of D^-1 C D^-1 below 1 are raised to 1, and scaled
//    back, so no direction of the prior is tighter than its floor (a
//    near-singular marginal cannot make an over-confident prior), whatever
//    the units mix in the block.
// Before that the marginals can be scaled by the batch's a-posteriori
// variance factor (residualScale below): the marginals assume the nominal
// measurement sigmas, and where the data are noisier than that (office TDoA
// under NLOS) they are that much too tight. Handed over unscaled, a start
// metres off claimed centimetre sigmas, and the tracker ran away from it
// (issue 7; measured: docs/noise-models.md, Figures behind the defaults).
#include <optional>
#include <span>

#include "math/types.h"

namespace rilo {

/// Covariances of a start state, in the tangent charts of Values.
struct StartCovariance {
  Mat6 pose = Mat6::Identity();      ///< [rot; trans] of Pose3 (right/body chart), rad^2, m^2
  Mat3 velocity = Mat3::Identity();  ///< world frame, m^2/s^2
  Mat6 bias = Mat6::Identity();      ///< [accel; gyro], (m/s^2)^2, (rad/s)^2
};

struct StartCovarianceConditioning {
  /// Covariance factor (sigma x sqrt). 2: between the batch's own marginals
  /// and the block-diagonal bound 3 (see the file comment); measured on the
  /// hall and office replays at 1 and 40 Hz; 1 and 4 against 2 on the office TDoA sims:
  /// docs/noise-models.md, "More office seeds, the EKF's runaways (session 19)".
  double inflation = 2.0;
  /// Smallest sigma per axis, [rot (rad) x3, trans (m) x3].
  Vec6 pose_floor_sigmas = (Vec6() << 0.005, 0.005, 0.005, 0.02, 0.02, 0.02).finished();
  double velocity_floor_sigma_m_s = 0.02;
  /// [accel (m/s^2) x3, gyro (rad/s) x3].
  Vec6 bias_floor_sigmas = (Vec6() << 0.005, 0.005, 0.005, 2e-4, 2e-4, 2e-4).finished();

  /// Throws std::invalid_argument naming the field (inflation >= 1, floors > 0, all finite).
  void validate() const;
};

/// The conditioned start covariance from the marginals of one state, or
/// nullopt when a marginal is not finite (the caller then starts with the
/// default priors). Symmetrizes its input. `variance_factor` (>= 1, finite)
/// multiplies the marginals before the inflation and the floors.
std::optional<StartCovariance> conditionStartCovariance(const Mat6& pose, const Mat3& velocity, const Mat6& bias,
                                                        const StartCovarianceConditioning& params = {},
                                                        double variance_factor = 1.0);

/// Robust scale of whitened residuals (1 when they follow the nominal
/// sigmas): 1.4826 x the median of |r|, taken about zero rather than about
/// the residuals' median, so that a shared bias (NLOS excess on most links)
/// counts as the error it is. NaN for no residuals. Reorders `abs_residuals`
/// (partial sort); every entry must be |r| >= 0.
double residualScale(std::span<double> abs_residuals);

}  // namespace rilo
