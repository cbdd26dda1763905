#include "estimation/smoother/sliding_window_smoother.h"

#include <Eigen/QR>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>
#include <unordered_set>

#include "estimation/smoother/sliding_window_detail.h"

namespace rilo {
using namespace sliding_window_detail;

SlidingWindowSmoother::SlidingWindowSmoother(SlidingWindowParams params) : params_(params) { params_.validate(); }

SlidingWindowSmoother::~SlidingWindowSmoother() { factor_.reset(); }

Variable SlidingWindowSmoother::estimate(Key key) const {
  if (!estimate_.exists(key)) {
    throw std::out_of_range("SlidingWindowSmoother::estimate: unknown variable " + keyString(key));
  }
  return estimate_.at(key);
}

void SlidingWindowSmoother::drainMarginalized(std::vector<std::pair<Key, Variable>>& out) {
  out.insert(out.end(), std::make_move_iterator(marginalized_.begin()), std::make_move_iterator(marginalized_.end()));
  marginalized_.clear();
}

FactorGraph SlidingWindowSmoother::nonlinearFactors() const {
  FactorGraph out;
  for (const FactorPtr& f : factors_) out.add(f);
  return out;
}

std::optional<Variable> SlidingWindowSmoother::firstEstimate(Key key) const {
  if (!first_estimate_.exists(key)) return std::nullopt;
  return first_estimate_.at(key);
}

double SlidingWindowSmoother::errorFromScratch() const {
  double sum = 0.0;
  for (const FactorPtr& f : factors_) sum += f->error(estimate_);
  for (const LinearMarginalPtr& p : priors_) sum += p->error(estimate_);
  return sum;
}

double SlidingWindowSmoother::sumErrors() const {
  double sum = 0.0;
  for (double e : factor_errors_) sum += e;
  for (double e : prior_errors_) sum += e;
  return sum;
}

// --- update() -----------------------------------------------------------------

UpdateStats SlidingWindowSmoother::update(const FactorGraph& new_factors, const Values& new_values,
                                          const KeyTimestamps& timestamps) {
  const auto t_start = std::chrono::steady_clock::now();
  validateInput(new_factors, new_values, timestamps);  // throws with nothing changed
  UpdateStats stats;

  for (Key key : new_values.keys()) {  // sorted: deterministic
    const Variable& value = new_values.at(key);
    VarInfo info;
    info.dim = variableDim(value);
    if (auto it = timestamps.find(key); it != timestamps.end()) {
      info.timed = true;
      info.t_ns = it->second;
      if (!have_time_ || it->second > newest_t_ns_) newest_t_ns_ = it->second;
      have_time_ = true;
    }
    vars_.emplace(key, info);
    estimate_.insert(key, value);
    candidate_.insert(key, value);
    ++stats.variables_added;
  }
  for (const FactorPtr& f : new_factors) {
    factors_.push_back(f);
    factor_errors_.push_back(f->error(estimate_));
    ++stats.factors_added;
  }
  if (stats.variables_added > 0 || stats.factors_added > 0) {
    structure_valid_ = false;
    linearized_at_estimate_ = false;
    covariance_factorized_ = false;
  }
  error_ = sumErrors();
  stats.error_before = error_;

  runLevenbergMarquardt(stats);
  marginalizeOldVariables(stats);

  stats.error_after = error_;
  stats.variables_total = variableCount();
  stats.factors_total = factorCount();
  stats.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return stats;
}

void SlidingWindowSmoother::validateInput(const FactorGraph& new_factors, const Values& new_values,
                                          const KeyTimestamps& timestamps) const {
  const std::string where = "SlidingWindowSmoother::update: ";
  for (const auto& [key, value] : new_values) {
    if (vars_.count(key)) throw std::invalid_argument(where + "value for existing variable " + keyString(key));
  }
  std::unordered_set<Key> covered;
  for (std::size_t i = 0; i < new_factors.size(); ++i) {
    const FactorPtr& f = new_factors[i];
    if (!f) throw std::invalid_argument(where + "new factor " + std::to_string(i) + " is null");
    for (std::size_t a = 0; a < f->keys().size(); ++a) {
      const Key k = f->keys()[a];
      for (std::size_t b = 0; b < a; ++b) {
        if (f->keys()[b] == k) {
          throw std::invalid_argument(where + "new factor " + std::to_string(i) + " repeats key " + keyString(k));
        }
      }
      if (!new_values.exists(k) && !vars_.count(k)) {
        throw std::invalid_argument(where + "new factor " + std::to_string(i) + " uses " + keyString(k) +
                                    ", which has no value (never added, or marginalized)");
      }
      covered.insert(k);
    }
    // The variable types a factor needs are known only to its evaluate():
    // try it once on its own keys before anything is inserted.
    Values scratch;
    for (Key k : f->keys()) scratch.insertOrAssign(k, new_values.exists(k) ? new_values.at(k) : estimate_.at(k));
    try {
      Residual r;
      Jacobians H;
      f->evaluate(scratch, r, &H);
      (void)f->errorOfResidual(r);  // an asymmetric loss on a vector residual throws here
    } catch (const std::exception& e) {
      std::string keys;
      for (Key k : f->keys()) keys += (keys.empty() ? "" : ", ") + keyString(k);
      throw std::invalid_argument(where + "new factor " + std::to_string(i) + " (keys " + keys +
                                  ") cannot be evaluated on the given values: " + e.what());
    }
  }
  for (const auto& [key, value] : new_values) {
    if (!covered.count(key)) throw std::invalid_argument(where + "new variable " + keyString(key) + " has no factor");
  }
  for (const auto& [key, t] : timestamps) {
    if (!new_values.exists(key)) {
      throw std::invalid_argument(where + "timestamp for " + keyString(key) + ", which is not a new variable");
    }
  }
}

// --- Linear system --------------------------------------------------------------

void SlidingWindowSmoother::buildStructure() {
  structure_valid_ = false;
  linearized_at_estimate_ = false;
  covariance_factorized_ = false;
  factor_.reset();

  // Variables in some factor or prior, in elimination order.
  for (auto& [key, info] : vars_) info.pos = -1;
  std::vector<OrderKey> order;
  order.reserve(vars_.size());
  auto touch = [&](Key k) {
    VarInfo& info = vars_.at(k);
    if (info.pos != -1) return;
    info.pos = 0;
    order.push_back({!info.timed, info.timed ? info.t_ns : 0, k});
  };
  for (const FactorPtr& f : factors_) {
    for (Key k : f->keys()) touch(k);
  }
  for (const LinearMarginalPtr& p : priors_) {
    for (Key k : p->keys()) touch(k);
  }
  std::sort(order.begin(), order.end());
  const std::size_t nv = order.size();
  ordering_.resize(nv);
  std::vector<int> dims(nv);
  offsets_.assign(nv + 1, 0);
  for (std::size_t b = 0; b < nv; ++b) {
    ordering_[b] = order[b].key;
    VarInfo& info = vars_.at(order[b].key);
    info.pos = static_cast<int>(b);
    dims[b] = info.dim;
    offsets_[b + 1] = offsets_[b] + info.dim;
  }
  n_ = offsets_[nv];

  // Key positions per factor / prior, and the block pairs (a <= b) they fill.
  std::vector<std::uint64_t> pairs;  // (b << 32) | a
  for (std::size_t b = 0; b < nv; ++b) pairs.push_back((static_cast<std::uint64_t>(b) << 32) | b);
  auto collect = [&](const std::vector<Key>& keys, std::vector<int>& pos_out) {
    const std::size_t begin = pos_out.size();
    for (Key k : keys) pos_out.push_back(vars_.at(k).pos);
    for (std::size_t i = begin; i < pos_out.size(); ++i) {
      for (std::size_t j = begin; j < pos_out.size(); ++j) {
        const auto a = static_cast<std::uint64_t>(pos_out[i]);
        const auto c = static_cast<std::uint64_t>(pos_out[j]);
        if (a < c) pairs.push_back((c << 32) | a);
      }
    }
  };
  factor_pos_.clear();
  factor_pos_begin_.assign(1, 0);
  for (const FactorPtr& f : factors_) {
    collect(f->keys(), factor_pos_);
    factor_pos_begin_.push_back(factor_pos_.size());
  }
  prior_pos_.clear();
  prior_pos_begin_.assign(1, 0);
  for (const LinearMarginalPtr& p : priors_) {
    collect(p->keys(), prior_pos_);
    prior_pos_begin_.push_back(prior_pos_.size());
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());

  // Block adjacency in compressed form (blocks a <= b of column-block b, a
  // ascending, the diagonal block last) and each block's first row.
  std::vector<std::size_t> adj_begin(nv + 1, 0);
  std::vector<int> adj(pairs.size());
  std::vector<int> row_start(pairs.size());
  for (std::size_t q = 0; q < pairs.size(); ++q) {
    ++adj_begin[static_cast<std::size_t>(pairs[q] >> 32) + 1];
    adj[q] = static_cast<int>(pairs[q] & 0xFFFFFFFFull);
  }
  for (std::size_t b = 0; b < nv; ++b) adj_begin[b + 1] += adj_begin[b];
  for (std::size_t b = 0; b < nv; ++b) {
    int acc = 0;
    for (std::size_t q = adj_begin[b]; q < adj_begin[b + 1]; ++q) {
      row_start[q] = acc;
      acc += dims[static_cast<std::size_t>(adj[q])];
    }
  }

  // Scalar pattern: column jj of block b holds the full blocks a < b, then
  // rows offset(b) .. offset(b) + jj of the diagonal block.
  col_ptr_.assign(static_cast<std::size_t>(n_) + 1, 0);
  std::size_t nnz = 0;
  for (std::size_t b = 0; b < nv; ++b) {
    const int above = row_start[adj_begin[b + 1] - 1];
    for (int jj = 0; jj < dims[b]; ++jj) {
      nnz += static_cast<std::size_t>(above + jj + 1);
      if (nnz > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
        throw std::runtime_error("SlidingWindowSmoother: Hessian too large for 32-bit indices");
      }
      col_ptr_[static_cast<std::size_t>(offsets_[b] + jj) + 1] = static_cast<int>(nnz);
    }
  }
  row_idx_.resize(nnz);
  values_.assign(nnz, 0.0);
  diag_idx_.resize(static_cast<std::size_t>(n_));
  for (std::size_t b = 0; b < nv; ++b) {
    for (int jj = 0; jj < dims[b]; ++jj) {
      const int c = offsets_[b] + jj;
      int p = col_ptr_[static_cast<std::size_t>(c)];
      for (std::size_t q = adj_begin[b]; q < adj_begin[b + 1]; ++q) {
        const auto a = static_cast<std::size_t>(adj[q]);
        const int rows = a == b ? jj + 1 : dims[a];
        for (int ii = 0; ii < rows; ++ii) row_idx_[static_cast<std::size_t>(p++)] = offsets_[a] + ii;
      }
      diag_idx_[static_cast<std::size_t>(c)] = p - 1;
    }
  }

  // Where each factor's / prior's blocks land.
  auto slotsOf = [&](const std::vector<int>& pos, const std::vector<std::size_t>& pos_begin,
                     std::vector<BlockSlot>& slots, std::vector<std::size_t>& slot_begin) {
    slots.clear();
    slot_begin.assign(1, 0);
    for (std::size_t f = 0; f + 1 < pos_begin.size(); ++f) {
      const std::size_t kb = pos_begin[f];
      const std::size_t nk = pos_begin[f + 1] - kb;
      for (std::size_t i = 0; i < nk; ++i) {
        for (std::size_t j = 0; j < nk; ++j) {
          const int pa = pos[kb + i];
          const int pb = pos[kb + j];
          if (pa > pb) continue;
          const auto first = adj.begin() + static_cast<std::ptrdiff_t>(adj_begin[static_cast<std::size_t>(pb)]);
          const auto last = adj.begin() + static_cast<std::ptrdiff_t>(adj_begin[static_cast<std::size_t>(pb) + 1]);
          const auto q = static_cast<std::size_t>(std::lower_bound(first, last, pa) - adj.begin());
          slots.push_back({static_cast<int>(i), static_cast<int>(j), row_start[q]});
        }
      }
      slot_begin.push_back(slots.size());
    }
  };
  slotsOf(factor_pos_, factor_pos_begin_, factor_slots_, factor_slot_begin_);
  slotsOf(prior_pos_, prior_pos_begin_, prior_slots_, prior_slot_begin_);
  gradient_.setZero(n_);
  undamped_diagonal_.setZero(n_);
  step_.setZero(n_);
  negative_gradient_.setZero(n_);
  hessian_step_.setZero(n_);
  if (n_ > 0) {
    // The columns are already in elimination order: natural ordering, no
    // postorder (as BatchLevenbergMarquardt: a postorder makes CHOLMOD
    // transpose-permute the matrix on every factorization). The supernodal
    // Eigen kernel, as the batch: CHOLMOD's supernodal path on the system's
    // reference BLAS was ~45% of a sliding-window replay.
    const SymmetricCscView view{n_, col_ptr_.data(), row_idx_.data(), values_.data()};
    const CholmodResult analyzed = cholmod_.analyze(
        view, {}, AnalyzeOptions{.postorder = false, .kernel = AnalyzeOptions::Kernel::kSupernodalEigen}, &factor_);
    ++analyses_;
    if (!analyzed.ok()) throw std::runtime_error("SlidingWindowSmoother: symbolic analysis failed: " + analyzed.message);
  }
  structure_valid_ = true;
}

void SlidingWindowSmoother::evaluatePrior(const LinearMarginal& prior, const Values& x, Eigen::VectorXd& r,
                                          Eigen::MatrixXd& J) const {
  if (params_.first_estimate_jacobians) {
    prior.evaluate(x, r, nullptr);
    J = prior.A();
  } else {
    prior.evaluate(x, r, &J);
  }
}

double SlidingWindowSmoother::linearize() {
  std::fill(values_.begin(), values_.end(), 0.0);
  gradient_.setZero();
  Residual r;
  Jacobians H;
  auto scatter = [&](int pa, int pb, bool diagonal, int row_start, const auto& block) {
    const int col0 = offsets_[static_cast<std::size_t>(pb)];
    const int cols = offsets_[static_cast<std::size_t>(pb) + 1] - col0;
    const int rows_a = offsets_[static_cast<std::size_t>(pa) + 1] - offsets_[static_cast<std::size_t>(pa)];
    for (int jj = 0; jj < cols; ++jj) {
      double* dst = values_.data() + col_ptr_[static_cast<std::size_t>(col0 + jj)] + row_start;
      const int rows = diagonal ? jj + 1 : rows_a;
      for (int ii = 0; ii < rows; ++ii) dst[ii] += block(ii, jj);
    }
  };
  double total = 0.0;
  for (std::size_t f = 0; f < factors_.size(); ++f) {
    const Factor& factor = *factors_[f];
    linearizeFactor(factor, estimate_, r, H, factor_errors_[f]);
    total += factor_errors_[f];
    const std::size_t kb = factor_pos_begin_[f];
    const std::size_t nk = factor_pos_begin_[f + 1] - kb;
    for (std::size_t k = 0; k < nk; ++k) {
      const auto pos = static_cast<std::size_t>(factor_pos_[kb + k]);
      const int dim = offsets_[pos + 1] - offsets_[pos];
      if (H[k].rows() != r.size() || H[k].cols() != dim) {
        throw std::logic_error("SlidingWindowSmoother: factor " + std::to_string(f) + " returned a " +
                               std::to_string(H[k].rows()) + "x" + std::to_string(H[k].cols()) + " block for key " +
                               keyString(ordering_[pos]));
      }
      const BlockVector g_k = H[k].transpose() * r;
      gradient_.segment(offsets_[pos], dim) += g_k;
    }
    for (std::size_t s = factor_slot_begin_[f]; s < factor_slot_begin_[f + 1]; ++s) {
      const BlockSlot& slot = factor_slots_[s];
      // Coefficient-wise product: Eigen's blocked GEMM costs more than it saves on 15x6 blocks.
      const BlockProduct block =
          H[static_cast<std::size_t>(slot.i)].transpose().lazyProduct(H[static_cast<std::size_t>(slot.j)]);
      scatter(factor_pos_[kb + static_cast<std::size_t>(slot.i)], factor_pos_[kb + static_cast<std::size_t>(slot.j)],
              slot.i == slot.j, slot.row_start, block);
    }
  }
  for (std::size_t p = 0; p < priors_.size(); ++p) {
    const LinearMarginal& prior = *priors_[p];
    evaluatePrior(prior, estimate_, prior_r_, prior_J_);
    prior_errors_[p] = 0.5 * prior_r_.squaredNorm();
    total += prior_errors_[p];
    const std::size_t kb = prior_pos_begin_[p];
    const std::size_t nk = prior_pos_begin_[p + 1] - kb;
    std::vector<int>& col = prior_cols_;
    col.assign(nk + 1, 0);
    for (std::size_t k = 0; k < nk; ++k) {
      const auto pos = static_cast<std::size_t>(prior_pos_[kb + k]);
      const int dim = offsets_[pos + 1] - offsets_[pos];
      col[k + 1] = col[k] + dim;
      gradient_.segment(offsets_[pos], dim) += prior_J_.middleCols(col[k], dim).transpose() * prior_r_;
    }
    prior_block_.noalias() = prior_J_.transpose() * prior_J_;
    for (std::size_t s = prior_slot_begin_[p]; s < prior_slot_begin_[p + 1]; ++s) {
      const BlockSlot& slot = prior_slots_[s];
      const auto i = static_cast<std::size_t>(slot.i);
      const auto j = static_cast<std::size_t>(slot.j);
      const auto block = prior_block_.block(col[i], col[j], col[i + 1] - col[i], col[j + 1] - col[j]);
      scatter(prior_pos_[kb + i], prior_pos_[kb + j], slot.i == slot.j, slot.row_start, block);
    }
  }
  for (std::size_t i = 0; i < diag_idx_.size(); ++i) {
    undamped_diagonal_(static_cast<Eigen::Index>(i)) = values_[static_cast<std::size_t>(diag_idx_[i])];
  }
  linearized_at_estimate_ = true;
  covariance_factorized_ = false;
  return total;
}

double SlidingWindowSmoother::evaluateError(const Values& x, std::vector<double>& errors) const {
  errors.resize(factors_.size() + priors_.size());
  double total = 0.0;
  for (std::size_t f = 0; f < factors_.size(); ++f) {
    errors[f] = factors_[f]->error(x);
    total += errors[f];
  }
  for (std::size_t p = 0; p < priors_.size(); ++p) {
    errors[factors_.size() + p] = priors_[p]->error(x);
    total += errors[factors_.size() + p];
  }
  return total;
}

void SlidingWindowSmoother::setDiagonal(double lambda) {
  for (std::size_t i = 0; i < diag_idx_.size(); ++i) {
    values_[static_cast<std::size_t>(diag_idx_[i])] = undamped_diagonal_(static_cast<Eigen::Index>(i)) + lambda;
  }
}

void SlidingWindowSmoother::multiplyHessian(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  y.setZero(n_);
  for (int c = 0; c < n_; ++c) {
    double acc = 0.0;
    const double xc = x(c);
    for (int p = col_ptr_[static_cast<std::size_t>(c)]; p < col_ptr_[static_cast<std::size_t>(c) + 1]; ++p) {
      const int r = row_idx_[static_cast<std::size_t>(p)];
      const double v = values_[static_cast<std::size_t>(p)];
      y(r) += v * xc;
      if (r != c) acc += v * x(r);
    }
    y(c) += acc;
  }
}

// --- Levenberg-Marquardt -----------------------------------------------------

void SlidingWindowSmoother::runLevenbergMarquardt(UpdateStats& stats) {
  if (!structure_valid_) buildStructure();
  covariance_factorized_ = false;
  stats.lambda = params_.lambda_initial;
  if (n_ == 0) return;

  double error = linearized_at_estimate_ ? error_ : linearize();
  error_ = error;
  stats.error_before = error;
  double lambda = params_.lambda_initial;
  double nu = 2.0;
  bool converged = false;
  bool any_accepted = false;
  bool done = false;
  auto increaseLambda = [&]() {
    const double next = std::max(params_.lambda_min, lambda * nu);
    nu *= 2.0;
    if (!(next <= params_.lambda_max)) return false;
    lambda = next;
    return true;
  };
  const SymmetricCscView view{n_, col_ptr_.data(), row_idx_.data(), values_.data()};
  for (int iter = 0; iter < params_.max_iterations && !done; ++iter) {
    if (!linearized_at_estimate_) error = linearize();
    const double gradient_norm = gradient_.lpNorm<Eigen::Infinity>();
    if (gradient_norm <= params_.gradient_tolerance) {
      converged = true;
      break;
    }
    ++stats.step_tries;
    negative_gradient_ = -gradient_;
    while (true) {
      setDiagonal(lambda);
      const CholmodResult factorized = cholmod_.factorize(
          view, FactorizeOptions{.shift = 0.0, .min_pivot_ratio = params_.indeterminate_pivot_ratio}, factor_);
      if (factorized.status == CholmodStatus::kNotPositiveDefinite) {
        ++stats.indeterminate_cliques;
        if (!increaseLambda()) {
          done = true;
          break;
        }
        continue;
      }
      if (!factorized.ok() || !cholmod_.solve(factor_, negative_gradient_.data(), 1, step_.data()).ok()) {
        done = true;  // out of memory or similar: keep the estimate
        break;
      }
      const double step_norm = step_.lpNorm<Eigen::Infinity>();
      // Decrease predicted by the undamped model: -g.d - d^T (J^T J) d / 2,
      // with J^T J d = (damped H) d - lambda d.
      multiplyHessian(step_, hessian_step_);
      const double predicted =
          -gradient_.dot(step_) - 0.5 * (step_.dot(hessian_step_) - lambda * step_.squaredNorm());
      for (std::size_t pos = 0; pos < ordering_.size(); ++pos) {
        const Key k = ordering_[pos];
        candidate_.update(k, retractVariable(estimate_.at(k), step_.data() + offsets_[pos]));
      }
      const double new_error = evaluateError(candidate_, candidate_errors_);
      const bool finite = std::isfinite(new_error);
      const double actual = error - new_error;
      const double rho = (finite && predicted > 0.0) ? actual / predicted : -std::numeric_limits<double>::infinity();
      const double tolerance = std::max(params_.absolute_error_tolerance, params_.relative_error_tolerance * error);
      const bool trustworthy = lambda <= kNegligibleDamping * undamped_diagonal_.maxCoeff();
      // Converged when the model predicts a negligible decrease (the Newton
      // decrement): near the optimum of an ill-conditioned window the actual
      // change is rounding and curvature noise of either sign, and chasing
      // it costs factorizations for nothing.
      const bool small_change = trustworthy && finite && predicted <= tolerance;
      const bool small_step = trustworthy && step_norm <= params_.step_tolerance;
      bool accepted = false;
      if (rho > params_.min_gain_ratio || ((small_change || small_step) && finite && new_error <= error)) {
        std::swap(estimate_, candidate_);
        std::copy(candidate_errors_.begin(), candidate_errors_.begin() + static_cast<std::ptrdiff_t>(factors_.size()),
                  factor_errors_.begin());
        std::copy(candidate_errors_.begin() + static_cast<std::ptrdiff_t>(factors_.size()), candidate_errors_.end(),
                  prior_errors_.begin());
        // candidate_ now holds the previous estimate; the next candidate
        // overwrites every key of the ordering, and keys in no factor never move.
        error = new_error;
        accepted = any_accepted = true;
        linearized_at_estimate_ = false;
        if (rho > params_.min_gain_ratio) {
          const double t = 2.0 * rho - 1.0;
          lambda = std::max(params_.lambda_min, lambda * std::max(1.0 / 3.0, 1.0 - t * t * t));
          nu = 2.0;
        }
      }
      if (small_change || small_step) {
        converged = true;
        done = true;
        break;
      }
      if (accepted) break;
      if (!increaseLambda()) {
        done = true;
        break;
      }
    }
  }
  error_ = error;
  stats.lambda = lambda;
  stats.step_accepted = any_accepted || converged;
}

// --- Marginalization -----------------------------------------------------------

std::optional<CovarianceBlock> SlidingWindowSmoother::marginalCovariance(Key key, std::string* failure) {
  auto fail = [&](std::string why) -> std::optional<CovarianceBlock> {
    if (failure) *failure = std::move(why);
    return std::nullopt;
  };
  auto it = vars_.find(key);
  if (it == vars_.end()) return fail("unknown variable " + keyString(key) + " (never added, or marginalized)");
  if (!structure_valid_) buildStructure();
  const int pos = it->second.pos;
  if (pos < 0) return fail(keyString(key) + " is in no factor");
  if (!covariance_factorized_) {
    if (!linearized_at_estimate_) linearize();
    setDiagonal(0.0);
    const SymmetricCscView view{n_, col_ptr_.data(), row_idx_.data(), values_.data()};
    covariance_status_ = cholmod_.factorize(
        view, FactorizeOptions{.shift = 0.0, .min_pivot_ratio = params_.indeterminate_pivot_ratio}, factor_);
    covariance_factorized_ = true;
  }
  if (!covariance_status_.ok()) {
    return fail("window Hessian is indeterminate (unconstrained direction or gauge freedom): " +
                covariance_status_.message);
  }
  const int offset = offsets_[static_cast<std::size_t>(pos)];
  const int dim = it->second.dim;
  Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(n_, dim);
  for (int i = 0; i < dim; ++i) unit(offset + i, i) = 1.0;
  Eigen::MatrixXd solved(n_, dim);
  const CholmodResult solved_status = cholmod_.solve(factor_, unit.data(), dim, solved.data());
  if (!solved_status.ok()) return fail("solve failed: " + solved_status.message);
  Eigen::MatrixXd block = solved.middleRows(offset, dim);
  block = 0.5 * (block + block.transpose()).eval();
  if (!block.allFinite()) return fail("covariance of " + keyString(key) + " is not finite");
  return CovarianceBlock(block);
}

}  // namespace rilo
