// D-iSAM2's step policy (Ranging-IMU Fusion paper, Alg. 1): Levenberg-Marquardt damping on the
// newest variables of an iSAM2 update. Everything D-iSAM2 decides is here:
// which variables it damps, the lambda loop (raise lambda and re-eliminate
// the damped path until the damped factors' error does not grow; keep the
// previous estimate past lambda_max or max_tries), and the damping rows the
// elimination stacks on the damped frontals. Parameters: d_isam2_params.h.
#include <algorithm>
#include <cmath>

#include "estimation/smoother/bayes_tree_smoother.h"

namespace rilo {

// --- Which variables it damps -------------------------------------------------------

bool BayesTreeSmoother::markDampedVariables(const std::vector<FactorId>& added, const Values& new_values,
                                            std::vector<VarId>& damped) {
  damp_stamp_ = newStamp();
  // D-iSAM2 damps the new variables (ordered last, into the root); an update
  // without new variables damps the keys of its new factors, and one without
  // either (an extra iteration) the whole re-eliminated top (stepDamped).
  // Of the new measurement factors at the estimate before the step. Motion
  // priors pull every new state a little (a vertical speed prior, the height
  // hold): counted, they damped every IMU-only state, and at 1 Hz ranging
  // from the truth D-iSAM2 ran away to kilometres again
  // (LowRateTracking.OneHertzCleanWalkStaysOnTrack with a vertical speed prior).
  double added_error = 0.0;
  for (FactorId f : added) {
    if (factors_[f].nonlinear == nullptr || !factors_[f].nonlinear->isMotionPrior()) added_error += factors_[f].error;
  }
  const bool damp = params_.method == SmootherParams::Method::kDamped &&
                    (added.empty() || added_error > params_.d_isam2.damping_min_new_error);
  if (damp) {
    for (const auto& [key, value] : new_values) damped.push_back(key_to_var_.at(key));
    if (damped.empty()) {
      for (FactorId f : added) damped.insert(damped.end(), factors_[f].vars.begin(), factors_[f].vars.end());
    }
    for (VarId v : damped) {
      vars_[v].damped = damp_stamp_;
      vars_[v].damping_center = vars_[v].step;
    }
  }
  return damp;
}

// --- The lambda decision -------------------------------------------------------------

void BayesTreeSmoother::stepDamped(bool damp, std::vector<VarId>& damped_vars, UpdateStats& stats) {
  if (!damp) {  // the new factors agree with the estimate: nothing to damp (DIsam2Params)
    stepGaussNewton(stats);
    return;
  }
  // An extra iteration (no new variables, no new factors) damps the whole
  // re-eliminated top; its cliques were eliminated undamped, so the first
  // try re-eliminates them with the damping.
  const bool eliminate_first = damped_vars.empty();
  if (eliminate_first) {
    for (CliqueId c : top_cliques_) {
      for (VarId v : cliques_[c].frontals) {
        vars_[v].damped = damp_stamp_;
        vars_[v].damping_center = vars_[v].step;
        damped_vars.push_back(v);
      }
    }
  }
  const double error_before = error_at_estimate_;
  // Cliques whose elimination sees the damping: those of the damped
  // variables and their ancestors, children first.
  auto path_of = [&](const std::vector<VarId>& vars) {
    std::vector<CliqueId> path;
    const std::uint64_t stamp = newStamp();
    for (VarId v : vars) {
      for (CliqueId c = vars_[v].clique; c != kNone && cliques_[c].mark != stamp; c = cliques_[c].parent) {
        cliques_[c].mark = stamp;
        path.push_back(c);
      }
    }
    auto depth = [&](CliqueId c) {
      int d = 0;
      for (; cliques_[c].parent != kNone; c = cliques_[c].parent) ++d;
      return d;
    };
    std::vector<std::pair<int, CliqueId>> by_depth;
    for (CliqueId c : path) by_depth.emplace_back(-depth(c), c);
    std::sort(by_depth.begin(), by_depth.end());
    path.clear();
    for (const auto& [d, c] : by_depth) path.push_back(c);
    return path;
  };
  std::vector<CliqueId> path = path_of(damped_vars);
  // What the acceptance test reads: the variables of the damped factors, in
  // their cliques and those cliques' ancestors.
  const bool global = params_.d_isam2.acceptance == DIsam2Params::Acceptance::kGlobal;
  std::vector<CliqueId> tested;
  bool partial = params_.d_isam2.partial_tries && !global;
  if (partial) {
    std::vector<VarId> neighbours;
    for (VarId v : damped_vars) {
      for (FactorId f : vars_[v].factors) neighbours.insert(neighbours.end(), factors_[f].vars.begin(), factors_[f].vars.end());
    }
    tested = path_of(neighbours);
  }
  bool wide = false;
  // Without the running error (SmootherParams::track_error) an old factor's
  // cached error may be stale: the damped factors' errors before the step
  // (those a factor-only update damps are old) are taken here.
  if (!tracksError()) refreshFactorErrors(damped_vars, false);

  // Rounding in an error sum is ~1e-16 of what it sums; a step that changes
  // nothing must not count as an increase. The whole graph's running sum
  // for kGlobal; for kDampedFactors the damped factors' own errors (the
  // running sum may be stale without SmootherParams::track_error), plus
  // DIsam2Params::tie_tolerance.
  const double global_tolerance = 1e-12 * std::abs(error_before);
  double lambda = lambda_;
  if (eliminate_first) {
    for (CliqueId c : path) eliminateClique(c, lambda, stats);
  }
  for (int attempt = 1;; ++attempt) {
    clearUndo();
    // A try that may be rejected solves only what its test reads (measured:
    // a rejection's 11-12 tries with the whole wildfire each took 8-14 ms,
    // docs/smoother.md); the accepted try continues into the rest of the
    // tree with the same marks.
    std::uint64_t moved = 0;
    if (!partial) {
      backSubstitute(params_.wildfire_threshold, stats);
    } else {
      moved = backSubstitutePart(tested, params_.wildfire_threshold, stats);
    }
    refreshErrorsOfChanged(true);
    stats.step_tries = attempt;
    double scale = 0.0;
    const double change = global ? error_at_estimate_ - error_before : dampedFactorsErrorChange(&scale);
    const double tolerance = global ? global_tolerance : 1e-12 * scale + params_.d_isam2.tie_tolerance;
    if (path.empty() || change <= tolerance) {
      if (partial) {  // the rest of the tree; what the try solved is not solved or refreshed again
        const std::size_t solved = changed_vars_.size();
        backSubstitute(params_.wildfire_threshold, stats, moved);
        refreshErrorsOfChanged(true, solved);
      }
      stats.lambda = lambda;
      lambda_ = wide ? params_.d_isam2.lambda_initial : std::max(params_.d_isam2.lambda_min, lambda * params_.d_isam2.lambda_decrease);
      break;
    }
    undoStep();
    lambda *= params_.d_isam2.lambda_increase;
    if (lambda > params_.d_isam2.lambda_max && params_.d_isam2.widen_damping && !wide) {
      // The newest variables are pinned and the error still grows: the
      // overshoot is in older variables. Damp the whole re-eliminated top.
      wide = true;
      ++stats.damping_widened;
      lambda = params_.d_isam2.lambda_initial;
      damp_stamp_ = newStamp();
      std::vector<VarId> widened;
      for (CliqueId c : top_cliques_) {
        for (VarId v : cliques_[c].frontals) {
          vars_[v].damped = damp_stamp_;
          vars_[v].damping_center = vars_[v].step;
          widened.push_back(v);
        }
      }
      path = top_cliques_;
      partial = false;  // the damped factors now reach below the top
      if (!tracksError()) refreshFactorErrors(widened, false);
    }
    if (lambda > params_.d_isam2.lambda_max || attempt >= params_.d_isam2.max_tries) {
      // Alg. 1 raises an error here; a real-time service keeps the previous
      // estimate (new variables at their initial values) and says so. The
      // next update relinearizes every variable at that estimate, so the
      // tree and the deltas agree again.
      stats.step_accepted = false;
      stats.lambda = params_.d_isam2.lambda_max;
      lambda_ = params_.d_isam2.lambda_initial;
      relinearize_all_pending_ = true;  // next update linearizes at the kept estimate
      break;
    }
    for (CliqueId c : path) eliminateClique(c, lambda, stats);
  }
  // The damping is transient: leave the tree holding the undamped system
  // (exact covariances, clean messages), keeping the accepted step.
  for (CliqueId c : path) eliminateClique(c, 0.0, stats);
}

double BayesTreeSmoother::dampedFactorsErrorChange(double* scale) const {
  // undo_error_ holds each refreshed factor once, with its error before the try.
  double change = 0.0;
  double magnitude = 0.0;
  for (const auto& [f, before] : undo_error_) {
    const FactorSlot& fs = factors_[f];
    if (std::any_of(fs.vars.begin(), fs.vars.end(), [&](VarId v) { return vars_[v].damped == damp_stamp_; })) {
      change += fs.error - before;
      magnitude += std::abs(before) + std::abs(fs.error);
    }
  }
  if (scale != nullptr) *scale = magnitude;
  return change;
}

// --- The damping rows -----------------------------------------------------------
// Levenberg-Marquardt rows sqrt(lambda * h_ii) (delta_i - c_i) on a clique's
// damped frontals, h_ii the diagonal of J^T J (Marquardt): lambda is
// dimensionless across a stiff IMU position (h ~ 1e10) and a weak yaw.
// Centred on the accepted delta c, so a large lambda keeps the variable where
// it is instead of pulling it back to theta. eliminateClique stacks them with
// the clique's factors and messages; lambda 0 adds none.

int BayesTreeSmoother::dampingRowCount(const Clique& q, double lambda) const {
  int rows = 0;
  for (VarId v : q.frontals) {
    if (lambda > 0.0 && vars_[v].damped == damp_stamp_) rows += vars_[v].dim;
  }
  return rows;
}

void BayesTreeSmoother::appendDampingLeading(const Clique& q, double lambda, int& r) {
  for (VarId v : q.frontals) {
    if (lambda > 0.0 && vars_[v].damped == damp_stamp_) {
      for (int i = 0; i < vars_[v].dim; ++i) row_leading_[r++] = vars_[v].col + i;
    }
  }
}

void BayesTreeSmoother::writeDampingRows(const Clique& q, double lambda, Eigen::Ref<RowMajorMatrixXd> W, int rhs_col,
                                         const int* dest, int& r) const {
  for (VarId v : q.frontals) {
    if (lambda > 0.0 && vars_[v].damped == damp_stamp_) {
      const Vec6 h = informationDiagonal(v);
      for (int i = 0; i < vars_[v].dim; ++i, ++r) {
        const double scale = std::sqrt(lambda * std::clamp(h[i], kMinDampingDiagonal, kMaxDampingDiagonal));
        W(dest[r], vars_[v].col + i) = scale;
        W(dest[r], rhs_col) = scale * vars_[v].damping_center[i];
      }
    }
  }
}

Vec6 BayesTreeSmoother::informationDiagonal(VarId v) const {
  Vec6 h = Vec6::Zero();
  for (FactorId f : vars_[v].factors) {
    const FactorSlot& fs = factors_[f];
    int src = 0;
    for (VarId u : fs.vars) {
      if (u == v) {
        h.head(vars_[v].dim) += fs.linear.middleCols(src, vars_[v].dim).colwise().squaredNorm().transpose();
      }
      src += vars_[u].dim;
    }
  }
  return h;
}

}  // namespace rilo
