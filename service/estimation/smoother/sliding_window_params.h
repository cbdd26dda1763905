#pragma once
// Parameters of SlidingWindowSmoother (IMU-Ultrasonic-UWB paper, Sec. III-C6 / III-D4):
// window length, the Levenberg-Marquardt iterations run in every update, and
// how the marginalization prior is linearized. Errors are FactorGraph::error
// values (sum of robust losses of whitened residuals); steps are tangent
// vectors (rad for rotations, m, m/s, m/s^2 and rad/s otherwise).
#include <stdexcept>
#include <string>

namespace rilo {

struct SlidingWindowParams {
  /// Timed variables older than (newest timestamp - window_s) are
  /// marginalized at the end of each update; untimed ones (anchors) never.
  /// 0 = keep everything (a full batch smoother).
  double window_s = 5.0;

  // --- Levenberg-Marquardt (one run per update) ---------------------------
  /// Bound on the outer iterations (linearizations) per update. The previous
  /// update's estimate plus the IMU prediction of the new state is a good
  /// start: in steady state the tolerances below stop after 1-2 iterations,
  /// and the bound matters at start-up and after large corrections.
  int max_iterations = 6;
  /// Damping H + lambda I (Levenberg, as BatchLevenbergMarquardt's default:
  /// Marquardt scaling is ill-conditioned on the stiff IMU chains). Every
  /// update starts at lambda_initial; the schedule is Nielsen's.
  double lambda_initial = 1e-4;
  double lambda_min = 1e-12;
  double lambda_max = 1e10;   ///< give up the update (keep the estimate) beyond this
  /// Accept a step when actual / predicted error decrease exceeds this.
  double min_gain_ratio = 1e-3;
  /// Converged when the model predicts a decrease of at most
  /// max(absolute_error_tolerance, relative_error_tolerance * error) (the
  /// step is then kept if it did not increase the error). The error is
  /// chi^2 / 2, and the predicted decrease of a Gauss-Newton step is half its
  /// squared length in the metric of the window's information: 0.5 stops
  /// once a step moves the window by less than one standard deviation
  /// (jointly, so by less than one sigma in any single coordinate), and the
  /// next update carries on from there. Measured on the 40 Hz walk with 4
  /// ranges per state (2 s window): 1.09 iterations per update at this
  /// tolerance, 1.96 at 0.05, 2.6 at 1e-2; the newest state's online error
  /// was the same to 1 cm in all three (robust range losses make the
  /// iterations after the first crawl: IRLS converges linearly).
  double relative_error_tolerance = 1e-6;
  double absolute_error_tolerance = 0.5;
  double step_tolerance = 1e-5;      ///< converged when |step|_inf <= this (rad / m ...)
  double gradient_tolerance = 1e-9;  ///< converged when |J^T r|_inf <= this before a step

  // --- Marginalization ----------------------------------------------------
  /// First-estimate Jacobians (FEJ). A marginal prior is the Gaussian
  ///   r(x) = A * [local(x0_1, x_1); ...; local(x0_k, x_k)] - d
  /// (LinearMarginal) over the Markov blanket, x0 its linearization point.
  /// Its residual is always evaluated exactly in that chart. With FEJ:
  ///  - the optimizer uses A as its Jacobian at every estimate (the one taken
  ///    at x0), not the exact A * d local(x0, x (+) delta) / d delta;
  ///  - a variable keeps the x0 it got when it first entered a prior, and
  ///    later marginalizations take the Jacobians of the factors they remove
  ///    there (residuals and robust weights at the estimate), so all the
  ///    information the priors hold about a variable shares one
  ///    linearization point: the priors add no information along directions
  ///    the linearized data leave unobservable (the consistency argument of
  ///    the IMU-Ultrasonic-UWB paper and of FEJ estimators).
  /// Without FEJ the prior's Jacobian is exact at the estimate and every
  /// marginalization linearizes at the estimate. The nonlinear factors in the
  /// window are relinearized at the estimate either way. For Vec3 and ImuBias
  /// variables local(x0, x) = x - x0, so the two Jacobians of a prior differ
  /// only in pose blocks (Jr^-1 of the rotation change, the rotation of the
  /// translation part); the marginalization points differ for every kind.
  ///
  /// Default off, measured: on the range + IMU walks anchors with survey
  /// priors fix the gauge and the yaw is weakly observable, not unobservable;
  /// a first estimate that is one update old is then a poorer linearization
  /// than the current one (the FEJ2 argument), and FEJ made the estimate both
  /// farther from batch and overconfident (docs/smoother.md, Figures behind
  /// the defaults).
  bool first_estimate_jacobians = false;
  /// Marginalization eliminates by column-pivoting QR: a pivot below this
  /// fraction of the largest marks the marginalized block rank deficient
  /// (its unconstrained directions carry no information and are dropped, so
  /// no NaN; counted in UpdateStats::indeterminate_cliques).
  double rank_tolerance = 1e-10;
  /// A factorization is indeterminate (lambda raised, retried; for
  /// marginalCovariance: nullopt) when CHOLMOD finds a pivot <= 0 or below
  /// this fraction of its diagonal entry.
  double indeterminate_pivot_ratio = 1e-12;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const {
    auto fail = [](const char* field, const char* rule) {
      throw std::invalid_argument(std::string("SlidingWindowParams.") + field + " " + rule);
    };
    if (!(window_s >= 0.0) || window_s > 1e9) fail("window_s", "must be in [0, 1e9]");
    if (max_iterations < 1) fail("max_iterations", "must be >= 1");
    if (!(lambda_min > 0.0)) fail("lambda_min", "must be > 0");
    if (!(lambda_max >= lambda_min)) fail("lambda_max", "must be >= lambda_min");
    if (!(lambda_initial >= 0.0 && lambda_initial <= lambda_max)) fail("lambda_initial", "must be in [0, lambda_max]");
    if (!(min_gain_ratio >= 0.0 && min_gain_ratio < 1.0)) fail("min_gain_ratio", "must be in [0, 1)");
    if (!(relative_error_tolerance >= 0.0)) fail("relative_error_tolerance", "must be >= 0");
    if (!(absolute_error_tolerance >= 0.0)) fail("absolute_error_tolerance", "must be >= 0");
    if (!(step_tolerance >= 0.0)) fail("step_tolerance", "must be >= 0");
    if (!(gradient_tolerance >= 0.0)) fail("gradient_tolerance", "must be >= 0");
    if (!(rank_tolerance > 0.0 && rank_tolerance < 1.0)) fail("rank_tolerance", "must be in (0, 1)");
    if (!(indeterminate_pivot_ratio >= 0.0 && indeterminate_pivot_ratio < 1.0)) {
      fail("indeterminate_pivot_ratio", "must be in [0, 1)");
    }
  }
};

}  // namespace rilo
