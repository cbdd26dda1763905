#pragma once
// Parameters of BatchLevenbergMarquardt. Errors are FactorGraph::error values
// (sum of robust losses of whitened residuals, ~ chi^2 / 2); steps are tangent
// vectors (rad for rotations, m or m/s otherwise).
#include <atomic>
#include <stdexcept>
#include <string>

namespace rilo {

struct LmParams {
  enum class Damping {
    kMarquardt,  ///< D = diag(J^T J) clamped to [min_diagonal, max_diagonal] (Ceres): scale invariant
    kIdentity,   ///< D = I (Levenberg; GTSAM's default)
  };
  enum class Ordering {
    kColamd,   ///< fill-reducing COLAMD on the key adjacency
    kNatural,  ///< keys ascending (reference / debugging)
  };

  int max_iterations = 100;  ///< outer iterations (linearizations)
  /// Stop when an evaluated step changes the error, and the model predicts a
  /// change, of at most max(absolute_error_tolerance,
  /// relative_error_tolerance * error).
  double relative_error_tolerance = 1e-12;
  double absolute_error_tolerance = 1e-12;
  double gradient_tolerance = 1e-10;  ///< stop when |J^T r|_inf <= this
  double step_tolerance = 1e-10;      ///< stop when |step|_inf <= this (rad / m)

  // Identity: on range + IMU graphs the stiff IMU chains make Marquardt scaling
  // ill-conditioned (25 vs 10 iterations on a 60 s walk, same optimum).
  Damping damping = Damping::kIdentity;
  double lambda_initial = 1e-4;  ///< >= 0 (Ceres' initial radius 1e4); 0 tries an undamped Gauss-Newton step first
  /// Floor of lambda (> 0), also where lambda restarts when it must grow from
  /// 0. Keep it tiny (Ceres' 1 / max radius): graphs with stiff chains (IMU,
  /// bias random walk) have Marquardt-scaled Hessians with condition numbers
  /// near 1e14, and a floor above their smallest eigenvalue turns Gauss-Newton
  /// convergence into a crawl. Below indeterminate_pivot_ratio a gauge-free
  /// graph may report (and recover from) indeterminate factorizations.
  double lambda_min = 1e-16;
  double lambda_max = 1e12;    ///< give up (status kLambdaMaxReached) when lambda would exceed this
  double min_diagonal = 1e-6;  ///< Marquardt: clamp of diag(J^T J) (Ceres' min_lm_diagonal)
  double max_diagonal = 1e32;  ///< Marquardt: clamp of diag(J^T J) (Ceres' max_lm_diagonal)
  /// Accept a step when gain ratio rho = actual / predicted decrease exceeds this.
  double min_gain_ratio = 1e-3;
  /// A factorization is indeterminate (counted, lambda raised, retried) when
  /// CHOLMOD finds a pivot <= 0 or a pivot below this fraction of its diagonal
  /// entry (numerically singular: unconstrained variable, gauge freedom).
  double indeterminate_pivot_ratio = 1e-12;

  Ordering ordering = Ordering::kColamd;
  bool record_trace = true;  ///< fill LmResult::trace
  /// Checked before each iteration: once it reads true the solve stops with
  /// LmStatus::kCancelled (an initialization attempt over its time budget,
  /// localizer.h). nullptr: never. Not owned; must outlive the solve.
  const std::atomic<bool>* cancel = nullptr;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const {
    auto fail = [](const char* field, const char* rule) {
      throw std::invalid_argument(std::string("LmParams.") + field + " " + rule);
    };
    if (max_iterations < 0) fail("max_iterations", "must be >= 0");
    if (!(relative_error_tolerance >= 0.0)) fail("relative_error_tolerance", "must be >= 0");
    if (!(absolute_error_tolerance >= 0.0)) fail("absolute_error_tolerance", "must be >= 0");
    if (!(gradient_tolerance >= 0.0)) fail("gradient_tolerance", "must be >= 0");
    if (!(step_tolerance >= 0.0)) fail("step_tolerance", "must be >= 0");
    if (!(lambda_min > 0.0)) fail("lambda_min", "must be > 0");
    if (!(lambda_max >= lambda_min)) fail("lambda_max", "must be >= lambda_min");
    if (!(lambda_initial >= 0.0 && lambda_initial <= lambda_max)) fail("lambda_initial", "must be in [0, lambda_max]");
    if (!(min_diagonal > 0.0 && max_diagonal >= min_diagonal)) fail("min_diagonal", "must be > 0 and <= max_diagonal");
    if (!(min_gain_ratio >= 0.0 && min_gain_ratio < 1.0)) fail("min_gain_ratio", "must be in [0, 1)");
    if (!(indeterminate_pivot_ratio >= 0.0 && indeterminate_pivot_ratio < 1.0)) {
      fail("indeterminate_pivot_ratio", "must be in [0, 1)");
    }
  }
};

}  // namespace rilo
