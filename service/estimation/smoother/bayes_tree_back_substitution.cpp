// BayesTreeSmoother: partial back-substitution (wildfire) and the incremental
// error bookkeeping every step policy shares (isam2_step.cpp,
// d_isam2_step.cpp, dogleg_step.cpp).
#include <algorithm>
#include <cmath>

#include "estimation/smoother/bayes_tree_smoother.h"

namespace rilo {

// --- Back-substitution ----------------------------------------------------------

void BayesTreeSmoother::backSubstitute(double threshold, UpdateStats& stats, std::uint64_t moved) {
  if (moved == 0) moved = newStamp();
  std::vector<CliqueId> stack(roots_.begin(), roots_.end());
  while (!stack.empty()) {
    const CliqueId c = stack.back();
    stack.pop_back();
    const Clique& q = cliques_[c];
    // Running intersection: a descendant's separator can only hold a moved
    // variable if this clique's does, so the subtree needs nothing either.
    if (!needsSolve(q, moved)) continue;
    if (q.solved != moved) {  // else done by backSubstitutePart
      solveClique(c, threshold, moved);
      ++stats.cliques_back_substituted;
    }
    stack.insert(stack.end(), q.children.begin(), q.children.end());
  }
}

bool BayesTreeSmoother::needsSolve(const Clique& q, std::uint64_t moved) const {
  if (q.replaced) return true;
  return std::any_of(q.separator.begin(), q.separator.end(), [&](VarId v) { return vars_[v].moved == moved; });
}

std::uint64_t BayesTreeSmoother::backSubstitutePart(const std::vector<CliqueId>& cliques, double threshold,
                                                    UpdateStats& stats) {
  const std::uint64_t moved = newStamp();
  for (auto it = cliques.rbegin(); it != cliques.rend(); ++it) {  // parents first, as the wildfire meets them
    Clique& q = cliques_[*it];
    if (!needsSolve(q, moved)) continue;
    solveClique(*it, threshold, moved);
    q.solved = moved;
    ++stats.cliques_back_substituted;
  }
  return moved;
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

bool BayesTreeSmoother::tracksError() const {
  return params_.track_error || params_.method == SmootherParams::Method::kDogleg ||
         (params_.method == SmootherParams::Method::kDamped &&
          params_.d_isam2.acceptance == DIsam2Params::Acceptance::kGlobal);
}

void BayesTreeSmoother::refreshErrorsOfChanged(bool log_undo, std::size_t from) {
  const std::span<const VarId> changed = std::span<const VarId>(changed_vars_).subspan(std::min(from, changed_vars_.size()));
  for (VarId v : changed) refreshEstimate(v);
  refreshFactorErrors(changed, log_undo);
}

void BayesTreeSmoother::refreshFactorErrors(std::span<const VarId> vars, bool log_undo) {
  const std::uint64_t stamp = newStamp();
  // Without the running error only the damped factors' errors are read
  // (dampedFactorsErrorChange); damp_stamp_ is fresh every update, so an
  // undamped update refreshes none.
  const bool all = tracksError();
  for (VarId v : vars) {
    for (FactorId f : vars_[v].factors) {
      FactorSlot& fs = factors_[f];
      if (fs.mark == stamp) continue;
      fs.mark = stamp;
      if (!all && std::none_of(fs.vars.begin(), fs.vars.end(), [&](VarId u) { return vars_[u].damped == damp_stamp_; })) {
        continue;
      }
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

}  // namespace rilo
