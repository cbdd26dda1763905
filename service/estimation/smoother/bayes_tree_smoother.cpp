// BayesTreeSmoother: update() orchestration, input checks, variable and
// factor bookkeeping, fluid relinearization, accessors.
#include "estimation/smoother/bayes_tree_smoother.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <unordered_set>

namespace rilo {
namespace {

constexpr int kErrorResumInterval = 256;  // updates between exact re-sums of the cached errors

}  // namespace

BayesTreeSmoother::BayesTreeSmoother(SmootherParams params) : params_(std::move(params)) {
  params_.validate();
  lambda_ = params_.d_isam2.lambda_initial;
  trust_radius_ = params_.dogleg.trust_radius_initial;
}

BayesTreeSmoother::~BayesTreeSmoother() = default;

// --- Pools -----------------------------------------------------------------

BayesTreeSmoother::VarId BayesTreeSmoother::allocVar() {
  VarId v;
  if (!free_vars_.empty()) {
    v = free_vars_.back();
    free_vars_.pop_back();
  } else {
    v = static_cast<VarId>(vars_.size());
    vars_.emplace_back();
  }
  VarSlot& slot = vars_[v];
  std::vector<FactorId> keep = std::move(slot.factors);  // reuse the list's capacity
  keep.clear();
  slot = VarSlot{};
  slot.factors = std::move(keep);
  slot.alive = true;
  return v;
}

BayesTreeSmoother::FactorId BayesTreeSmoother::allocFactor() {
  FactorId f;
  if (!free_factors_.empty()) {
    f = free_factors_.back();
    free_factors_.pop_back();
  } else {
    f = static_cast<FactorId>(factors_.size());
    factors_.emplace_back();
  }
  FactorSlot& slot = factors_[f];
  slot.alive = true;
  slot.nonlinear.reset();
  slot.marginal.reset();
  slot.vars.clear();
  slot.clique = kNone;
  slot.needs_linearization = true;
  slot.error = 0.0;
  slot.error_at_theta = 0.0;
  ++live_factors_;
  return f;
}

BayesTreeSmoother::CliqueId BayesTreeSmoother::allocClique() {
  CliqueId c;
  if (!free_cliques_.empty()) {
    c = free_cliques_.back();
    free_cliques_.pop_back();
  } else {
    c = static_cast<CliqueId>(cliques_.size());
    cliques_.emplace_back();
  }
  Clique& q = cliques_[c];
  q.alive = true;
  q.frontals.clear();
  q.separator.clear();
  q.children.clear();
  q.factors.clear();
  q.frontal_dim = q.separator_dim = 0;
  q.parent = kNone;
  q.replaced = false;
  return c;
}

void BayesTreeSmoother::freeClique(CliqueId c) {
  cliques_[c].alive = false;
  free_cliques_.push_back(c);
}

void BayesTreeSmoother::removeFactor(FactorId f) {
  FactorSlot& slot = factors_[f];
  error_at_estimate_ -= slot.error;
  error_at_theta_ -= slot.error_at_theta;
  for (VarId v : slot.vars) {
    auto& list = vars_[v].factors;
    auto it = std::find(list.begin(), list.end(), f);
    if (it != list.end()) {
      *it = list.back();
      list.pop_back();
    }
    if (slot.marginal) --vars_[v].frozen;
  }
  if (slot.clique != kNone) {
    auto& list = cliques_[slot.clique].factors;
    auto it = std::find(list.begin(), list.end(), f);
    if (it != list.end()) {
      *it = list.back();
      list.pop_back();
    }
  }
  slot.alive = false;
  slot.nonlinear.reset();
  slot.marginal.reset();
  free_factors_.push_back(f);
  --live_factors_;
}

void BayesTreeSmoother::removeVar(VarId v) {
  VarSlot& slot = vars_[v];
  theta_.erase(slot.key);
  estimate_.erase(slot.key);
  key_to_var_.erase(slot.key);
  slot.alive = false;
  slot.clique = kNone;
  free_vars_.push_back(v);
}

// --- update() ---------------------------------------------------------------

UpdateStats BayesTreeSmoother::update(const FactorGraph& new_factors, const Values& new_values,
                                      const KeyTimestamps& timestamps) {
  const auto t_start = std::chrono::steady_clock::now();
  validateInput(new_factors, new_values, timestamps);  // throws with nothing changed
  UpdateStats stats;
  ++update_count_;

  insertVariables(new_values, timestamps, stats);
  const std::vector<FactorId> added = insertFactors(new_factors, stats);
  stats.error_before = error_at_estimate_;

  const std::vector<VarId> marginalizable = selectMarginalizable();
  std::vector<VarId> marked;
  for (FactorId f : added) marked.insert(marked.end(), factors_[f].vars.begin(), factors_[f].vars.end());
  relinearize(marked, marginalizable, stats);
  markForCleanMarginalization(marginalizable, marked, stats);

  // Marked before the tree is updated: its elimination adds the damping rows.
  std::vector<VarId> damped;
  const bool damp = markDampedVariables(added, new_values, damped);
  updateTree(marked, added, stats);

  switch (params_.method) {
    case SmootherParams::Method::kGaussNewton: stepGaussNewton(stats); break;
    case SmootherParams::Method::kDamped: stepDamped(damp, damped, stats); break;
    case SmootherParams::Method::kDogleg: stepDogleg(stats); break;
  }
  for (CliqueId c : top_cliques_) cliques_[c].replaced = false;  // only the top was re-eliminated

  marginalize(marginalizable, stats);

  // The running sums lose ~1e-16 of the largest error they ever held per
  // operation: re-add the cached per-factor errors periodically and whenever
  // the error has fallen far below its recent peak (a converging start).
  error_peak_ = std::max({error_peak_, std::abs(stats.error_before), std::abs(error_at_estimate_) + std::abs(error_at_theta_)});
  if (++updates_since_error_resum_ >= kErrorResumInterval ||
      std::abs(error_at_estimate_) + std::abs(error_at_theta_) < 1e-3 * error_peak_) {
    updates_since_error_resum_ = 0;
    error_at_estimate_ = 0.0;
    error_at_theta_ = 0.0;
    for (const FactorSlot& f : factors_) {
      if (!f.alive) continue;
      error_at_estimate_ += f.error;
      error_at_theta_ += f.error_at_theta;
    }
    error_peak_ = std::abs(error_at_estimate_) + std::abs(error_at_theta_);
  }
  stats.error_after = error_at_estimate_;
  if (!tracksError()) {  // the running sum holds stale per-factor errors
    stats.error_before = std::numeric_limits<double>::quiet_NaN();
    stats.error_after = std::numeric_limits<double>::quiet_NaN();
  }
  stats.cliques_total = cliqueCount();
  stats.variables_total = variableCount();
  stats.factors_total = live_factors_;
  stats.trust_radius = params_.method == SmootherParams::Method::kDogleg ? trust_radius_ : 0.0;
  stats.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return stats;
}

void BayesTreeSmoother::validateInput(const FactorGraph& new_factors, const Values& new_values,
                                      const KeyTimestamps& timestamps) const {
  for (const auto& [key, value] : new_values) {
    if (key_to_var_.count(key)) throw std::invalid_argument("BayesTreeSmoother::update: value for existing variable " + keyString(key));
  }
  std::unordered_set<Key> covered;
  for (std::size_t i = 0; i < new_factors.size(); ++i) {
    const FactorPtr& f = new_factors[i];
    if (!f) throw std::invalid_argument("BayesTreeSmoother::update: new factor " + std::to_string(i) + " is null");
    for (std::size_t a = 0; a < f->keys().size(); ++a) {
      const Key k = f->keys()[a];
      for (std::size_t b = 0; b < a; ++b) {
        if (f->keys()[b] == k) throw std::invalid_argument("BayesTreeSmoother::update: new factor " + std::to_string(i) + " repeats key " + keyString(k));
      }
      if (!new_values.exists(k) && !key_to_var_.count(k)) {
        throw std::invalid_argument("BayesTreeSmoother::update: new factor " + std::to_string(i) + " uses " + keyString(k) +
                                    ", which has no value (never added, or marginalized)");
      }
      covered.insert(k);
    }
    // The variable types a factor needs are known only to its evaluate():
    // try it once on its own keys before anything is inserted.
    Values scratch;
    for (Key k : f->keys()) scratch.insertOrAssign(k, new_values.exists(k) ? new_values.at(k) : theta_.at(k));
    try {
      Residual r;
      Jacobians H;
      f->evaluate(scratch, r, &H);
    } catch (const std::exception& e) {
      std::string keys;
      for (Key k : f->keys()) keys += (keys.empty() ? "" : ", ") + keyString(k);
      throw std::invalid_argument("BayesTreeSmoother::update: new factor " + std::to_string(i) + " (keys " + keys +
                                  ") cannot be evaluated on the given values: " + e.what());
    }
  }
  for (const auto& [key, value] : new_values) {
    if (!covered.count(key)) throw std::invalid_argument("BayesTreeSmoother::update: new variable " + keyString(key) + " has no factor");
  }
  for (const auto& [key, t] : timestamps) {
    if (!new_values.exists(key)) throw std::invalid_argument("BayesTreeSmoother::update: timestamp for " + keyString(key) + ", which is not a new variable");
  }
}

void BayesTreeSmoother::insertVariables(const Values& new_values, const KeyTimestamps& timestamps, UpdateStats& stats) {
  for (Key key : new_values.keys()) {  // sorted: deterministic slot assignment
    const VarId v = allocVar();
    VarSlot& slot = vars_[v];
    const Variable& value = new_values.at(key);
    slot.key = key;
    slot.dim = variableDim(value);
    slot.introduced_at = update_count_;
    if (auto it = timestamps.find(key); it != timestamps.end()) {
      slot.has_time = true;
      slot.t_ns = it->second;
      if (!have_time_ || it->second > newest_t_ns_) newest_t_ns_ = it->second;
      have_time_ = true;
      noteRecentTime(it->second);
    }
    // Relinearization threshold by variable kind and key symbol.
    const char symbol = keySymbol(key);
    if (slot.dim == 3) {
      auto it = params_.relinearize_thresholds3.find(symbol);
      slot.threshold.head<3>() = it != params_.relinearize_thresholds3.end() ? it->second : params_.default_vec3_threshold;
    } else {
      auto it = params_.relinearize_thresholds6.find(symbol);
      const bool is_pose = std::holds_alternative<Pose3>(value);
      slot.threshold = it != params_.relinearize_thresholds6.end() ? it->second
                       : is_pose ? params_.default_pose_threshold : params_.default_bias_threshold;
    }
    theta_.insertOrAssign(key, value);
    estimate_.insertOrAssign(key, value);
    key_to_var_.emplace(key, v);
    ++stats.variables_added;
  }
}

std::vector<BayesTreeSmoother::FactorId> BayesTreeSmoother::insertFactors(const FactorGraph& new_factors, UpdateStats& stats) {
  std::vector<FactorId> added;
  added.reserve(new_factors.size());
  for (const FactorPtr& factor : new_factors) {
    const FactorId f = allocFactor();
    FactorSlot& slot = factors_[f];
    slot.nonlinear = factor;
    for (Key k : factor->keys()) {
      const VarId v = key_to_var_.at(k);
      slot.vars.push_back(v);
      vars_[v].factors.push_back(f);
    }
    slot.error = factorError(slot, estimate_);
    slot.error_at_theta = params_.method == SmootherParams::Method::kDogleg ? factorError(slot, theta_) : 0.0;
    error_at_estimate_ += slot.error;
    error_at_theta_ += slot.error_at_theta;
    added.push_back(f);
    ++stats.factors_added;
  }
  return added;
}

double BayesTreeSmoother::factorError(const FactorSlot& f, const Values& x) const {
  return f.nonlinear ? f.nonlinear->error(x) : f.marginal->error(x);
}

// --- Fluid relinearization ----------------------------------------------------

void BayesTreeSmoother::noteRecentTime(std::int64_t t_ns) {
  const auto keep = static_cast<std::size_t>(params_.relinearize_min_recent_times);
  if (keep == 0 || (!recent_times_.empty() && t_ns <= recent_times_.back())) return;  // seen, or out of order
  recent_times_.push_back(t_ns);
  if (recent_times_.size() > keep) recent_times_.pop_front();
}

bool BayesTreeSmoother::thresholdIntervalElapsed(const UpdateStats& stats) const {
  // An update without new variables is an extra iteration: it always checks.
  if (params_.relinearize_interval_s <= 0.0 || !have_time_ || !threshold_checked_ || stats.variables_added == 0) return true;
  const auto interval_ns = static_cast<std::int64_t>(std::llround(params_.relinearize_interval_s * 1e9));
  return newest_t_ns_ - last_threshold_check_ns_ >= interval_ns;
}

void BayesTreeSmoother::relinearize(std::vector<VarId>& marked, const std::vector<VarId>& marginalizable,
                                    UpdateStats& stats) {
  // After a rejected D-iSAM2 step every moved variable is relinearized at the
  // kept estimate, so the tree and the deltas agree again.
  const bool all = relinearize_all_pending_;
  relinearize_all_pending_ = false;
  const bool together = params_.relinearize_together || all;
  const bool threshold_check =
      all || (update_count_ % static_cast<std::uint64_t>(params_.relinearize_skip) == 0 && thresholdIntervalElapsed(stats));
  if (threshold_check) {
    last_threshold_check_ns_ = newest_t_ns_;
    threshold_checked_ = true;
  }
  // About to be marginalized: relinearizing them alone would re-eliminate the
  // path from their leaf to the root for nothing. When everything moves
  // together they move too: a stale state next to a fresh one leaves a large
  // IMU residual at theta.
  const std::uint64_t skip_stamp = newStamp();
  if (!together) {
    for (VarId v : marginalizable) vars_[v].mark = skip_stamp;
  }
  if (all && params_.after_rejection_max_age_s > 0.0 && have_time_) {
    // A bounded refresh after a rejection: the young states only.
    const std::int64_t oldest_ns =
        newest_t_ns_ - static_cast<std::int64_t>(std::llround(params_.after_rejection_max_age_s * 1e9));
    for (VarSlot& slot : vars_) {
      if (slot.alive && (!slot.has_time || slot.t_ns < oldest_ns)) slot.mark = skip_stamp;
    }
  }
  const bool enough_recent = recent_times_.size() >= static_cast<std::size_t>(params_.relinearize_min_recent_times);
  if (params_.relinearize_max_age_s > 0.0 && have_time_ && !all && enough_recent) {
    std::int64_t oldest_ns = newest_t_ns_ - static_cast<std::int64_t>(std::llround(params_.relinearize_max_age_s * 1e9));
    if (!recent_times_.empty()) oldest_ns = std::min(oldest_ns, recent_times_.front());
    for (VarSlot& slot : vars_) {
      if (slot.alive && slot.has_time && slot.t_ns < oldest_ns) slot.mark = skip_stamp;
    }
  }

  std::vector<VarId> forced;
  std::vector<std::pair<double, VarId>> by_threshold;  // (largest |delta| / threshold, var)
  bool any_passed = false;
  for (VarId v = 0; v < static_cast<VarId>(vars_.size()); ++v) {
    VarSlot& slot = vars_[v];
    if (!slot.alive || slot.mark == skip_stamp || slot.introduced_at == update_count_) continue;
    if (slot.frozen > 0 && params_.freeze_marginal_variables) continue;
    const auto step = slot.step.head(slot.dim);
    if (step.isZero(0.0)) continue;
    const std::uint64_t age = update_count_ - slot.introduced_at;
    if (age <= static_cast<std::uint64_t>(params_.always_relinearize_recent_updates)) {
      forced.push_back(v);
      continue;
    }
    if (!threshold_check) continue;
    double ratio = 0.0;
    for (int i = 0; i < slot.dim; ++i) {
      const double t = slot.threshold[i];
      const double a = std::abs(step[i]);
      ratio = std::max(ratio, t > 0.0 ? a / t : (a > 0.0 ? std::numeric_limits<double>::infinity() : 0.0));
    }
    any_passed |= ratio >= 1.0;
    if (ratio >= 1.0 || together) by_threshold.emplace_back(ratio, v);
  }
  if (together && !any_passed && !all) by_threshold.clear();
  if (params_.max_relinearized_variables > 0 && !together &&
      by_threshold.size() > static_cast<std::size_t>(params_.max_relinearized_variables)) {
    const auto keep = by_threshold.begin() + params_.max_relinearized_variables;
    std::nth_element(by_threshold.begin(), keep, by_threshold.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    by_threshold.erase(keep, by_threshold.end());
  }
  for (const auto& [ratio, v] : by_threshold) forced.push_back(v);

  const std::uint64_t factor_stamp = newStamp();
  for (VarId v : forced) {
    VarSlot& slot = vars_[v];
    theta_.retractInPlace(slot.key, slot.step.data());
    estimate_.insertOrAssign(slot.key, theta_.at(slot.key));
    slot.delta.setZero();
    slot.step.setZero();
    ++stats.variables_relinearized;
    for (FactorId f : slot.factors) {
      FactorSlot& fs = factors_[f];
      if (fs.mark == factor_stamp) continue;
      fs.mark = factor_stamp;
      fs.needs_linearization = true;
      marked.insert(marked.end(), fs.vars.begin(), fs.vars.end());
    }
  }
  if (params_.method == SmootherParams::Method::kDogleg && !forced.empty()) {
    // The dog-leg reference error is taken at theta, which just moved.
    for (FactorId f = 0; f < static_cast<FactorId>(factors_.size()); ++f) {
      FactorSlot& fs = factors_[f];
      if (!fs.alive || fs.mark != factor_stamp) continue;
      const double e = factorError(fs, theta_);
      error_at_theta_ += e - fs.error_at_theta;
      fs.error_at_theta = e;
    }
  }
}

// --- Accessors ---------------------------------------------------------------

Values BayesTreeSmoother::estimate() const { return estimate_; }

Variable BayesTreeSmoother::estimate(Key key) const {
  if (!estimate_.exists(key)) throw std::out_of_range("BayesTreeSmoother::estimate: unknown variable " + keyString(key));
  return estimate_.at(key);
}

bool BayesTreeSmoother::exists(Key key) const { return key_to_var_.count(key) != 0; }

Eigen::VectorXd BayesTreeSmoother::delta(Key key) const {
  auto it = key_to_var_.find(key);
  if (it == key_to_var_.end()) throw std::out_of_range("BayesTreeSmoother::delta: unknown variable " + keyString(key));
  const VarSlot& slot = vars_[it->second];
  return slot.delta.head(slot.dim);
}

double BayesTreeSmoother::errorFromScratch() const {
  double sum = 0.0;
  for (const FactorSlot& f : factors_) {
    if (f.alive) sum += factorError(f, estimate_);
  }
  return sum;
}

FactorGraph BayesTreeSmoother::nonlinearFactors() const {
  FactorGraph out;
  for (const FactorSlot& f : factors_) {
    if (f.alive && f.nonlinear) out.add(f.nonlinear);
  }
  return out;
}

std::vector<LinearMarginalPtr> BayesTreeSmoother::linearMarginals() const {
  std::vector<LinearMarginalPtr> out;
  for (const FactorSlot& f : factors_) {
    if (f.alive && f.marginal) out.push_back(f.marginal);
  }
  return out;
}

std::vector<Key> BayesTreeSmoother::frozenKeys() const {
  std::vector<Key> out;
  for (const VarSlot& v : vars_) {
    if (v.alive && v.frozen > 0) out.push_back(v.key);
  }
  std::sort(out.begin(), out.end());
  return out;
}

int BayesTreeSmoother::cliqueCount() const {
  return static_cast<int>(cliques_.size() - free_cliques_.size());
}

std::string BayesTreeSmoother::checkInvariants() const {
  std::ostringstream err;
  std::vector<int> seen(vars_.size(), 0);
  for (CliqueId c = 0; c < static_cast<CliqueId>(cliques_.size()); ++c) {
    const Clique& q = cliques_[c];
    if (!q.alive) continue;
    std::unordered_set<VarId> scope(q.frontals.begin(), q.frontals.end());
    scope.insert(q.separator.begin(), q.separator.end());
    for (VarId v : q.frontals) {
      if (!vars_[v].alive) return "clique " + std::to_string(c) + " has a dead frontal";
      if (vars_[v].clique != c) return "frontal " + keyString(vars_[v].key) + " does not point to its clique";
      ++seen[v];
    }
    if (q.parent == kNone) {
      if (!q.separator.empty()) return "root clique " + std::to_string(c) + " has a separator";
      if (std::find(roots_.begin(), roots_.end(), c) == roots_.end()) return "root clique " + std::to_string(c) + " not in roots";
    } else {
      const Clique& p = cliques_[q.parent];
      if (!p.alive) return "clique " + std::to_string(c) + " has a dead parent";
      if (std::find(p.children.begin(), p.children.end(), c) == p.children.end()) return "parent does not list child";
      std::unordered_set<VarId> pscope(p.frontals.begin(), p.frontals.end());
      pscope.insert(p.separator.begin(), p.separator.end());
      for (VarId s : q.separator) {
        if (!pscope.count(s)) return "running intersection violated: " + keyString(vars_[s].key) + " in separator of clique " + std::to_string(c) + " but not in its parent";
      }
      bool touches_parent_frontal = false;
      for (VarId s : q.separator) touches_parent_frontal |= std::find(p.frontals.begin(), p.frontals.end(), s) != p.frontals.end();
      if (!touches_parent_frontal) return "clique " + std::to_string(c) + " hangs below a clique that eliminates none of its separator";
    }
    for (CliqueId ch : q.children) {
      if (!cliques_[ch].alive || cliques_[ch].parent != c) return "child link broken at clique " + std::to_string(c);
    }
    for (FactorId f : q.factors) {
      const FactorSlot& fs = factors_[f];
      if (!fs.alive || fs.clique != c) return "factor link broken at clique " + std::to_string(c);
      for (VarId v : fs.vars) {
        if (!scope.count(v)) return "factor keys outside its clique " + std::to_string(c);
      }
    }
    if (q.conditional.rows() != q.frontal_dim || q.conditional.cols() != q.frontal_dim + q.separator_dim + 1) {
      return "conditional of clique " + std::to_string(c) + " has the wrong size";
    }
  }
  for (VarId v = 0; v < static_cast<VarId>(vars_.size()); ++v) {
    if (vars_[v].alive && seen[v] != 1) return "variable " + keyString(vars_[v].key) + " is frontal in " + std::to_string(seen[v]) + " cliques";
  }
  for (FactorId f = 0; f < static_cast<FactorId>(factors_.size()); ++f) {
    if (factors_[f].alive && factors_[f].clique == kNone) return "factor " + std::to_string(f) + " is not assigned";
  }
  for (CliqueId r : roots_) {
    if (!cliques_[r].alive || cliques_[r].parent != kNone) return "stale root " + std::to_string(r);
  }
  return {};
}

}  // namespace rilo
