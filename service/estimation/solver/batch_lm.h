#pragma once
// Batch Levenberg-Marquardt over a whole factor graph on CHOLMOD: the
// reference solver and the smoother's initializer.
//
// Each outer iteration linearizes all factors (robust IRLS weights), then
// solves (J^T J + lambda D) d = -J^T r with D = diag(J^T J) clamped
// (Marquardt) or I, and retracts. The gain ratio rho = actual / predicted
// decrease uses the nonlinear FactorGraph::error (signed robust losses) and
// the undamped quadratic model. Trust-region schedule after Nielsen: on
// success lambda *= max(1/3, 1 - (2 rho - 1)^3), nu = 2; on failure
// lambda *= nu, nu *= 2. A factorization that is not positive definite
// (unconstrained variable, gauge freedom) is counted and retried with a
// larger lambda: numerical trouble ends in an LmStatus, never an exception.
//
// The ordering, the Hessian pattern and CHOLMOD's symbolic analysis are
// computed once per graph structure and reused by later optimize() calls on
// a graph with the same factor keys. Not thread-safe: one solver per thread.
#include <Eigen/Core>
#include <optional>
#include <string>

#include "estimation/graph/factor.h"
#include "estimation/solver/cholmod_context.h"
#include "estimation/solver/lm_params.h"
#include "estimation/solver/lm_result.h"
#include "estimation/solver/normal_equations.h"

namespace rilo {

class BatchLevenbergMarquardt {
 public:
  /// Marginal covariance of one variable (dim x dim, tangent chart of Values).
  using CovarianceBlock = rilo::CovarianceBlock;

  struct Output {
    Values values;  ///< optimized values (keys in no factor are copied unchanged)
    LmResult result;
  };

  /// Throws std::invalid_argument for invalid params (see LmParams::validate).
  explicit BatchLevenbergMarquardt(LmParams params = {});

  const LmParams& params() const { return params_; }

  /// Optimizes every variable that appears in a factor, starting at
  /// `initial`. Throws std::invalid_argument only for inconsistent input (a
  /// factor key without an initial value, a factor repeating a key).
  Output optimize(const FactorGraph& graph, const Values& initial);

  /// Marginal covariance of `key` at the solution of the last optimize(): the
  /// key's diagonal block of (J^T J)^-1 (undamped, robust-weighted), from
  /// CHOLMOD solves on the key's identity columns. Returns nullopt (reason in
  /// *failure when given) if that system is indeterminate. Throws
  /// std::logic_error before the first optimize() and std::out_of_range for a
  /// key that was not optimized.
  std::optional<CovarianceBlock> marginalCovariance(Key key, std::string* failure = nullptr);

  /// Marginal covariance of `key` at `values` without optimizing: one
  /// linearization and factorization of J^T J there (the Initializer's gate
  /// probe). The same as optimize() with max_iterations 0 followed by
  /// marginalCovariance(key), and afterwards marginalCovariance() answers for
  /// other keys at `values` the same way. What it builds serves the next
  /// optimize(): the ordering, the Hessian pattern and CHOLMOD's symbolic
  /// analysis (reused as for any graph of the same structure) and, when that
  /// optimize() starts from the same values, the linearization and the error
  /// at the start (its first iteration's). Throws as optimize() and
  /// marginalCovariance() do.
  std::optional<CovarianceBlock> covarianceAt(const FactorGraph& graph, const Values& values, Key key,
                                              std::string* failure = nullptr);

 private:
  void checkKeys(const FactorGraph& graph, const Values& values) const;
  /// normal_ holds the undamped linearization at `values` (left by covarianceAt).
  bool holdsLinearizationAt(const FactorGraph& graph, const Values& values) const;
  bool structureMatches(const FactorGraph& graph, const Values& values) const;
  void buildStructure(const FactorGraph& graph, const Values& values, LmResult& result);
  void setDampedDiagonal(double lambda);
  bool increaseLambda(double& lambda, double& nu) const;

  LmParams params_;
  CholmodContext cholmod_;  // declared before factor_: outlives it
  CholmodFactor factor_;
  NormalEquations normal_;

  // Structure the ordering / pattern / symbolic factor were built for.
  bool structure_valid_ = false;
  std::vector<Key> structure_keys_;           // factor keys, flattened
  std::vector<std::size_t> structure_sizes_;  // keys per factor

  // Per-iteration buffers (sized once per structure).
  Eigen::VectorXd undamped_diagonal_;
  Eigen::VectorXd damping_;
  Eigen::VectorXd negative_gradient_;
  Eigen::VectorXd step_;
  Eigen::VectorXd hessian_step_;

  // State for marginalCovariance().
  bool have_solution_ = false;
  bool linearized_at_solution_ = false;  // normal_ holds J^T J at the solution (diagonal possibly damped)
  bool covariance_factorized_ = false;
  // covarianceAt() left normal_ linearized (undamped) at solution_values_
  // with this error there; cleared by anything that changes normal_.
  bool start_linearized_ = false;
  double start_error_ = 0.0;
  CholmodResult covariance_status_;
  FactorGraph solution_graph_;
  Values solution_values_;
  Eigen::VectorXd unit_columns_;
  Eigen::VectorXd solved_columns_;
};

}  // namespace rilo
