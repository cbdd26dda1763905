// BayesTreeSmoother: partial back-substitution, incremental error
// bookkeeping, and the three step policies (Gauss-Newton, D-iSAM2, dog-leg).
#include <algorithm>
#include <cmath>

#include "estimation/smoother/bayes_tree_smoother.h"

namespace rilo {

// --- Back-substitution ----------------------------------------------------------

void BayesTreeSmoother::backSubstitute(double threshold, UpdateStats& stats) {
  const std::uint64_t moved = newStamp();
  std::vector<CliqueId> stack(roots_.begin(), roots_.end());
  while (!stack.empty()) {
    const CliqueId c = stack.back();
    stack.pop_back();
    const Clique& q = cliques_[c];
    bool recompute = q.replaced;
    for (std::size_t i = 0; !recompute && i < q.separator.size(); ++i) recompute = vars_[q.separator[i]].moved == moved;
    // Running intersection: a descendant's separator can only hold a moved
    // variable if this clique's does, so the subtree needs nothing either.
    if (!recompute) continue;
    solveClique(c, threshold, moved);
    ++stats.cliques_back_substituted;
    stack.insert(stack.end(), q.children.begin(), q.children.end());
  }
}

void BayesTreeSmoother::solveClique(CliqueId c, double threshold, std::uint64_t moved_stamp) {
  const Clique& q = cliques_[c];
  const int fd = q.frontal_dim;
  const int sd = q.separator_dim;
  if (solve_scratch_.size() < fd + sd) solve_scratch_.resize(fd + sd);
  Eigen::Map<Eigen::VectorXd> x(solve_scratch_.data(), fd);
  Eigen::Map<Eigen::VectorXd> delta_sep(solve_scratch_.data() + fd, sd);
  int offset = 0;
  for (VarId v : q.separator) {
    delta_sep.segment(offset, vars_[v].dim) = vars_[v].delta.head(vars_[v].dim);
    offset += vars_[v].dim;
  }
  x = q.conditional.col(fd + sd);
  if (sd > 0) x.noalias() -= q.conditional.block(0, fd, fd, sd) * delta_sep;
  q.conditional.topLeftCorner(fd, fd).triangularView<Eigen::Upper>().solveInPlace(x);

  offset = 0;
  const bool step_follows = params_.method != SmootherParams::Method::kDogleg;
  for (VarId v : q.frontals) {
    VarSlot& slot = vars_[v];
    const auto fresh = x.segment(offset, slot.dim);
    const double change = (fresh - slot.delta.head(slot.dim)).cwiseAbs().maxCoeff();
    if (change > 0.0) {
      logDelta(v);
      slot.delta.head(slot.dim) = fresh;
      if (step_follows) slot.step = slot.delta;
      if (change > threshold) slot.moved = moved_stamp;
    }
    offset += slot.dim;
  }
}

// --- Incremental error ------------------------------------------------------------

void BayesTreeSmoother::logDelta(VarId v) {
  VarSlot& slot = vars_[v];
  if (slot.logged == undo_stamp_) return;
  slot.logged = undo_stamp_;
  undo_delta_.emplace_back(v, slot.delta);
  changed_vars_.push_back(v);
}

void BayesTreeSmoother::clearUndo() {
  undo_delta_.clear();
  undo_error_.clear();
  changed_vars_.clear();
  undo_stamp_ = newStamp();
}

void BayesTreeSmoother::refreshEstimate(VarId v) {
  const VarSlot& slot = vars_[v];
  estimate_.insertOrAssign(slot.key, retractVariable(theta_.at(slot.key), slot.step.data()));
}

void BayesTreeSmoother::refreshErrorsOfChanged(bool log_undo) {
  for (VarId v : changed_vars_) refreshEstimate(v);
  refreshFactorErrors(changed_vars_, log_undo);
}

void BayesTreeSmoother::refreshFactorErrors(const std::vector<VarId>& vars, bool log_undo) {
  const std::uint64_t stamp = newStamp();
  for (VarId v : vars) {
    for (FactorId f : vars_[v].factors) {
      FactorSlot& fs = factors_[f];
      if (fs.mark == stamp) continue;
      fs.mark = stamp;
      const double e = factorError(fs, estimate_);
      if (log_undo) undo_error_.emplace_back(f, fs.error);
      error_at_estimate_ += e - fs.error;
      fs.error = e;
    }
  }
}

void BayesTreeSmoother::undoStep() {
  for (const auto& [v, old] : undo_delta_) {
    vars_[v].delta = old;
    vars_[v].step = old;
    refreshEstimate(v);
  }
  for (auto it = undo_error_.rbegin(); it != undo_error_.rend(); ++it) {
    FactorSlot& fs = factors_[it->first];
    error_at_estimate_ += it->second - fs.error;
    fs.error = it->second;
  }
  clearUndo();
}

// --- Step policies -----------------------------------------------------------------

void BayesTreeSmoother::stepGaussNewton(UpdateStats& stats) {
  clearUndo();
  backSubstitute(params_.wildfire_threshold, stats);
  refreshErrorsOfChanged(false);
  stats.step_tries = 1;
}

void BayesTreeSmoother::stepDamped(const std::vector<VarId>& damped_vars, bool eliminate_first, UpdateStats& stats) {
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
  bool wide = false;

  // Rounding in the running error sum is ~1e-16 relative; a step that changes
  // nothing must not count as an increase.
  const double tolerance = 1e-12 * std::abs(error_before);
  double lambda = lambda_;
  if (eliminate_first) {
    for (CliqueId c : path) eliminateClique(c, lambda, stats);
  }
  const bool global = params_.acceptance == SmootherParams::Acceptance::kGlobal;
  for (int attempt = 1;; ++attempt) {
    clearUndo();
    backSubstitute(params_.wildfire_threshold, stats);
    refreshErrorsOfChanged(true);
    stats.step_tries = attempt;
    const double change = global ? error_at_estimate_ - error_before : dampedFactorsErrorChange();
    if (path.empty() || change <= tolerance) {
      stats.lambda = lambda;
      lambda_ = wide ? params_.lambda_initial : std::max(params_.lambda_min, lambda * params_.lambda_decrease);
      break;
    }
    undoStep();
    lambda *= params_.lambda_increase;
    if (lambda > params_.lambda_max && params_.widen_damping && !wide) {
      // The newest variables are pinned and the error still grows: the
      // overshoot is in older variables. Damp the whole re-eliminated top.
      wide = true;
      ++stats.damping_widened;
      lambda = params_.lambda_initial;
      damp_stamp_ = newStamp();
      for (CliqueId c : top_cliques_) {
        for (VarId v : cliques_[c].frontals) {
          vars_[v].damped = damp_stamp_;
          vars_[v].damping_center = vars_[v].step;
        }
      }
      path = top_cliques_;
    }
    if (lambda > params_.lambda_max || attempt >= params_.max_tries) {
      // Alg. 1 raises an error here; a real-time service keeps the previous
      // estimate (new variables at their initial values) and says so. The
      // next update relinearizes every variable at that estimate, so the
      // tree and the deltas agree again.
      stats.step_accepted = false;
      stats.lambda = params_.lambda_max;
      lambda_ = params_.lambda_initial;
      relinearize_all_pending_ = true;  // next update linearizes at the kept estimate
      break;
    }
    for (CliqueId c : path) eliminateClique(c, lambda, stats);
  }
  // The damping is transient: leave the tree holding the undamped system
  // (exact covariances, clean messages), keeping the accepted step.
  for (CliqueId c : path) eliminateClique(c, 0.0, stats);
}

double BayesTreeSmoother::dampedFactorsErrorChange() const {
  // undo_error_ holds each refreshed factor once, with its error before the try.
  double change = 0.0;
  for (const auto& [f, before] : undo_error_) {
    const FactorSlot& fs = factors_[f];
    if (std::any_of(fs.vars.begin(), fs.vars.end(), [&](VarId v) { return vars_[v].damped == damp_stamp_; })) {
      change += fs.error - before;
    }
  }
  return change;
}

void BayesTreeSmoother::addCliqueGradient(CliqueId c, double sign) {
  Clique& q = cliques_[c];
  const int n = q.frontal_dim + q.separator_dim;
  if (sign > 0.0) q.gradient = -(q.conditional.leftCols(n).transpose() * q.conditional.col(n));
  if (q.gradient.size() != n) return;
  int offset = 0;
  for (const auto* list : {&q.frontals, &q.separator}) {
    for (VarId v : *list) {
      vars_[v].gradient.head(vars_[v].dim) += sign * q.gradient.segment(offset, vars_[v].dim);
      offset += vars_[v].dim;
    }
  }
}

void BayesTreeSmoother::applyStep(double a, double b) {
  std::vector<VarId> moved;
  if (a == 1.0 && b == 0.0 && step_is_delta_) {
    for (VarId v : changed_vars_) {
      if (vars_[v].step != vars_[v].delta) moved.push_back(v);
    }
    for (VarId v : moved) vars_[v].step = vars_[v].delta;
  } else {
    for (VarId v = 0; v < static_cast<VarId>(vars_.size()); ++v) {
      VarSlot& slot = vars_[v];
      if (!slot.alive) continue;
      const Vec6 fresh = a * slot.delta + b * slot.gradient;
      if (fresh != slot.step) {
        slot.step = fresh;
        moved.push_back(v);
      }
    }
  }
  step_is_delta_ = a == 1.0 && b == 0.0;
  for (VarId v : moved) refreshEstimate(v);
  refreshFactorErrors(moved, false);
}

void BayesTreeSmoother::linearModel(double a, double b, double& change, double& d_norm_sq) const {
  change = 0.0;
  d_norm_sq = 0.0;
  Eigen::VectorXd h;
  for (const Clique& q : cliques_) {
    if (!q.alive) continue;
    const int n = q.frontal_dim + q.separator_dim;
    h.resize(n);
    int offset = 0;
    for (const auto* list : {&q.frontals, &q.separator}) {
      for (VarId v : *list) {
        const VarSlot& slot = vars_[v];
        h.segment(offset, slot.dim) = a * slot.delta.head(slot.dim) + b * slot.gradient.head(slot.dim);
        offset += slot.dim;
      }
    }
    const Eigen::VectorXd Rh = q.conditional.leftCols(n) * h;
    const auto d = q.conditional.col(n);
    change += Rh.squaredNorm() - 2.0 * d.dot(Rh);
    d_norm_sq += d.squaredNorm();
  }
}

void BayesTreeSmoother::stepDogleg(UpdateStats& stats) {
  clearUndo();
  backSubstitute(params_.wildfire_threshold, stats);  // delta = Gauss-Newton step from theta
  const double error_at_theta = error_at_theta_;

  double gn_sq = 0.0, g_sq = 0.0, gn_dot_g = 0.0;
  for (const VarSlot& slot : vars_) {
    if (!slot.alive) continue;
    gn_sq += slot.delta.squaredNorm();
    g_sq += slot.gradient.squaredNorm();
    gn_dot_g += slot.delta.dot(slot.gradient);
  }
  const double gn_norm = std::sqrt(gn_sq);
  double alpha = -1.0;  // steepest-descent length |g|^2 / |R g|^2, computed when first needed

  for (int attempt = 1;; ++attempt) {
    stats.step_tries = attempt;
    const double radius = trust_radius_;
    double a = 1.0, b = 0.0;
    if (gn_norm > radius && g_sq > 0.0) {
      if (alpha < 0.0) {
        double rg_change = 0.0, unused = 0.0;
        linearModel(0.0, 1.0, rg_change, unused);  // |Rg|^2 - 2 d^T R g, and d^T R g = -|g|^2
        const double rg_sq = rg_change - 2.0 * g_sq;
        alpha = rg_sq > 0.0 ? g_sq / rg_sq : 0.0;
      }
      const double sd_norm = alpha * std::sqrt(g_sq);
      if (sd_norm >= radius || alpha == 0.0) {
        a = 0.0;
        b = -radius / std::sqrt(g_sq);
      } else {
        // h = h_sd + tau (h_gn - h_sd), |h| = radius, h_sd = -alpha g.
        const double sd_sq = alpha * alpha * g_sq;
        const double diff_sq = gn_sq + 2.0 * alpha * gn_dot_g + sd_sq;      // |h_gn - h_sd|^2
        const double sd_dot_diff = -alpha * gn_dot_g - sd_sq;                 // h_sd . (h_gn - h_sd)
        const double disc = sd_dot_diff * sd_dot_diff + diff_sq * (radius * radius - sd_sq);
        const double tau = diff_sq > 0.0 ? (-sd_dot_diff + std::sqrt(std::max(0.0, disc))) / diff_sq : 1.0;
        a = tau;
        b = -alpha * (1.0 - tau);
      }
    }
    applyStep(a, b);
    double change = 0.0, d_norm_sq = 0.0;
    linearModel(a, b, change, d_norm_sq);
    const double predicted = -0.5 * change;
    const double actual = error_at_theta - error_at_estimate_;
    const double rho = predicted > 0.0 ? actual / predicted : (actual >= 0.0 ? 1.0 : -1.0);
    double step_norm_sq = 0.0;
    for (const VarSlot& slot : vars_) {
      if (slot.alive) step_norm_sq += slot.step.squaredNorm();
    }
    if (rho >= 0.75) {
      trust_radius_ = std::max(trust_radius_, 3.0 * std::sqrt(step_norm_sq));
    } else if (rho < 0.25) {
      trust_radius_ *= 0.5;
    }
    if (rho > 0.0 || actual >= 0.0) break;
    if (trust_radius_ < params_.trust_radius_min) {
      applyStep(0.0, 0.0);  // keep the linearization point
      stats.step_accepted = false;
      trust_radius_ = params_.trust_radius_min;
      break;
    }
  }
}

}  // namespace rilo
