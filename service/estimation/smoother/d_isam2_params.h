#pragma once
// D-iSAM2's step policy (Ranging-IMU Fusion paper, Alg. 1): Levenberg-Marquardt damping on the
// newest variables of an iSAM2 update. Its own parameters, as GTSAM keeps
// ISAM2GaussNewtonParams and ISAM2DoglegParams apart; the lambda decision is
// d_isam2_step.cpp, the damping rows it adds to the elimination too.
#include <stdexcept>
#include <string>

namespace rilo {

struct DIsam2Params {
  /// An update whose new factors agree with the current estimate (their
  /// error there at most this) takes the Gauss-Newton step: there is no
  /// conflict for damping to arbitrate. That is an IMU-only state, predicted
  /// exactly by its IMU factor, and the acceptance test (kDampedFactors)
  /// would only see the error that factor picks up when older states move.
  /// At 1 Hz ranging damping them rejected every IMU-only update and the
  /// track diverged even on a clean walk. Motion priors (Factor::isMotionPrior:
  /// the height band and hold, vertical speed, zero velocity) are not counted:
  /// they pull an IMU-only state a little and would damp it all the same. An
  /// update without new factors (an extra iteration) always damps the
  /// re-eliminated top.
  double damping_min_new_error = 1e-9;
  double lambda_initial = 1e-5;
  double lambda_min = 1e-10;
  double lambda_max = 1e5;     ///< relative to the diagonal; give up (keep the previous estimate) beyond this
  /// When damping the newest variables up to lambda_max still increases the
  /// error (the overshoot is in older variables: weakly observed yaw early in
  /// a run), retry from lambda_initial with every variable of the
  /// re-eliminated top damped: Levenberg-Marquardt on the affected part.
  /// Needed with Acceptance::kGlobal (early-run yaw overshoot); with
  /// kDampedFactors it only doubles the tries of the rare rejected update
  /// (docs/smoother.md).
  bool widen_damping = false;
  /// Which nonlinear error a D-iSAM2 try must not increase.
  enum class Acceptance {
    /// The Ranging-IMU Fusion paper's Alg. 1 literally: the whole graph's error.
    kGlobal,
    /// The error of the factors on the damped variables (the newest state,
    /// its IMU factor, its ranges): the part the damping controls. Older
    /// states keep a stale linearization point between relinearizations, and
    /// the model mismatch of the stiff IMU factors between them changes with
    /// every back-substitution; damping the newest state cannot remove it,
    /// and rejecting on it discards good steps (measured: docs/smoother.md).
    kDampedFactors,
  };
  Acceptance acceptance = Acceptance::kDampedFactors;
  /// With kDampedFactors: a try that raises the damped factors' error by at
  /// most this (the smoother's cost units, half the sum of squared whitened
  /// residuals) is a tie, not an increase. 0: the paper's rule (rounding
  /// aside). A rejection keeps the newest state at its IMU prediction and
  /// relinearizes the whole window at the next update (4-10 ms), a far larger
  /// change than an increase of 1e-5, which no residual can show (0.005 sigma
  /// on one). rilod keeps 0: 1e-5 moved single 1 Hz runs by +-0.15 m both
  /// ways for no gain on the sets (docs/smoother.md).
  double tie_tolerance = 0.0;
  /// With kDampedFactors, a try back-substitutes only the cliques its test
  /// reads (the damped factors' variables and their ancestors), under the
  /// wildfire's own rule; the accepted try goes on into the rest of the
  /// tree. false: every try runs the whole wildfire, the reference the
  /// tests compare with (same decisions, same estimates).
  bool partial_tries = true;
  double lambda_increase = 10.0;
  double lambda_decrease = 0.1;
  /// Bound on D-iSAM2 tries in one update (each re-solves the tree): past it
  /// the previous estimate is kept, as at lambda_max. Bounds the worst update.
  int max_tries = 12;

  /// Throws std::invalid_argument naming the first bad field
  /// ("SmootherParams.d_isam2.<field> ...").
  void validate() const {
    auto fail = [](const char* field, const char* rule) {
      throw std::invalid_argument(std::string("SmootherParams.d_isam2.") + field + " " + rule);
    };
    if (!(lambda_min > 0.0)) fail("lambda_min", "must be > 0");
    if (!(lambda_max >= lambda_min)) fail("lambda_max", "must be >= lambda_min");
    if (!(lambda_initial >= lambda_min && lambda_initial <= lambda_max)) fail("lambda_initial", "must be in [lambda_min, lambda_max]");
    if (!(lambda_increase > 1.0)) fail("lambda_increase", "must be > 1");
    if (!(lambda_decrease > 0.0 && lambda_decrease < 1.0)) fail("lambda_decrease", "must be in (0, 1)");
    if (max_tries < 1) fail("max_tries", "must be >= 1");
    if (!(damping_min_new_error >= 0.0)) fail("damping_min_new_error", "must be >= 0");
    if (!(tie_tolerance >= 0.0)) fail("tie_tolerance", "must be >= 0");
  }
};

}  // namespace rilo
