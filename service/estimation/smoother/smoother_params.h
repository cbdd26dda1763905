#pragma once
// Parameters of BayesTreeSmoother. Thresholds are on tangent vectors: rad for
// rotations, m, m/s, m/s^2 (accelerometer bias), rad/s (gyroscope bias).
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "estimation/smoother/d_isam2_params.h"
#include "estimation/smoother/dogleg_params.h"
#include "math/types.h"

namespace rilo {

struct SmootherParams {
  enum class Method {
    kGaussNewton,  ///< iSAM2: Gauss-Newton step from the Bayes tree
    kDamped,       ///< D-iSAM2 (Ranging-IMU Fusion paper, Alg. 1): LM damping on the newest variables
    kDogleg,       ///< RISE: incremental Powell's dog-leg
  };
  Method method = Method::kDamped;

  // --- Fluid relinearization ---------------------------------------------
  /// Check for relinearization every this many updates (GTSAM's relinearizeSkip).
  int relinearize_skip = 1;
  /// ...and at most once per this much data time (s, by the newest
  /// timestamp; 0: at every update the skip allows). An update without new
  /// variables (an extra iteration) always checks. A cadence in data time
  /// rather than in updates, for boards where dense ranging (many updates a
  /// second, each threshold pass re-eliminating the paths it relinearizes)
  /// costs too much. Off by default: the error rises with the interval, most
  /// where ranging is clean, for little saved time with the service's
  /// settings; below 10 Hz an interval of 0.1 s changes nothing. Measured in
  /// docs/smoother.md ("Figures behind the defaults").
  double relinearize_interval_s = 0.0;
  /// Relinearize a variable when |delta|_inf reaches its threshold. Per
  /// variable kind: a 6-vector for poses ([rot; trans]) and biases ([accel;
  /// gyro]), a 3-vector for Vec3 variables; keyed by the key's symbol
  /// character. Symbols not listed use the default of their kind. Defaults
  /// ten times tighter than GTSAM's 0.1: the robust weights of the ranges
  /// only change when their state is relinearized: tighter thresholds keep
  /// them fresh, at about twice the update time (measured in
  /// docs/smoother.md, "Figures behind the defaults").
  std::unordered_map<char, Vec6> relinearize_thresholds6;
  std::unordered_map<char, Vec3> relinearize_thresholds3;
  Vec6 default_pose_threshold = (Vec6() << 0.01, 0.01, 0.01, 0.02, 0.02, 0.02).finished();
  Vec6 default_bias_threshold = (Vec6() << 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4).finished();
  Vec3 default_vec3_threshold = Vec3::Constant(0.02);
  /// Variables introduced by the last this-many updates are relinearized at
  /// every update (their delta is rarely below threshold, and the robust
  /// weights of the range factors on the newest states must stay fresh).
  /// D-iSAM2 needs at least 1 once older states relinearize: with the previous
  /// state stale, its stiff IMU factor to the new one dominates the error the
  /// acceptance test compares, and almost every try is rejected
  /// (dampedWithStalePreviousState; docs/smoother.md). 0 suits exact-algebra
  /// tests, which relinearize nothing.
  int always_relinearize_recent_updates = 1;
  /// When any variable passes its threshold, relinearize every variable that
  /// moved, not just that one. A linearization point mixing fresh and stale
  /// states leaves large residuals at theta on the stiff IMU factors between
  /// them, and the Gauss-Newton model's neglected second-order terms change
  /// the whole-graph error: with Acceptance::kGlobal that rejected 25% of
  /// updates. With the default acceptance (kDampedFactors) mixed epochs cost
  /// nothing, and relinearizing the whole window at once is the worst update
  /// (18-30 ms on the 40 Hz walk), so the default is off.
  bool relinearize_together = false;
  /// Upper bound on variables relinearized by threshold in one update (largest
  /// relative delta first; the rest wait for the next update): bounds the
  /// re-elimination after a large correction. 0 = unbounded. Ignored with
  /// relinearize_together (a partial set is what that option avoids).
  int max_relinearized_variables = 0;
  /// Timed variables older than this (s, behind the newest) keep their
  /// linearization point: relinearizing an old state re-eliminates every
  /// clique from its own up to the root, so this bounds the worst update.
  /// They are near the end of the lag and soon marginalized at that point
  /// anyway. 0 = no limit.
  double relinearize_max_age_s = 1.0;
  /// ...but the timed variables of the newest this-many distinct timestamps
  /// are never frozen by age. The cost the age limit bounds grows with the
  /// number of states behind the newest, not with seconds: at 40 Hz ranging
  /// 1 s is 40 states, at 1 Hz only two, and freezing states after one or two
  /// ranges left the stiff IMU factors linearized far from the estimate (at
  /// 1 Hz the asymmetric model then tracked a clean walk to 3.4 m instead of
  /// 0.6 m). 0: the age limit alone.
  int relinearize_min_recent_times = 40;
  /// After a rejected D-iSAM2 step every moved variable is relinearized at
  /// the kept estimate, which re-eliminates the whole tree (the real-time
  /// tail, docs/smoother.md). > 0: only timed variables this young (s behind
  /// the newest) are; older states and the static variables (anchors) keep
  /// their linearization point, and their kept delta until a back-substitution
  /// or their own threshold reaches them. 0 = the whole window.
  double after_rejection_max_age_s = 0.0;

  // --- Partial back-substitution -----------------------------------------
  /// Re-solve a clique only when a separator delta moved by more than this
  /// (GTSAM's wildfire threshold). 0 = exact back-substitution.
  double wildfire_threshold = 1e-3;

  // --- Error bookkeeping --------------------------------------------------
  /// Keep the nonlinear error at the estimate current after every update
  /// (UpdateStats::error_before / error_after; error() in O(1)). Off, an
  /// update re-evaluates only the factor errors its step reads: D-iSAM2's
  /// damped factors (Acceptance::kDampedFactors), none for iSAM2; the
  /// stats' errors are NaN and error() sums every factor. The estimates are
  /// the same. Dog-leg and Acceptance::kGlobal read the whole error and keep
  /// it regardless. Measured: the refresh was 14 % of a 40 Hz replay with
  /// config/rilod.yaml (docs/smoother.md, "The real-time tail").
  bool track_error = true;

  // --- Step policies ----------------------------------------------------
  /// D-iSAM2's damping (method kDamped) and RISE's trust region (kDogleg);
  /// iSAM2's Gauss-Newton step has no parameters of its own.
  DIsam2Params d_isam2;
  DoglegParams dogleg;

  // --- Fixed lag ----------------------------------------------------------
  /// Variables whose timestamp is older than (newest timestamp - lag) are
  /// marginalized. 0 = keep everything (full smoother).
  double lag_s = 0.0;

  /// GTSAM freezes the linearization point of every variable a marginal
  /// touches (first-estimate Jacobians). A linear marginal is exact at any
  /// linearization point (it is linear in local(x0, x)), and with anchors
  /// fixing the gauge there is no unobservable direction to protect; frozen
  /// states, however, drift away from their linearization point while their
  /// neighbours are relinearized, and the stiff IMU factors between them then
  /// carry large residuals at theta that wreck the Gauss-Newton model
  /// (D-iSAM2 then rejects many updates; docs/smoother.md). Default off.
  bool freeze_marginal_variables = false;

  // --- Numerics -----------------------------------------------------------
  /// A frontal pivot |R_ii| below this fraction of its column's norm marks a
  /// clique rank deficient; it is then re-eliminated with regularization rows
  /// sqrt(regularization) * I on its frontals (reported as indeterminate).
  double rank_tolerance = 1e-10;
  double regularization = 1e-9;

  /// D-iSAM2 with the previous update's variables left at a stale
  /// linearization point (always_relinearize_recent_updates 0): rilod's
  /// configuration and rilo replay refuse it with this reason (validate()
  /// cannot: the exact-algebra tests use it with no relinearization at all).
  bool dampedWithStalePreviousState() const {
    return method == Method::kDamped && always_relinearize_recent_updates == 0;
  }
  static constexpr const char* kDampedNeedsRecentRelinearization =
      "relinearization.recent_updates must be >= 1 with smoother d-isam2 (its damped acceptance needs the previous "
      "state relinearized)";

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const {
    auto fail = [](const char* field, const char* rule) {
      throw std::invalid_argument(std::string("SmootherParams.") + field + " " + rule);
    };
    if (relinearize_skip < 1) fail("relinearize_skip", "must be >= 1");
    if (!(relinearize_interval_s >= 0.0 && relinearize_interval_s <= 3600.0)) fail("relinearize_interval_s", "must be in [0, 3600] s");
    if (always_relinearize_recent_updates < 0) fail("always_relinearize_recent_updates", "must be >= 0");
    if (max_relinearized_variables < 0) fail("max_relinearized_variables", "must be >= 0");
    if (!(wildfire_threshold >= 0.0)) fail("wildfire_threshold", "must be >= 0");
    d_isam2.validate();
    dogleg.validate();
    if (!(lag_s >= 0.0)) fail("lag_s", "must be >= 0");
    if (!(relinearize_max_age_s >= 0.0)) fail("relinearize_max_age_s", "must be >= 0");
    if (relinearize_min_recent_times < 0) fail("relinearize_min_recent_times", "must be >= 0");
    if (!(after_rejection_max_age_s >= 0.0)) fail("after_rejection_max_age_s", "must be >= 0");
    if (!(rank_tolerance > 0.0 && rank_tolerance < 1.0)) fail("rank_tolerance", "must be in (0, 1)");
    if (!(regularization > 0.0)) fail("regularization", "must be > 0");
    auto nonnegative = [](const auto& v) { return (v.array() >= 0.0).all(); };
    if (!nonnegative(default_pose_threshold) || !nonnegative(default_bias_threshold) || !nonnegative(default_vec3_threshold)) {
      fail("default_*_threshold", "must be >= 0");
    }
    for (const auto& [symbol, t] : relinearize_thresholds6) {
      if (!nonnegative(t)) fail("relinearize_thresholds6", "must be >= 0");
    }
    for (const auto& [symbol, t] : relinearize_thresholds3) {
      if (!nonnegative(t)) fail("relinearize_thresholds3", "must be >= 0");
    }
  }
};

}  // namespace rilo
