#pragma once
// Incremental smoothing on our own Bayes tree (iSAM2, Kaess et al. 2012), with
// the step policies of the Ranging-IMU Fusion paper, one file each: plain iSAM2 (Gauss-Newton,
// isam2_step.cpp), D-iSAM2 (Levenberg-Marquardt damping on the newest
// variables, Alg. 1: d_isam2_step.cpp) and RISE (incremental Powell's
// dog-leg: dogleg_step.cpp); optional fixed-lag marginalization.
//
// update():
//   1. insert new variables (delta 0) and pick the variables to marginalize;
//   2. fluid relinearization: retract variables whose |delta| passed their
//      threshold, plus the newest variables (fresh robust weights);
//   3. remove the top of the tree above every affected variable; its
//      children become orphans carrying their cached separator factor;
//   4. re-eliminate the top: CCOLAMD (marginalizable keys first, keys of new
//      factors last), symbolic elimination into cliques, dense staircase QR
//      per clique; orphans re-attach below the clique of their separator;
//   5. step: back-substitute only where something moved (wildfire), then
//      accept / damp (D-iSAM2) or bound the step (dog-leg), with the
//      nonlinear error kept incrementally per factor;
//   6. marginalize variables older than the lag: they are leaves by
//      construction, their cached factors become a linear marginal on the
//      Markov blanket, and their slots are reused.
// Details and the reasoning: docs/smoother.md.
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <deque>
#include <vector>

#include "estimation/smoother/dense_qr.h"
#include "estimation/smoother/linear_marginal.h"
#include "estimation/smoother/smoother.h"
#include "estimation/smoother/smoother_params.h"

namespace rilo {

class BayesTreeSmoother final : public Smoother {
 public:
  /// Throws std::invalid_argument for invalid params.
  explicit BayesTreeSmoother(SmootherParams params = {});
  ~BayesTreeSmoother() override;

  UpdateStats update(const FactorGraph& new_factors, const Values& new_values,
                     const KeyTimestamps& timestamps = {}) override;

  Values estimate() const override;
  Variable estimate(Key key) const override;
  bool exists(Key key) const override;
  std::optional<CovarianceBlock> marginalCovariance(Key key, std::string* failure = nullptr) override;
  /// O(1) with SmootherParams::track_error; otherwise a sum over every factor.
  double error() const override { return tracksError() ? error_at_estimate_ : errorFromScratch(); }
  void drainMarginalized(std::vector<std::pair<Key, Variable>>& out) override {
    out.insert(out.end(), std::make_move_iterator(marginalized_.begin()), std::make_move_iterator(marginalized_.end()));
    marginalized_.clear();
  }

  const SmootherParams& params() const { return params_; }

  // --- Introspection (tests, diagnostics) ---------------------------------
  /// Linearization point of every variable.
  const Values& linearizationPoint() const { return theta_; }
  /// Current linear step of a variable (estimate = theta (+) delta).
  Eigen::VectorXd delta(Key key) const;
  /// Nonlinear error recomputed from scratch over all factors (O(factors)).
  double errorFromScratch() const;
  /// Nonlinear factors currently held (not yet marginalized).
  FactorGraph nonlinearFactors() const;
  /// Linear marginals currently held (fixed-lag).
  std::vector<LinearMarginalPtr> linearMarginals() const;
  /// Variables whose linearization point is frozen by a linear marginal.
  std::vector<Key> frozenKeys() const;
  int cliqueCount() const;
  int variableCount() const { return static_cast<int>(key_to_var_.size()); }
  int factorCount() const { return live_factors_; }
  /// Capacity of the slot pools (bounded in fixed-lag operation).
  std::size_t slotCapacity() const { return vars_.size() + factors_.size() + cliques_.size(); }
  /// Checks the tree's structural invariants (running intersection, every
  /// factor's keys inside its clique, parent/child links); returns the first
  /// violation or an empty string.
  std::string checkInvariants() const;

 private:
  using VarId = int;
  using FactorId = int;
  using CliqueId = int;
  static constexpr int kNone = -1;
  // Bounds on the diagonal that scales the D-iSAM2 damping (as GTSAM's LM).
  static constexpr std::size_t kMaxUndrainedMarginalized = 100'000;
  static constexpr double kMinDampingDiagonal = 1e-6;
  static constexpr double kMaxDampingDiagonal = 1e32;

  struct VarSlot {
    bool alive = false;
    Key key = 0;
    int dim = 0;
    Vec6 delta = Vec6::Zero();         // tree solution (D-iSAM2: of the accepted damping)
    Vec6 step = Vec6::Zero();          // applied step (dog-leg; equals delta otherwise)
    Vec6 damping_center = Vec6::Zero(); // D-iSAM2: the accepted delta a damped variable is held to
    CliqueId clique = kNone;
    std::vector<FactorId> factors;     // factors touching the variable
    int frozen = 0;                    // linear marginals touching it
    std::int64_t t_ns = 0;
    bool has_time = false;
    std::uint64_t introduced_at = 0;   // update count when inserted
    Vec6 threshold = Vec6::Zero();
    // scratch (stamped to avoid clearing)
    std::uint64_t mark = 0;
    int pos = -1;                      // position in the current top ordering
    int col = -1;                      // column offset in the clique being eliminated
    std::uint64_t moved = 0;           // back-substitution: delta moved beyond the wildfire threshold
    std::uint64_t logged = 0;          // undo log holds this variable's delta for the current try
    std::uint64_t damped = 0;          // D-iSAM2 damps this variable in the current update
    bool marginalize = false;          // selected for marginalization in the current update
    Vec6 gradient = Vec6::Zero();      // dog-leg: -R^T d, summed over the cliques holding the variable
  };

  struct FactorSlot {
    bool alive = false;
    FactorPtr nonlinear;               // exactly one of nonlinear / marginal is set
    LinearMarginalPtr marginal;
    std::vector<VarId> vars;           // in the factor's key order
    CliqueId clique = kNone;
    RowMajorMatrixXd linear;           // [A | b] at theta: rows x (sum dims + 1), upper triangular
    bool needs_linearization = true;
    double error = 0.0;                // at the estimate
    double error_at_theta = 0.0;       // dog-leg reference
    std::uint64_t mark = 0;
  };

  struct Clique {
    bool alive = false;
    std::vector<VarId> frontals;       // in elimination order
    std::vector<VarId> separator;
    int frontal_dim = 0;
    int separator_dim = 0;
    CliqueId parent = kNone;
    std::vector<CliqueId> children;
    std::vector<FactorId> factors;     // factors assigned (first-eliminated key here)
    RowMajorMatrixXd conditional;      // frontal_dim x (frontal_dim + separator_dim + 1): [R S | d]
    RowMajorMatrixXd message;          // k x (separator_dim + 1): [R_sep | d_sep], upper triangular
    bool replaced = false;             // re-eliminated during the current update
    Eigen::VectorXd gradient;          // dog-leg: this clique's -[R S]^T d (frontals, then separator)
    std::uint64_t mark = 0;
    std::uint64_t solved = 0;          // == the back-substitution's moved stamp: solved by backSubstitutePart
  };

  // update() stages
  void validateInput(const FactorGraph& new_factors, const Values& new_values, const KeyTimestamps& timestamps) const;
  void insertVariables(const Values& new_values, const KeyTimestamps& timestamps, UpdateStats& stats);
  std::vector<FactorId> insertFactors(const FactorGraph& new_factors, UpdateStats& stats);
  std::vector<VarId> selectMarginalizable() const;
  void noteRecentTime(std::int64_t t_ns);
  /// Whether relinearize_interval_s of data time passed since the last
  /// threshold pass (or none ran yet, or this update added no variables).
  bool thresholdIntervalElapsed(const UpdateStats& stats) const;
  void relinearize(std::vector<VarId>& marked, const std::vector<VarId>& marginalizable, UpdateStats& stats);
  void markForCleanMarginalization(const std::vector<VarId>& marginalizable, std::vector<VarId>& marked,
                                   UpdateStats& stats);
  void updateTree(const std::vector<VarId>& marked, const std::vector<FactorId>& new_factors, UpdateStats& stats);
  // Step policies, one file each: isam2_step.cpp, d_isam2_step.cpp, dogleg_step.cpp.
  void stepGaussNewton(UpdateStats& stats);
  /// D-iSAM2: marks the variables this update damps (damp_stamp_) and says
  /// whether it damps at all; before updateTree, whose elimination adds the
  /// damping rows.
  bool markDampedVariables(const std::vector<FactorId>& added, const Values& new_values, std::vector<VarId>& damped);
  /// D-iSAM2's lambda loop over the damped variables (the Gauss-Newton step
  /// when `damp` is false; the whole re-eliminated top when none are marked).
  void stepDamped(bool damp, std::vector<VarId>& damped_vars, UpdateStats& stats);
  void stepDogleg(UpdateStats& stats);
  void marginalize(const std::vector<VarId>& marginalizable, UpdateStats& stats);

  // Bayes tree
  std::vector<CliqueId> removeTop(const std::vector<VarId>& marked, std::vector<VarId>& top_vars,
                                  std::vector<FactorId>& top_factors);
  void eliminateTop(const std::vector<VarId>& top_vars, const std::vector<FactorId>& top_factors,
                    const std::vector<CliqueId>& orphans, const std::vector<Key>& last_keys, UpdateStats& stats);
  /// Numeric elimination of one clique from its factors, children's messages
  /// and (when lambda > 0) damping rows on its frontals in `damped_vars`.
  void eliminateClique(CliqueId c, double lambda, UpdateStats& stats);
  void linearizeFactor(FactorSlot& f);
  /// Copies the rows of a block row [A_1 .. A_k | b] over `vars` into W:
  /// block k at its variable's column (VarSlot::col), b at `rhs_col`; row i
  /// goes to dest[i], or to first_row + i when dest is null.
  void scatterRows(const RowMajorMatrixXd& blocks, const std::vector<VarId>& vars, Eigen::Ref<RowMajorMatrixXd> W,
                   int rhs_col, const int* dest, int first_row) const;
  /// Back-substitution from the roots; re-solves replaced cliques and those
  /// whose separator moved by more than `threshold`. Appends every variable
  /// whose delta changed to `changed`, logging the old delta for undo.
  /// `moved` continues an earlier backSubstitutePart (0: a fresh pass): its
  /// marks, and the cliques it solved are not solved again.
  void backSubstitute(double threshold, UpdateStats& stats, std::uint64_t moved = 0);
  /// The same wildfire restricted to `cliques` (children first, closed
  /// under ancestors): each is solved under the same rule as in
  /// backSubstitute, so their variables come out as the whole pass would
  /// give them. Returns the stamp its moved variables carry.
  std::uint64_t backSubstitutePart(const std::vector<CliqueId>& cliques, double threshold, UpdateStats& stats);
  void solveClique(CliqueId c, double threshold, std::uint64_t moved_stamp);
  /// The wildfire's rule: re-eliminated, or a separator variable moved.
  bool needsSolve(const Clique& q, std::uint64_t moved) const;

  // Error bookkeeping
  double factorError(const FactorSlot& f, const Values& x) const;
  void refreshEstimate(VarId v);
  /// Estimates and factor errors of changed_vars_ from index `from` on.
  void refreshErrorsOfChanged(bool log_undo, std::size_t from = 0);
  /// Whether error_at_estimate_ is kept current (SmootherParams::track_error,
  /// or a step policy that reads the whole error).
  bool tracksError() const;
  /// Re-evaluates (once each) the factors touching `vars` at the estimate and
  /// updates the running sum, logging old errors for undo when asked.
  void refreshFactorErrors(std::span<const VarId> vars, bool log_undo);
  void logDelta(VarId v);
  void undoStep();
  /// D-iSAM2 (Acceptance::kDampedFactors): error change of this try on the
  /// factors of the damped variables.
  /// `scale` (optional): the sum of their errors' magnitudes before and after.
  double dampedFactorsErrorChange(double* scale = nullptr) const;
  /// Diagonal of J^T J for variable v over its factors (scales the damping).
  Vec6 informationDiagonal(VarId v) const;
  /// D-iSAM2's damping rows on the damped frontals of clique q (none at
  /// lambda 0): their count, their leading columns (row_leading_ from r), and
  /// their values in W (rows dest[r...], right-hand side at rhs_col).
  int dampingRowCount(const Clique& q, double lambda) const;
  void appendDampingLeading(const Clique& q, double lambda, int& r);
  void writeDampingRows(const Clique& q, double lambda, Eigen::Ref<RowMajorMatrixXd> W, int rhs_col, const int* dest,
                        int& r) const;
  void clearUndo();

  // Pools
  VarId allocVar();
  FactorId allocFactor();
  CliqueId allocClique();
  void freeClique(CliqueId c);
  void removeFactor(FactorId f);
  void removeVar(VarId v);
  std::uint64_t newStamp() { return ++stamp_; }

  // Dog-leg helpers
  void addCliqueGradient(CliqueId c, double sign);
  /// Sets the applied step of every variable to a*delta + b*gradient and
  /// refreshes the estimate and errors of those that changed.
  void applyStep(double a, double b);
  /// |R h|^2 - 2 d^T R h summed over cliques for h = a*delta + b*gradient (the
  /// linear model's change is half of this) and |d|^2.
  void linearModel(double a, double b, double& change, double& d_norm_sq) const;

  SmootherParams params_;
  Values theta_;      // linearization point
  Values estimate_;   // theta (+) step
  std::unordered_map<Key, VarId> key_to_var_;
  std::vector<VarSlot> vars_;
  std::vector<FactorSlot> factors_;
  std::vector<Clique> cliques_;
  std::vector<VarId> free_vars_;
  std::vector<FactorId> free_factors_;
  std::vector<CliqueId> free_cliques_;
  std::vector<CliqueId> roots_;
  int live_factors_ = 0;
  std::uint64_t stamp_ = 0;
  std::uint64_t update_count_ = 0;
  std::int64_t newest_t_ns_ = 0;
  std::int64_t last_threshold_check_ns_ = 0;  ///< newest timestamp at the last threshold pass
  bool threshold_checked_ = false;            ///< a threshold pass has run
  bool have_time_ = false;
  // The newest relinearize_min_recent_times distinct timestamps, oldest first.
  std::deque<std::int64_t> recent_times_;

  double error_at_estimate_ = 0.0;   // sum of FactorSlot::error
  double error_at_theta_ = 0.0;      // sum of FactorSlot::error_at_theta (dog-leg)
  int updates_since_error_resum_ = 0;
  double error_peak_ = 0.0;          // largest |running sums| since the last exact re-sum
  double lambda_;
  double trust_radius_;
  std::uint64_t damp_stamp_ = 0;     // VarSlot::damped == damp_stamp_: damped now
  std::vector<CliqueId> top_cliques_;
  bool relinearize_all_pending_ = false;  // a rejected step left deltas off the tree's solution  // cliques of the last re-eliminated top, children first

  // Step scratch and undo log
  std::vector<VarId> changed_vars_;
  std::vector<std::pair<VarId, Vec6>> undo_delta_;
  std::vector<std::pair<Key, Variable>> marginalized_;  // final estimates, until drained
  std::vector<std::pair<FactorId, double>> undo_error_;
  std::uint64_t undo_stamp_ = 0;      // VarSlot::logged == undo_stamp_: in the undo log
  bool step_is_delta_ = true;        // dog-leg: the applied step equals delta everywhere

  // Elimination scratch
  RowMajorMatrixXd work_;
  Eigen::VectorXd qr_workspace_;
  Eigen::VectorXd solve_scratch_;
  std::vector<int> row_leading_;
  std::vector<int> rows_with_leading_le_;
  std::vector<int> suffix_col_;
  std::vector<int> row_dest_, row_next_;
  Eigen::VectorXd column_norms_;
};

}  // namespace rilo
