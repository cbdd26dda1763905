// BayesTreeSmoother: fixed-lag marginalization.
//
// A variable can leave the tree cleanly when it is eliminated before every
// variable it shares a clique with: then everything below its clique is
// marginalizable too, and the information it carried is exactly what its
// clique (or subtree) passed up. Keys to marginalize are ordered first
// whenever the top is re-eliminated; the few cliques that still break the
// rule (an old variable below a newer one, a marginal key in the middle of
// a clique: GTSAM issues #1638, #1680) are re-eliminated in the same update.
#include <algorithm>
#include <cmath>

#include "estimation/smoother/bayes_tree_smoother.h"
#include "estimation/smoother/dense_qr.h"

namespace rilo {

std::vector<BayesTreeSmoother::VarId> BayesTreeSmoother::selectMarginalizable() const {
  std::vector<VarId> out;
  if (params_.lag_s <= 0.0 || !have_time_) return out;
  const std::int64_t cutoff = newest_t_ns_ - static_cast<std::int64_t>(std::llround(params_.lag_s * 1e9));
  for (VarId v = 0; v < static_cast<VarId>(vars_.size()); ++v) {
    const VarSlot& slot = vars_[v];
    if (slot.alive && slot.has_time && slot.t_ns < cutoff) out.push_back(v);
  }
  return out;
}

void BayesTreeSmoother::markForCleanMarginalization(const std::vector<VarId>& marginalizable,
                                                    std::vector<VarId>& marked, UpdateStats& stats) {
  for (VarSlot& slot : vars_) slot.marginalize = false;
  for (VarId v : marginalizable) vars_[v].marginalize = true;

  // Every clique that holds a marginal variable (as frontal or separator)
  // must eliminate its marginal frontals first and, if it keeps any frontal,
  // have no marginal variable in its separator.
  const std::uint64_t visited = newStamp();
  std::vector<CliqueId> stack;
  for (VarId v : marginalizable) {
    if (vars_[v].clique != kNone) stack.push_back(vars_[v].clique);
  }
  while (!stack.empty()) {
    const CliqueId c = stack.back();
    stack.pop_back();
    Clique& q = cliques_[c];
    if (q.mark == visited) continue;
    q.mark = visited;
    bool kept_seen = false;
    bool violation = false;
    for (VarId f : q.frontals) {
      if (!vars_[f].marginalize) {
        kept_seen = true;
      } else if (kept_seen) {
        violation = true;
      }
    }
    if (kept_seen) {
      for (VarId s : q.separator) violation |= vars_[s].marginalize;
    }
    if (violation) {
      marked.insert(marked.end(), q.frontals.begin(), q.frontals.end());
      stats.variables_reordered_for_marginalization += static_cast<int>(q.frontals.size());
    }
    for (CliqueId child : q.children) {
      const auto& sep = cliques_[child].separator;
      if (std::any_of(sep.begin(), sep.end(), [&](VarId s) { return vars_[s].marginalize; })) stack.push_back(child);
    }
  }
}

void BayesTreeSmoother::marginalize(const std::vector<VarId>& marginalizable, UpdateStats& stats) {
  if (marginalizable.empty()) return;
  const bool dogleg = params_.method == SmootherParams::Method::kDogleg;
  auto all_marginal = [&](const Clique& q) {
    return std::all_of(q.frontals.begin(), q.frontals.end(), [&](VarId f) { return vars_[f].marginalize; });
  };

  // Cliques holding marginal frontals: wholly marginal ones go, partial ones
  // are split; `boundary` are the kept cliques that receive a marginal.
  std::vector<CliqueId> doomed;
  std::vector<CliqueId> boundary;
  const std::uint64_t seen = newStamp();
  const std::uint64_t is_boundary = newStamp();
  for (VarId v : marginalizable) {
    const CliqueId c = vars_[v].clique;
    if (cliques_[c].mark == seen) continue;
    cliques_[c].mark = seen;
    if (!all_marginal(cliques_[c])) {
      boundary.push_back(c);
      continue;
    }
    doomed.push_back(c);
  }
  // Kept parents of wholly marginal cliques also receive a marginal.
  for (CliqueId c : doomed) {
    const CliqueId p = cliques_[c].parent;
    if (p != kNone && !all_marginal(cliques_[p]) && cliques_[p].mark != is_boundary) {
      if (std::find(boundary.begin(), boundary.end(), p) == boundary.end()) boundary.push_back(p);
    }
  }
  for (CliqueId b : boundary) cliques_[b].mark = is_boundary;

  // 1. The marginal of each boundary clique: eliminate its marginal frontals
  //    from the rows that involve them (factors on marginal variables and the
  //    messages of wholly marginal children); what remains, compacted by QR,
  //    is a Gaussian factor on kept frontals and separator.
  for (CliqueId b : boundary) {
    Clique& q = cliques_[b];
    int col = 0;
    int marginal_dim = 0;
    for (VarId v : q.frontals) {
      vars_[v].col = col;
      col += vars_[v].dim;
      if (vars_[v].marginalize) marginal_dim += vars_[v].dim;
    }
    for (VarId v : q.separator) {
      vars_[v].col = col;
      col += vars_[v].dim;
    }
    const int n = col;
    std::vector<FactorId> sources;
    std::vector<FactorId> merged;  // earlier marginals of b on kept variables only
    for (FactorId f : q.factors) {
      const auto& fv = factors_[f].vars;
      if (std::any_of(fv.begin(), fv.end(), [&](VarId v) { return vars_[v].marginalize; })) {
        sources.push_back(f);
      } else if (factors_[f].marginal) {
        merged.push_back(f);
      }
    }
    std::vector<CliqueId> children;
    for (CliqueId ch : q.children) {
      if (all_marginal(cliques_[ch])) children.push_back(ch);
    }
    int rows = 0;
    for (FactorId f : sources) rows += static_cast<int>(factors_[f].linear.rows());
    for (CliqueId ch : children) rows += static_cast<int>(cliques_[ch].message.rows());
    if (rows == 0) continue;
    // Fold b's earlier marginals into the new one (re-expressed at theta):
    // otherwise every marginalized state leaves one more marginal on the
    // same long-lived variables (anchors) and the root's elimination grows.
    sources.insert(sources.end(), merged.begin(), merged.end());
    for (FactorId f : merged) rows += static_cast<int>(factors_[f].linear.rows());
    RowMajorMatrixXd W = RowMajorMatrixXd::Zero(rows, n + 1);
    int r = 0;
    for (FactorId f : sources) {
      scatterRows(factors_[f].linear, factors_[f].vars, W, n, nullptr, r);
      r += static_cast<int>(factors_[f].linear.rows());
    }
    for (CliqueId ch : children) {
      scatterRows(cliques_[ch].message, cliques_[ch].separator, W, n, nullptr, r);
      r += static_cast<int>(cliques_[ch].message.rows());
    }
    Eigen::VectorXd workspace(rows + n + 1);
    staircaseQrInPlace(W, n, nullptr, workspace.data());
    const int kept_rows = std::max(0, std::min(rows, n) - marginal_dim);
    if (kept_rows == 0) continue;
    const auto block = W.block(marginal_dim, marginal_dim, kept_rows, n - marginal_dim + 1);

    // Keep only the variables the marginal actually touches.
    std::vector<Key> keys;
    std::vector<VarId> key_vars;
    std::vector<int> cols;
    int offset = 0;
    for (const auto* list : {&q.frontals, &q.separator}) {
      for (VarId v : *list) {
        if (vars_[v].marginalize) continue;
        const int local = vars_[v].col - marginal_dim;
        if (!block.middleCols(local, vars_[v].dim).isZero(0.0)) {
          keys.push_back(vars_[v].key);
          key_vars.push_back(v);
          cols.push_back(local);
          offset += vars_[v].dim;
        }
      }
    }
    if (keys.empty()) continue;
    Eigen::MatrixXd A(kept_rows, offset);
    offset = 0;
    for (std::size_t k = 0; k < keys.size(); ++k) {
      const int dim = vars_[key_vars[k]].dim;
      A.middleCols(offset, dim) = block.middleCols(cols[k], dim);
      offset += dim;
    }
    Eigen::VectorXd d = block.col(n - marginal_dim);

    auto marginal = std::make_shared<LinearMarginal>(keys, theta_, std::move(A), std::move(d));
    const FactorId f = allocFactor();
    FactorSlot& fs = factors_[f];
    fs.marginal = std::move(marginal);
    fs.vars = key_vars;
    for (VarId v : key_vars) {
      vars_[v].factors.push_back(f);
      ++vars_[v].frozen;
    }
    // Assigned to b (not to the clique of its first key): b's stored message
    // already carries this information, and b re-eliminated must reproduce it.
    fs.clique = b;
    q.factors.push_back(f);
    linearizeFactor(fs);
    for (FactorId old : merged) {
      removeFactor(old);
      ++stats.marginal_factors_merged;
    }
    fs.error = factorError(fs, estimate_);
    fs.error_at_theta = dogleg ? factorError(fs, theta_) : 0.0;
    error_at_estimate_ += fs.error;
    error_at_theta_ += fs.error_at_theta;
    ++stats.marginal_factors_created;
  }

  // 2. Drop every factor on a marginal variable, and every factor of a wholly
  //    marginal clique (a marginal on its separator only): their information
  //    now lives in the new marginals.
  for (CliqueId c : doomed) {
    while (!cliques_[c].factors.empty()) removeFactor(cliques_[c].factors.back());
  }
  for (VarId v : marginalizable) {
    while (!vars_[v].factors.empty()) removeFactor(vars_[v].factors.back());
  }

  // 3. Split partial cliques: their kept rows of [R S | d] are unchanged (R is
  //    upper triangular and the marginal frontals come first).
  for (CliqueId b : boundary) {
    Clique& q = cliques_[b];
    if (dogleg) addCliqueGradient(b, -1.0);
    int marginal_dim = 0;
    std::vector<VarId> kept;
    for (VarId v : q.frontals) {
      if (vars_[v].marginalize) {
        marginal_dim += vars_[v].dim;
      } else {
        kept.push_back(v);
      }
    }
    if (marginal_dim > 0) {
      const int n = q.frontal_dim + q.separator_dim;
      q.conditional = q.conditional.block(marginal_dim, marginal_dim, q.frontal_dim - marginal_dim, n - marginal_dim + 1).eval();
      q.frontals = std::move(kept);
      q.frontal_dim -= marginal_dim;
    }
    q.children.erase(std::remove_if(q.children.begin(), q.children.end(),
                                    [&](CliqueId ch) { return all_marginal(cliques_[ch]); }),
                     q.children.end());
    if (dogleg) addCliqueGradient(b, 1.0);
  }

  // 4. Delete wholly marginal cliques (with their wholly marginal subtrees)
  //    and the marginal variables; their slots are reused.
  std::vector<CliqueId> stack(doomed.begin(), doomed.end());
  const std::uint64_t freed = newStamp();
  while (!stack.empty()) {
    const CliqueId c = stack.back();
    stack.pop_back();
    Clique& q = cliques_[c];
    if (!q.alive || q.mark == freed) continue;
    q.mark = freed;
    stack.insert(stack.end(), q.children.begin(), q.children.end());
    if (dogleg) addCliqueGradient(c, -1.0);
    if (q.parent == kNone) {
      auto it = std::find(roots_.begin(), roots_.end(), c);
      if (it != roots_.end()) roots_.erase(it);
    } else if (cliques_[q.parent].alive && !all_marginal(cliques_[q.parent])) {
      auto& siblings = cliques_[q.parent].children;
      siblings.erase(std::remove(siblings.begin(), siblings.end(), c), siblings.end());
    }
    freeClique(c);
  }
  // Callers that never drain must not grow memory without bound.
  if (marginalized_.size() > kMaxUndrainedMarginalized) marginalized_.clear();
  for (VarId v : marginalizable) {
    marginalized_.emplace_back(vars_[v].key, estimate_.at(vars_[v].key));
    removeVar(v);
    ++stats.variables_marginalized;
  }
  for (VarSlot& slot : vars_) slot.marginalize = false;
}

}  // namespace rilo
