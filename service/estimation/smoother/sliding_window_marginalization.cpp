// The sliding window's marginalization (IMU-Ultrasonic-UWB paper, Sec. III-C6): timed
// variables older than the window leave it. The factors and priors touching
// them are linearized at the estimate, the variables eliminated from that
// dense Gaussian by column-pivoting QR, and the result kept as one
// LinearMarginal on their Markov blanket; their final estimates wait to be
// drained (sliding_window_smoother.h, step 3).
#include <Eigen/QR>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>
#include <unordered_set>

#include "estimation/smoother/sliding_window_detail.h"
#include "estimation/smoother/sliding_window_smoother.h"

namespace rilo {

using namespace sliding_window_detail;

void SlidingWindowSmoother::marginalizeOldVariables(UpdateStats& stats) {
  if (params_.window_s <= 0.0 || !have_time_) return;
  const std::int64_t cutoff = newest_t_ns_ - static_cast<std::int64_t>(std::llround(params_.window_s * 1e9));
  std::vector<OrderKey> doomed;
  for (const auto& [key, info] : vars_) {
    if (info.timed && info.t_ns < cutoff) doomed.push_back({false, info.t_ns, key});
  }
  if (doomed.empty()) return;
  std::sort(doomed.begin(), doomed.end());
  for (const OrderKey& d : doomed) vars_.at(d.key).marginalize = true;
  auto isDoomed = [&](Key k) { return vars_.at(k).marginalize; };

  // Factors and priors on doomed variables go; the blanket is their other keys.
  std::vector<char> factor_out(factors_.size(), 0);
  std::vector<char> prior_out(priors_.size(), 0);
  std::unordered_set<Key> blanket_set;
  std::unordered_set<Key> eliminated_set;  // doomed keys with rows
  auto take = [&](const std::vector<Key>& keys, char& out) {
    if (std::none_of(keys.begin(), keys.end(), isDoomed)) return;
    out = 1;
    for (Key k : keys) (isDoomed(k) ? eliminated_set : blanket_set).insert(k);
  };
  for (std::size_t f = 0; f < factors_.size(); ++f) take(factors_[f]->keys(), factor_out[f]);
  for (std::size_t p = 0; p < priors_.size(); ++p) take(priors_[p]->keys(), prior_out[p]);
  // Earlier priors lying wholly inside the blanket are folded in as well: the
  // prior count stays bounded when marginalized states leave priors on the
  // same long-lived variables (anchors) without touching each other.
  if (!blanket_set.empty()) {
    for (std::size_t p = 0; p < priors_.size(); ++p) {
      const auto& keys = priors_[p]->keys();
      if (!prior_out[p] && std::all_of(keys.begin(), keys.end(), [&](Key k) { return blanket_set.count(k) != 0; })) {
        prior_out[p] = 2;
      }
    }
  }

  std::vector<Key> eliminated;
  for (const OrderKey& d : doomed) {
    if (eliminated_set.count(d.key)) eliminated.push_back(d.key);
  }
  std::vector<OrderKey> blanket_order;
  for (Key k : blanket_set) {
    const VarInfo& info = vars_.at(k);
    blanket_order.push_back({!info.timed, info.timed ? info.t_ns : 0, k});
  }
  std::sort(blanket_order.begin(), blanket_order.end());

  if (!eliminated.empty()) {
    // The removed information is linearized at the estimate (residuals, and
    // the chart of the step); with FEJ its Jacobians are taken at x_jac: the
    // first estimate of every variable already in a prior, the estimate for
    // the rest. The earlier priors enter with the Jacobian the optimizer
    // gives them (A under FEJ).
    const bool fej = params_.first_estimate_jacobians;
    Values x_jac;
    std::unordered_map<Key, int> column;
    int m = 0;
    auto addColumn = [&](Key k, int& offset) {
      x_jac.insert(k, fej && first_estimate_.exists(k) ? first_estimate_.at(k) : estimate_.at(k));
      column.emplace(k, offset);
      offset += vars_.at(k).dim;
    };
    for (Key k : eliminated) addColumn(k, m);
    int cols = m;
    std::vector<Key> blanket;
    for (const OrderKey& o : blanket_order) {
      blanket.push_back(o.key);
      addColumn(o.key, cols);
    }
    const int b = cols - m;

    // Dense whitened system [J_m J_b | r] of everything removed.
    int rows = 0;
    for (std::size_t f = 0; f < factors_.size(); ++f) rows += factor_out[f] ? factors_[f]->dim() : 0;
    for (std::size_t p = 0; p < priors_.size(); ++p) rows += prior_out[p] ? priors_[p]->rows() : 0;
    Eigen::MatrixXd W = Eigen::MatrixXd::Zero(rows, cols + 1);
    int row = 0;
    Residual r;
    Jacobians H;
    for (std::size_t f = 0; f < factors_.size(); ++f) {
      if (!factor_out[f]) continue;
      const Factor& factor = *factors_[f];
      const auto& keys = factor.keys();
      const bool frozen = fej && std::any_of(keys.begin(), keys.end(), [&](Key k) { return first_estimate_.exists(k); });
      if (frozen) {
        // Residual and IRLS weight at the estimate, Jacobians at x_jac.
        factor.evaluate(x_jac, r, &H);
        factor.evaluate(estimate_, r, nullptr);
        const double sw = sqrtWeight(factor, r);
        r *= sw;
        for (std::size_t q = 0; q < keys.size(); ++q) H[q] *= sw;
      } else {
        double e = 0.0;
        linearizeFactor(factor, estimate_, r, H, e);
      }
      const int d = factor.dim();
      for (std::size_t q = 0; q < keys.size(); ++q) W.block(row, column.at(keys[q]), d, H[q].cols()) = H[q];
      W.block(row, cols, d, 1) = r;
      row += d;
    }
    for (std::size_t p = 0; p < priors_.size(); ++p) {
      if (!prior_out[p]) continue;
      const LinearMarginal& prior = *priors_[p];
      evaluatePrior(prior, estimate_, prior_r_, prior_J_);
      int c = 0;
      for (Key k : prior.keys()) {
        const int dim = vars_.at(k).dim;
        W.block(row, column.at(k), prior.rows(), dim) = prior_J_.middleCols(c, dim);
        c += dim;
      }
      W.block(row, cols, prior.rows(), 1) = prior_r_;
      row += prior.rows();
    }

    // Eliminate the doomed block by rank-revealing QR: min over x_m of
    // |J_m x_m + J_b x_b + r|^2 is the part of the rows orthogonal to
    // range(J_m), whatever J_m's rank; directions of x_m that nothing
    // constrains simply carry no information (never a division by ~0).
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr_m(W.leftCols(m));
    qr_m.setThreshold(params_.rank_tolerance);
    const int rank = static_cast<int>(qr_m.rank());
    if (rank < m) {
      ++stats.indeterminate_cliques;
      ++rank_deficient_marginalizations_;
    }
    Eigen::MatrixXd rest = W.rightCols(b + 1);
    rest.applyOnTheLeft(qr_m.householderQ().adjoint());
    const int kept_rows = rows - rank;
    if (b > 0 && kept_rows > 0) {
      // Compress to at most b rows [R | z]: r(x) = R local(x_est, x) + z.
      Eigen::HouseholderQR<Eigen::MatrixXd> qr_b(rest.bottomRows(kept_rows));
      const int k = std::min(kept_rows, b);
      Eigen::MatrixXd R = qr_b.matrixQR().topRows(k).triangularView<Eigen::Upper>();
      // Keep only the blanket keys the prior actually touches.
      std::vector<Key> keys;
      std::vector<int> key_cols;
      int width = 0;
      for (Key key : blanket) {
        const int c = column.at(key) - m;
        const int dim = vars_.at(key).dim;
        if (!R.block(0, c, k, dim).isZero(0.0)) {
          keys.push_back(key);
          key_cols.push_back(c);
          width += dim;
        }
      }
      if (!keys.empty()) {
        Eigen::MatrixXd A(k, width);
        int c = 0;
        for (std::size_t i = 0; i < keys.size(); ++i) {
          const int dim = vars_.at(keys[i]).dim;
          A.middleCols(c, dim) = R.block(0, key_cols[i], k, dim);
          c += dim;
        }
        // The prior is kept at x0 = x_jac (FEJ: first estimates) with
        // local(x_est, x) = local(x0, x) - local(x0, x_est) (exact for vector
        // variables, first order for poses): d = A local(x0, x_est) - z, so
        // the prior's residual at the estimate is z.
        Eigen::VectorXd local_est(width);
        c = 0;
        for (Key key : keys) {
          const int dim = vars_.at(key).dim;
          local_est.segment(c, dim) = localVariable(x_jac.at(key), estimate_.at(key));
          c += dim;
        }
        Eigen::VectorXd d = A * local_est - R.col(b);
        auto prior = std::make_shared<const LinearMarginal>(keys, x_jac, std::move(A), std::move(d));
        if (fej) {
          for (Key key : keys) {
            if (!first_estimate_.exists(key)) first_estimate_.insert(key, x_jac.at(key));
          }
        }
        priors_.push_back(prior);
        prior_errors_.push_back(prior->error(estimate_));
        prior_out.push_back(0);
        ++stats.marginal_factors_created;
      }
    }
  }

  // Remove what was marginalized (stable order: deterministic structure).
  std::size_t w = 0;
  for (std::size_t f = 0; f < factors_.size(); ++f) {
    if (factor_out[f]) continue;
    factors_[w] = std::move(factors_[f]);
    factor_errors_[w] = factor_errors_[f];
    ++w;
  }
  factors_.resize(w);
  factor_errors_.resize(w);
  w = 0;
  for (std::size_t p = 0; p < priors_.size(); ++p) {
    if (prior_out[p]) {
      ++stats.marginal_factors_merged;
      continue;
    }
    priors_[w] = std::move(priors_[p]);
    prior_errors_[w] = prior_errors_[p];
    ++w;
  }
  priors_.resize(w);
  prior_errors_.resize(w);
  if (marginalized_.size() > kMaxUndrainedMarginalized) marginalized_.clear();
  for (const OrderKey& d : doomed) {
    marginalized_.emplace_back(d.key, estimate_.at(d.key));
    estimate_.erase(d.key);
    candidate_.erase(d.key);
    first_estimate_.erase(d.key);
    vars_.erase(d.key);
    ++stats.variables_marginalized;
  }
  structure_valid_ = false;
  linearized_at_estimate_ = false;
  covariance_factorized_ = false;
  error_ = sumErrors();
}

// --- Covariance --------------------------------------------------------------------

}  // namespace rilo
