#pragma once
// Outcome of BatchLevenbergMarquardt::optimize(): why it stopped, how the
// error evolved, and how much trouble the linear solver had. Numerical
// trouble is reported here, never thrown.
#include <string>
#include <vector>

namespace rilo {

enum class LmStatus {
  kErrorTolerance,       ///< error change below tolerance (converged)
  kGradientTolerance,    ///< |J^T r|_inf below tolerance (converged; also for a graph without variables)
  kStepTolerance,        ///< step below tolerance (converged)
  kMaxIterations,        ///< iteration budget used up
  kLambdaMaxReached,     ///< no acceptable step even at lambda_max
  kNonFiniteError,       ///< the initial error is NaN or infinite
  kLinearSolverFailure,  ///< CHOLMOD failed for a reason other than indefiniteness (e.g. out of memory)
  kCancelled,            ///< LmParams::cancel was set
};
const char* toString(LmStatus s);
/// True for the three tolerance statuses.
inline bool isConverged(LmStatus s) {
  return s == LmStatus::kErrorTolerance || s == LmStatus::kGradientTolerance || s == LmStatus::kStepTolerance;
}

/// One outer iteration (one linearization and its damped solve attempts).
struct LmIteration {
  int iteration = 0;
  double error = 0.0;       ///< error after the iteration (unchanged if no step was accepted)
  double lambda = 0.0;      ///< lambda of the last attempt
  double gain_ratio = 0.0;  ///< rho of the last evaluated step (0 if none)
  double step_norm = 0.0;   ///< |step|_inf of the last solved step (rad / m)
  int attempts = 0;         ///< factorizations tried in this iteration
  bool accepted = false;
  double time_s = 0.0;  ///< wall time since optimize() started (s)
};

struct LmResult {
  LmStatus status = LmStatus::kMaxIterations;
  std::string message;  ///< human-readable reason for status
  int iterations = 0;   ///< outer iterations performed
  double initial_error = 0.0;
  double final_error = 0.0;
  double final_lambda = 0.0;
  int rejected_steps = 0;                ///< solved steps that did not reduce the error enough
  int indeterminate_factorizations = 0;  ///< factorizations found not positive definite
  int factorizations = 0;                ///< all numeric factorizations
  std::vector<LmIteration> trace;        ///< per outer iteration (LmParams::record_trace)
  double time_s = 0.0;                   ///< total wall time (s)

  bool converged() const { return isConverged(status); }
};

}  // namespace rilo
