// RISE's step policy (incremental Powell's dog-leg): a trust region over the
// Gauss-Newton step and the steepest-descent direction, with each clique's
// gradient kept as it is eliminated. Parameters: dogleg_params.h.
#include <algorithm>
#include <cmath>

#include "estimation/smoother/bayes_tree_smoother.h"

namespace rilo {

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
    if (trust_radius_ < params_.dogleg.trust_radius_min) {
      applyStep(0.0, 0.0);  // keep the linearization point
      stats.step_accepted = false;
      trust_radius_ = params_.dogleg.trust_radius_min;
      break;
    }
  }
}

}  // namespace rilo
