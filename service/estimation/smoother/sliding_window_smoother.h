#pragma once
// Sliding-window smoother with marginalization (IMU-Ultrasonic-UWB paper, Sec. III-C6 and
// III-D4): Levenberg-Marquardt over every factor of a time window plus the
// marginal priors left by the states that fell out of it.
//
// update():
//   1. validate the input (nothing changes when it throws), insert the new
//      variables and factors;
//   2. Levenberg-Marquardt: linearize every factor at the estimate (robust
//      losses as IRLS weights, as BatchLevenbergMarquardt), solve
//      (J^T J + lambda I) d = -J^T r with CHOLMOD, accept on the nonlinear
//      error's gain ratio; a few iterations per update;
//   3. marginalize timed variables older than the window: linearize the
//      factors and priors touching them at the estimate (with first-estimate
//      Jacobians when enabled: see SlidingWindowParams), eliminate them from that dense
//      Gaussian by column-pivoting QR (rank revealing: unconstrained
//      directions are dropped, never NaN) and keep the result as one
//      LinearMarginal on their Markov blanket, merged with the priors it
//      replaces; the factors go, the final estimates wait in
//      drainMarginalized().
//
// The Hessian's pattern, its ordering (time order, untimed variables last:
// no fill beyond the IMU band and the anchor border) and CHOLMOD's symbolic
// analysis are built once per structure change (once per update in steady
// state) and reused across the iterations and by marginalCovariance().
// Cost grows linearly with the window (every iteration relinearizes and
// refactorizes all of it): 400 states x 15 dof with 4 ranges each take
// ~12 ms of CPU per update (tests/bench/sliding_window_bench.cpp).
// Not thread-safe: one smoother per estimation thread.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include "estimation/smoother/linear_marginal.h"
#include "estimation/smoother/sliding_window_params.h"
#include "estimation/smoother/smoother.h"
#include "estimation/solver/cholmod_context.h"

namespace rilo {

class SlidingWindowSmoother final : public Smoother {
 public:
  /// Throws std::invalid_argument for invalid params.
  explicit SlidingWindowSmoother(SlidingWindowParams params = {});
  ~SlidingWindowSmoother() override;
  SlidingWindowSmoother(const SlidingWindowSmoother&) = delete;
  SlidingWindowSmoother& operator=(const SlidingWindowSmoother&) = delete;

  /// UpdateStats filled: variables_added, factors_added, variables_total,
  /// factors_total (nonlinear + marginal priors), variables_marginalized,
  /// marginal_factors_created, marginal_factors_merged (earlier priors folded
  /// into the new one), step_tries (LM iterations), step_accepted (false: no
  /// step was accepted although the gradient was not negligible), lambda
  /// (final), error_before, error_after (after marginalization: the error of
  /// what the smoother holds), indeterminate_cliques (marginalizations whose
  /// eliminated block was rank deficient, plus LM factorizations that were
  /// not positive definite and were retried with more damping), time_s.
  UpdateStats update(const FactorGraph& new_factors, const Values& new_values,
                     const KeyTimestamps& timestamps = {}) override;

  Values estimate() const override { return estimate_; }
  Variable estimate(Key key) const override;
  bool exists(Key key) const override { return vars_.count(key) != 0; }
  /// Block of the inverse of the window's Hessian J^T J (nonlinear factors
  /// with their robust weights, and the marginal priors) at the estimate.
  std::optional<CovarianceBlock> marginalCovariance(Key key, std::string* failure = nullptr) override;
  double error() const override { return error_; }
  void drainMarginalized(std::vector<std::pair<Key, Variable>>& out) override;

  const SlidingWindowParams& params() const { return params_; }

  // --- Introspection (tests, diagnostics) ---------------------------------
  /// Nonlinear factors in the window.
  FactorGraph nonlinearFactors() const;
  /// Marginal priors (at most one per connected part of the window in steady state).
  const std::vector<LinearMarginalPtr>& linearMarginals() const { return priors_; }
  /// Error of every factor and prior recomputed at the estimate.
  double errorFromScratch() const;
  int variableCount() const { return static_cast<int>(vars_.size()); }
  int factorCount() const { return static_cast<int>(factors_.size() + priors_.size()); }
  /// FEJ: the linearization point a variable got when it first entered a
  /// marginal prior (nullopt: in none, or FEJ off).
  std::optional<Variable> firstEstimate(Key key) const;
  /// Times the symbolic analysis ran (structure changes), for tests.
  int symbolicAnalyses() const { return analyses_; }
  /// Marginalizations whose eliminated block was rank deficient (since construction).
  int rankDeficientMarginalizations() const { return rank_deficient_marginalizations_; }

 private:
  struct VarInfo {
    int dim = 0;
    bool timed = false;
    std::int64_t t_ns = 0;
    int pos = -1;          // position in the current ordering; -1: in no factor
    bool marginalize = false;
  };
  // One Hessian block of a factor or prior: its keys (i, j) (indices into
  // its key list) with pos(i) <= pos(j); the block's first row inside the
  // CSC columns of key j.
  struct BlockSlot {
    int i;
    int j;
    int row_start;
  };

  void validateInput(const FactorGraph& new_factors, const Values& new_values, const KeyTimestamps& timestamps) const;
  void buildStructure();
  /// Linearizes everything at estimate_ into H (undamped), g and the
  /// per-factor errors; returns the total error.
  double linearize();
  /// Error of every factor and prior at x (per-factor errors into `errors`).
  double evaluateError(const Values& x, std::vector<double>& errors) const;
  void setDiagonal(double lambda);
  void runLevenbergMarquardt(UpdateStats& stats);
  void marginalizeOldVariables(UpdateStats& stats);
  /// Prior residual and Jacobian as the optimizer sees it (FEJ: J = A).
  void evaluatePrior(const LinearMarginal& prior, const Values& x, Eigen::VectorXd& r, Eigen::MatrixXd& J) const;
  void multiplyHessian(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  double sumErrors() const;

  SlidingWindowParams params_;
  std::unordered_map<Key, VarInfo> vars_;
  Values estimate_;
  Values candidate_;               // same keys as estimate_: LM candidate, no allocation per iteration
  Values first_estimate_;          // FEJ linearization points of variables in priors
  std::vector<FactorPtr> factors_;
  std::vector<double> factor_errors_;  // at estimate_
  std::vector<LinearMarginalPtr> priors_;
  std::vector<double> prior_errors_;   // at estimate_
  std::vector<double> candidate_errors_;  // factors then priors
  double error_ = 0.0;
  std::int64_t newest_t_ns_ = 0;
  bool have_time_ = false;
  std::vector<std::pair<Key, Variable>> marginalized_;  // until drained

  // --- Linear system (rebuilt when the structure changes) -----------------
  bool structure_valid_ = false;
  std::vector<Key> ordering_;                 // keys in column (elimination) order
  std::vector<int> offsets_{0};               // ordering_.size() + 1
  int n_ = 0;
  std::vector<int> col_ptr_{0};
  std::vector<int> row_idx_;
  std::vector<double> values_;                // H (upper triangle), possibly damped on the diagonal
  std::vector<int> diag_idx_;
  Eigen::VectorXd undamped_diagonal_;
  Eigen::VectorXd gradient_;
  std::vector<int> factor_pos_;               // per factor key: position
  std::vector<std::size_t> factor_pos_begin_; // per factor (+1) into factor_pos_
  std::vector<BlockSlot> factor_slots_;
  std::vector<std::size_t> factor_slot_begin_;
  std::vector<int> prior_pos_;                // same for the priors
  std::vector<std::size_t> prior_pos_begin_;
  std::vector<BlockSlot> prior_slots_;
  std::vector<std::size_t> prior_slot_begin_;
  CholmodContext cholmod_;                    // declared before factor_: outlives it
  CholmodFactor factor_;
  int analyses_ = 0;
  int rank_deficient_marginalizations_ = 0;
  // State of values_: linearized at estimate_ (undamped) / factorized undamped.
  bool linearized_at_estimate_ = false;
  bool covariance_factorized_ = false;
  CholmodResult covariance_status_;

  // Scratch reused across iterations.
  Eigen::VectorXd step_;
  Eigen::VectorXd negative_gradient_;
  Eigen::VectorXd hessian_step_;
  Eigen::VectorXd prior_r_;
  Eigen::MatrixXd prior_J_;
  Eigen::MatrixXd prior_block_;
  std::vector<int> prior_cols_;
};

}  // namespace rilo
