#pragma once
// Parameters of BayesTreeSmoother. Thresholds are on tangent vectors: rad for
// rotations, m, m/s, m/s^2 (accelerometer bias), rad/s (gyroscope bias).
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "estimation/math/types.h"

namespace rilo {

struct SmootherParams {
  enum class Method {
    kGaussNewton,  ///< iSAM2: Gauss-Newton step from the Bayes tree
    kDamped,       ///< D-iSAM2 (seed 000, Alg. 1): LM damping on the newest variables
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
  /// costs too much. Off by default: measured with rilo replay (d-isam2,
  /// asymmetric, 2-minute sims at 40 Hz), interval 0 / 0.1 / 0.25 s:
  ///   11 sims, replay defaults: online 0.339 / 0.341 / 0.343 m, mean update
  ///     0.75 / 0.46 / 0.35 ms (replay wall time 1.1-1.5x lower at 0.1 s);
  ///   the same with config/rilod.yaml (anchors as variables, 10 s lag):
  ///     0.285 / 0.293 m at 0.96 / 0.93 ms, no real gain;
  ///   3 TDoA + ultrasonic sims: 0.316 / 0.319 / 0.325 m.
  /// The error rises with the interval, most where ranging is clean (the
  /// severity-0 Localizer test: 0.245 / 0.250 / 0.283 m). Below 10 Hz an
  /// interval of 0.1 s changes nothing.
  double relinearize_interval_s = 0.0;
  /// Relinearize a variable when |delta|_inf reaches its threshold. Per
  /// variable kind: a 6-vector for poses ([rot; trans]) and biases ([accel;
  /// gyro]), a 3-vector for Vec3 variables; keyed by the key's symbol
  /// character. Symbols not listed use the default of their kind. Defaults
  /// ten times tighter than GTSAM's 0.1: the robust weights of the ranges
  /// only change when their state is relinearized, and with GTSAM's values
  /// D-iSAM2 on 2-minute hall sims (seeds 1-3, 40 Hz, asymmetric) had online
  /// APE 0.30/0.31/0.40 m, against 0.21/0.26/0.17 m now (smoothed
  /// 0.28/0.30/0.32 -> 0.17/0.23/0.11 m); 3x tighter gained nothing. Cost:
  /// mean update 0.4 -> 0.8-1.0 ms, p99 1.4 -> 2-5 ms. In the NLOS-heavy
  /// office sims the gain is 0-0.02 m.
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

  // --- Partial back-substitution -----------------------------------------
  /// Re-solve a clique only when a separator delta moved by more than this
  /// (GTSAM's wildfire threshold). 0 = exact back-substitution.
  double wildfire_threshold = 1e-3;

  // --- D-iSAM2 ------------------------------------------------------------
  /// An update whose new factors agree with the current estimate (their
  /// error there at most this) takes the Gauss-Newton step: there is no
  /// conflict for damping to arbitrate. That is an IMU-only state, predicted
  /// exactly by its IMU factor, and the acceptance test (kDampedFactors)
  /// would only see the error that factor picks up when older states move.
  /// At 1 Hz ranging damping them rejected every IMU-only update and the
  /// track diverged even on a clean walk. An update without new factors (an
  /// extra iteration) always damps the re-eliminated top.
  double damping_min_new_error = 1e-9;
  double lambda_initial = 1e-5;
  double lambda_min = 1e-10;
  double lambda_max = 1e5;     ///< relative to the diagonal; give up (keep the previous estimate) beyond this
  /// When damping the newest variables up to lambda_max still increases the
  /// error (the overshoot is in older variables: weakly observed yaw early in
  /// a run), retry from lambda_initial with every variable of the
  /// re-eliminated top damped: Levenberg-Marquardt on the affected part.
  /// Needed with Acceptance::kGlobal (measured: early-run yaw overshoot);
  /// with kDampedFactors it only doubled the tries of the rare rejected
  /// update (the worst update on the 60 s walk: 28 ms with it, 11 ms
  /// without, same online error on 2 of 3 seeds, +0.04 m on the third).
  bool widen_damping = false;
  /// Which nonlinear error a D-iSAM2 try must not increase.
  enum class Acceptance {
    /// Seed Alg. 1 literally: the whole graph's error.
    kGlobal,
    /// The error of the factors on the damped variables (the newest state,
    /// its IMU factor, its ranges): the part the damping controls. Older
    /// states keep a stale linearization point between relinearizations, and
    /// the model mismatch of the stiff IMU factors between them changes with
    /// every back-substitution; damping the newest state cannot remove it,
    /// and rejecting on it discards good steps. Measured on the 60 s walk
    /// (40 Hz, asymmetric): kGlobal 4.5-10 tries per update, 1.5-2.5% of
    /// updates rejected, online error up to 2x plain iSAM2's; this: 1.07
    /// tries, no rejection, online error equal to iSAM2's.
    kDampedFactors,
  };
  Acceptance acceptance = Acceptance::kDampedFactors;
  double lambda_increase = 10.0;
  double lambda_decrease = 0.1;
  /// Bound on D-iSAM2 tries in one update (each re-solves the tree): past it
  /// the previous estimate is kept, as at lambda_max. Bounds the worst update.
  int max_tries = 12;

  // --- Dog-leg (RISE) -----------------------------------------------------
  double trust_radius_initial = 0.1;  ///< seed 000: initial delta 0.1
  double trust_radius_min = 1e-8;     ///< stop shrinking (keep the linearization point) below this

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
  /// (measured: D-iSAM2 rejected 25% of updates on a clean walk). Default off.
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
    if (!(lambda_min > 0.0)) fail("lambda_min", "must be > 0");
    if (!(lambda_max >= lambda_min)) fail("lambda_max", "must be >= lambda_min");
    if (!(lambda_initial >= lambda_min && lambda_initial <= lambda_max)) fail("lambda_initial", "must be in [lambda_min, lambda_max]");
    if (!(lambda_increase > 1.0)) fail("lambda_increase", "must be > 1");
    if (!(lambda_decrease > 0.0 && lambda_decrease < 1.0)) fail("lambda_decrease", "must be in (0, 1)");
    if (max_tries < 1) fail("max_tries", "must be >= 1");
    if (!(damping_min_new_error >= 0.0)) fail("damping_min_new_error", "must be >= 0");
    if (!(trust_radius_initial > 0.0)) fail("trust_radius_initial", "must be > 0");
    if (!(trust_radius_min > 0.0 && trust_radius_min <= trust_radius_initial)) fail("trust_radius_min", "must be in (0, trust_radius_initial]");
    if (!(lag_s >= 0.0)) fail("lag_s", "must be >= 0");
    if (!(relinearize_max_age_s >= 0.0)) fail("relinearize_max_age_s", "must be >= 0");
    if (relinearize_min_recent_times < 0) fail("relinearize_min_recent_times", "must be >= 0");
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
