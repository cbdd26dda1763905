#pragma once
// A marginal kept by the fixed-lag smoother: the Gaussian factor
//   r(x) = A * [local(x0_1, x_1); ...; local(x0_k, x_k)] - d
// over the Markov blanket of marginalized variables, frozen at their
// linearization points x0 (first-estimate Jacobians keep the estimator
// consistent). Unlike Factor it may span any number of keys and rows.
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "estimation/graph/values.h"

namespace rilo {

class LinearMarginal {
 public:
  /// A has sum(dims of keys) columns in keys order; d has A.rows() entries.
  /// Throws std::invalid_argument on inconsistent sizes or a key missing in x0.
  LinearMarginal(std::vector<Key> keys, const Values& x0, Eigen::MatrixXd A, Eigen::VectorXd d);

  const std::vector<Key>& keys() const { return keys_; }
  int rows() const { return static_cast<int>(A_.rows()); }
  int cols() const { return static_cast<int>(A_.cols()); }
  const Eigen::MatrixXd& A() const { return A_; }
  const Eigen::VectorXd& d() const { return d_; }
  const Variable& linearizationPoint(std::size_t i) const { return x0_[i]; }

  /// r(x) and, when J is given, dr/d(delta) in the retraction chart of x
  /// (exact: A times the Jacobian of local(x0, x (+) delta)). At x = x0 the
  /// Jacobian is A.
  void evaluate(const Values& x, Eigen::VectorXd& r, Eigen::MatrixXd* J = nullptr) const;
  /// |r(x)|^2 / 2
  double error(const Values& x) const;

 private:
  std::vector<Key> keys_;
  std::vector<Variable> x0_;
  std::vector<int> offsets_;
  Eigen::MatrixXd A_;
  Eigen::VectorXd d_;
};

using LinearMarginalPtr = std::shared_ptr<const LinearMarginal>;

}  // namespace rilo
