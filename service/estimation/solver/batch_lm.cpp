#include "estimation/solver/batch_lm.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "estimation/solver/ordering.h"

namespace rilo {
namespace {
/// lambda * max(D) below this fraction of max(diag(J^T J)): the step is Gauss-Newton's.
constexpr double kNegligibleDamping = 1e-6;
}  // namespace


namespace {
double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// std::to_string prints tiny tolerances as 0.000000.
std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}
}  // namespace

BatchLevenbergMarquardt::BatchLevenbergMarquardt(LmParams params) : params_(params) { params_.validate(); }

bool BatchLevenbergMarquardt::structureMatches(const FactorGraph& graph, const Values& values) const {
  if (!structure_valid_ || graph.size() != structure_sizes_.size()) return false;
  std::size_t q = 0;
  for (std::size_t f = 0; f < graph.size(); ++f) {
    const auto& keys = graph[f]->keys();
    if (keys.size() != structure_sizes_[f]) return false;
    for (Key k : keys) {
      if (structure_keys_[q++] != k) return false;
    }
  }
  // Variable types (dimensions) must match too.
  for (std::size_t pos = 0; pos < normal_.numVariables(); ++pos) {
    if (values.dim(normal_.ordering()[pos]) != normal_.varDim(pos)) return false;
  }
  return true;
}

void BatchLevenbergMarquardt::buildStructure(const FactorGraph& graph, const Values& values, LmResult& result) {
  structure_valid_ = false;
  factor_.reset();
  const std::vector<Key> ordering =
      params_.ordering == LmParams::Ordering::kColamd ? colamdOrdering(graph) : naturalOrdering(graph);
  normal_.setStructure(graph, values, ordering);
  const int n = normal_.dim();
  undamped_diagonal_.setZero(n);
  damping_.setZero(n);
  negative_gradient_.setZero(n);
  step_.setZero(n);
  hessian_step_.setZero(n);
  // The matrix is already in elimination order: no postorder, so CHOLMOD's
  // simplicial factorization reads the upper triangle as is (a postorder makes
  // it transpose-permute A on every factorization, ~30% of the solve time).
  const CholmodResult analyzed = cholmod_.analyze(
      normal_.hessian(), {},
      AnalyzeOptions{.postorder = false, .kernel = AnalyzeOptions::Kernel::kSupernodalEigen}, &factor_);
  if (!analyzed.ok()) {
    result.status = LmStatus::kLinearSolverFailure;
    result.message = "symbolic analysis failed: " + analyzed.message;
    return;
  }
  structure_keys_.clear();
  structure_sizes_.clear();
  for (const auto& f : graph) {
    structure_keys_.insert(structure_keys_.end(), f->keys().begin(), f->keys().end());
    structure_sizes_.push_back(f->keys().size());
  }
  structure_valid_ = true;
}

void BatchLevenbergMarquardt::setDampedDiagonal(double lambda) {
  std::span<double> h = normal_.hessianValues();
  const auto& diag = normal_.diagonalIndex();
  for (std::size_t i = 0; i < diag.size(); ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    h[static_cast<std::size_t>(diag[i])] = undamped_diagonal_(ii) + lambda * damping_(ii);
  }
}

bool BatchLevenbergMarquardt::increaseLambda(double& lambda, double& nu) const {
  const double next = std::max(params_.lambda_min, lambda * nu);
  nu *= 2.0;
  if (!(next <= params_.lambda_max)) return false;
  lambda = next;
  return true;
}

void BatchLevenbergMarquardt::checkKeys(const FactorGraph& graph, const Values& values) const {
  for (std::size_t f = 0; f < graph.size(); ++f) {
    for (Key k : graph[f]->keys()) {
      if (!values.exists(k)) {
        throw std::invalid_argument("BatchLevenbergMarquardt::optimize: key " + keyString(k) + " of factor " +
                                    std::to_string(f) + " has no initial value");
      }
    }
  }
}

namespace {
/// Bitwise-equal contents (same alternative, same doubles): only then is a
/// linearization at `a` the one at `b`.
bool sameVariable(const Variable& a, const Variable& b) {
  if (a.index() != b.index()) return false;
  if (const auto* pa = std::get_if<Pose3>(&a)) {
    const Pose3& pb = std::get<Pose3>(b);
    return pa->R == pb.R && pa->p == pb.p;
  }
  if (const auto* va = std::get_if<Vec3>(&a)) return *va == std::get<Vec3>(b);
  const ImuBias& ba = std::get<ImuBias>(a);
  const ImuBias& bb = std::get<ImuBias>(b);
  return ba.accel == bb.accel && ba.gyro == bb.gyro;
}
}  // namespace

bool BatchLevenbergMarquardt::holdsLinearizationAt(const FactorGraph& graph, const Values& values) const {
  if (!start_linearized_ || !structureMatches(graph, values)) return false;
  // The same factor objects (structureMatches compares keys only) ...
  if (graph.size() != solution_graph_.size()) return false;
  for (std::size_t f = 0; f < graph.size(); ++f) {
    if (graph[f].get() != solution_graph_[f].get()) return false;
  }
  // ... at the same values of every optimized variable.
  for (Key k : normal_.ordering()) {
    if (!sameVariable(values.at(k), solution_values_.at(k))) return false;
  }
  return true;
}

std::optional<BatchLevenbergMarquardt::CovarianceBlock> BatchLevenbergMarquardt::covarianceAt(
    const FactorGraph& graph, const Values& values, Key key, std::string* failure) {
  have_solution_ = false;
  linearized_at_solution_ = false;
  covariance_factorized_ = false;
  start_linearized_ = false;
  checkKeys(graph, values);
  solution_graph_ = graph;
  solution_values_ = values;
  have_solution_ = true;
  // What optimize() with no iterations leaves: no system on a non-finite
  // error, a failed analysis or no variables.
  auto noCovariance = [&](const std::string& message) {
    covariance_factorized_ = true;
    covariance_status_ = {CholmodStatus::kInvalidInput, "optimize() stopped before linearizing: " + message, -1};
    if (failure) *failure = "J^T J at the solution: " + covariance_status_.message;
    return std::nullopt;
  };
  const double error = graph.error(values);
  if (!std::isfinite(error)) return noCovariance("initial error is not finite");
  if (!structureMatches(graph, values)) {
    LmResult res;
    buildStructure(graph, values, res);
    if (!structure_valid_) return noCovariance(res.message);
  }
  if (normal_.dim() == 0) return noCovariance("no variables to optimize");
  // marginalCovariance() linearizes at solution_values_ (undamped) and factorizes.
  std::optional<CovarianceBlock> cov = marginalCovariance(key, failure);
  start_linearized_ = true;
  start_error_ = error;
  return cov;
}

BatchLevenbergMarquardt::Output BatchLevenbergMarquardt::optimize(const FactorGraph& graph, const Values& initial) {
  const auto t0 = std::chrono::steady_clock::now();
  // The probe's linearization and error at these values, if covarianceAt() left them.
  const bool reuse_start = holdsLinearizationAt(graph, initial);
  start_linearized_ = false;
  have_solution_ = false;
  linearized_at_solution_ = false;
  covariance_factorized_ = false;
  checkKeys(graph, initial);

  Output out{initial, {}};
  Values& x = out.values;
  LmResult& res = out.result;
  auto finish = [&](LmStatus status, std::string message, double error, double lambda) {
    res.status = status;
    res.message = std::move(message);
    res.final_error = error;
    res.final_lambda = lambda;
    res.time_s = secondsSince(t0);
  };
  // Early exits leave no system to take a covariance from.
  auto noCovariance = [&]() {
    have_solution_ = true;
    covariance_factorized_ = true;
    covariance_status_ = {CholmodStatus::kInvalidInput, "optimize() stopped before linearizing: " + res.message, -1};
  };

  double error = reuse_start ? start_error_ : graph.error(x);
  res.initial_error = error;
  if (!std::isfinite(error)) {
    finish(LmStatus::kNonFiniteError, "initial error is not finite", error, params_.lambda_initial);
    noCovariance();
    return out;
  }
  if (!structureMatches(graph, x)) {
    buildStructure(graph, x, res);
    if (!structure_valid_) {
      finish(LmStatus::kLinearSolverFailure, res.message, error, params_.lambda_initial);
      noCovariance();
      return out;
    }
  }
  if (normal_.dim() == 0) {
    finish(LmStatus::kGradientTolerance, "no variables to optimize", error, params_.lambda_initial);
    noCovariance();
    return out;
  }

  const auto& ordering = normal_.ordering();
  Values candidate = x;  // same keys as x; only optimized keys are overwritten
  double lambda = params_.lambda_initial;
  double nu = 2.0;
  bool done = false;
  std::string indeterminate_message;
  if (params_.record_trace) res.trace.reserve(static_cast<std::size_t>(params_.max_iterations));
  for (int iter = 0; iter < params_.max_iterations && !done; ++iter) {
    if (params_.cancel && params_.cancel->load(std::memory_order_relaxed)) {
      finish(LmStatus::kCancelled, "cancelled before iteration " + std::to_string(iter), error, lambda);
      done = true;
      break;
    }
    if (iter > 0 || !reuse_start) normal_.linearize(graph, x);
    linearized_at_solution_ = true;
    const std::span<const double> h = normal_.hessianValues();
    const auto& diag = normal_.diagonalIndex();
    for (std::size_t i = 0; i < diag.size(); ++i) {
      const auto ii = static_cast<Eigen::Index>(i);
      undamped_diagonal_(ii) = h[static_cast<std::size_t>(diag[i])];
      damping_(ii) = params_.damping == LmParams::Damping::kMarquardt
                         ? std::clamp(undamped_diagonal_(ii), params_.min_diagonal, params_.max_diagonal)
                         : 1.0;
    }
    const Eigen::VectorXd& g = normal_.gradient();
    const double gradient_norm = g.lpNorm<Eigen::Infinity>();
    if (gradient_norm <= params_.gradient_tolerance) {
      finish(LmStatus::kGradientTolerance, "gradient |J^T r|_inf " + fmt(gradient_norm) + " below tolerance", error,
             lambda);
      done = true;
      break;
    }
    ++res.iterations;
    negative_gradient_ = -g;

    LmIteration it;
    it.iteration = iter;
    while (true) {
      it.lambda = lambda;
      ++it.attempts;
      setDampedDiagonal(lambda);
      ++res.factorizations;
      const CholmodResult factorized = cholmod_.factorize(
          normal_.hessian(), FactorizeOptions{.shift = 0.0, .min_pivot_ratio = params_.indeterminate_pivot_ratio},
          factor_);
      if (factorized.status == CholmodStatus::kNotPositiveDefinite) {
        ++res.indeterminate_factorizations;
        indeterminate_message = factorized.message;
        if (!increaseLambda(lambda, nu)) {
          finish(LmStatus::kLambdaMaxReached, "indeterminate system up to lambda_max: " + indeterminate_message, error,
                 lambda);
          done = true;
          break;
        }
        continue;
      }
      if (!factorized.ok()) {
        finish(LmStatus::kLinearSolverFailure, factorized.message, error, lambda);
        done = true;
        break;
      }
      const CholmodResult solved = cholmod_.solve(factor_, negative_gradient_.data(), 1, step_.data());
      if (!solved.ok()) {
        finish(LmStatus::kLinearSolverFailure, solved.message, error, lambda);
        done = true;
        break;
      }
      const double step_norm = step_.lpNorm<Eigen::Infinity>();
      // Decrease predicted by the undamped model m(d) = |J d + r|^2 / 2:
      // -g.d - d^T (J^T J) d / 2, with J^T J d = (damped H) d - lambda D d.
      normal_.multiplyHessian(step_, hessian_step_);
      const double d_D_d = (step_.array().square() * damping_.array()).sum();
      const double predicted = -g.dot(step_) - 0.5 * (step_.dot(hessian_step_) - lambda * d_D_d);

      for (std::size_t pos = 0; pos < ordering.size(); ++pos) {
        const Key k = ordering[pos];
        candidate.update(k, retractVariable(x.at(k), step_.data() + normal_.offset(pos)));
      }
      const double new_error = graph.error(candidate);
      const bool finite = std::isfinite(new_error);
      const double actual = error - new_error;
      const double rho = (finite && predicted > 0.0) ? actual / predicted : -std::numeric_limits<double>::infinity();
      const double tolerance = std::max(params_.absolute_error_tolerance, params_.relative_error_tolerance * error);
      // A small step or change only signals convergence when damping did not
      // shrink the step: at a large lambda every step is small, optimum or not.
      const bool damping_negligible =
          lambda * damping_.maxCoeff() <= kNegligibleDamping * undamped_diagonal_.maxCoeff();
      const bool trustworthy = damping_negligible;
      const bool small_change = trustworthy && finite && std::abs(actual) <= tolerance && predicted <= tolerance;
      const bool small_step = trustworthy && step_norm <= params_.step_tolerance;
      it.gain_ratio = std::isfinite(rho) ? rho : 0.0;
      it.step_norm = step_norm;

      if (rho > params_.min_gain_ratio || ((small_change || small_step) && finite && new_error <= error)) {
        std::swap(x, candidate);
        error = new_error;
        it.accepted = true;
        linearized_at_solution_ = false;
        if (rho > params_.min_gain_ratio) {
          const double t = 2.0 * rho - 1.0;
          lambda = std::max(params_.lambda_min, lambda * std::max(1.0 / 3.0, 1.0 - t * t * t));
          nu = 2.0;
        }
      } else {
        ++res.rejected_steps;
      }
      if (small_change) {
        finish(LmStatus::kErrorTolerance,
               "error change " + fmt(actual) + " (predicted " + fmt(predicted) + ") below tolerance", error, lambda);
        done = true;
        break;
      }
      if (small_step) {
        finish(LmStatus::kStepTolerance, "step |d|_inf " + fmt(step_norm) + " below tolerance", error, lambda);
        done = true;
        break;
      }
      if (it.accepted) break;
      if (!increaseLambda(lambda, nu)) {
        finish(LmStatus::kLambdaMaxReached, "no decrease up to lambda_max", error, lambda);
        done = true;
        break;
      }
    }
    if (params_.record_trace) {
      it.error = error;
      it.time_s = secondsSince(t0);
      res.trace.push_back(it);
    }
  }
  if (!done) {
    finish(LmStatus::kMaxIterations, "reached " + std::to_string(params_.max_iterations) + " iterations", error,
           lambda);
  }

  have_solution_ = true;
  solution_graph_ = graph;
  solution_values_ = x;
  return out;
}

std::optional<BatchLevenbergMarquardt::CovarianceBlock> BatchLevenbergMarquardt::marginalCovariance(
    Key key, std::string* failure) {
  if (!have_solution_) throw std::logic_error("BatchLevenbergMarquardt::marginalCovariance: call optimize() first");
  if (covariance_factorized_ && !covariance_status_.ok()) {
    if (failure) *failure = "J^T J at the solution: " + covariance_status_.message;
    return std::nullopt;
  }
  const std::size_t pos = normal_.position(key);
  if (!covariance_factorized_) {
    if (linearized_at_solution_) {
      setDampedDiagonal(0.0);  // normal_ holds J^T J at the solution, possibly with damping
    } else {
      normal_.linearize(solution_graph_, solution_values_);
    }
    covariance_status_ = cholmod_.factorize(
        normal_.hessian(), FactorizeOptions{.shift = 0.0, .min_pivot_ratio = params_.indeterminate_pivot_ratio},
        factor_);
    covariance_factorized_ = true;
  }
  if (!covariance_status_.ok()) {
    if (failure) *failure = "J^T J at the solution: " + covariance_status_.message;
    return std::nullopt;
  }
  const int n = normal_.dim();
  const int d = normal_.varDim(pos);
  const int off = normal_.offset(pos);
  unit_columns_.setZero(static_cast<Eigen::Index>(n) * d);
  solved_columns_.resize(static_cast<Eigen::Index>(n) * d);
  for (int c = 0; c < d; ++c) unit_columns_(static_cast<Eigen::Index>(c) * n + off + c) = 1.0;
  const CholmodResult solved = cholmod_.solve(factor_, unit_columns_.data(), d, solved_columns_.data());
  if (!solved.ok()) {
    if (failure) *failure = solved.message;
    return std::nullopt;
  }
  CovarianceBlock cov(d, d);
  for (int c = 0; c < d; ++c) {
    for (int r = 0; r < d; ++r) cov(r, c) = solved_columns_(static_cast<Eigen::Index>(c) * n + off + r);
  }
  return CovarianceBlock(0.5 * (cov + cov.transpose()));
}

}  // namespace rilo
