#include "estimation/smoother/linear_marginal.h"

#include <stdexcept>

#include "math/so3.h"

namespace rilo {
namespace {

/// d local(x0, x (+) delta) / d delta at delta = 0.
Eigen::MatrixXd localJacobian(const Variable& x0, const Variable& x) {
  if (const auto* T0 = std::get_if<Pose3>(&x0)) {
    const Pose3& T = std::get<Pose3>(x);
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(6, 6);
    // local = [Log(R0^T R); R0^T (p - p0)], x (+) delta = (R Exp(dphi), p + R drho)
    J.topLeftCorner<3, 3>() = so3::rightJacobianInverse(so3::log(T0->R.transpose() * T.R));
    J.bottomRightCorner<3, 3>() = T0->R.transpose() * T.R;
    return J;
  }
  const int dim = variableDim(x0);
  return Eigen::MatrixXd::Identity(dim, dim);  // vector spaces: local(a, b) = b - a
}

}  // namespace

LinearMarginal::LinearMarginal(std::vector<Key> keys, const Values& x0, Eigen::MatrixXd A, Eigen::VectorXd d)
    : keys_(std::move(keys)), A_(std::move(A)), d_(std::move(d)) {
  if (keys_.empty()) throw std::invalid_argument("LinearMarginal: no keys");
  int offset = 0;
  for (Key k : keys_) {
    if (!x0.exists(k)) throw std::invalid_argument("LinearMarginal: no linearization point for " + keyString(k));
    x0_.push_back(x0.at(k));
    offsets_.push_back(offset);
    offset += variableDim(x0_.back());
  }
  if (A_.cols() != offset) throw std::invalid_argument("LinearMarginal: A has " + std::to_string(A_.cols()) + " columns, keys need " + std::to_string(offset));
  if (d_.size() != A_.rows()) throw std::invalid_argument("LinearMarginal: d and A have different row counts");
}

void LinearMarginal::evaluate(const Values& x, Eigen::VectorXd& r, Eigen::MatrixXd* J) const {
  Eigen::VectorXd local(A_.cols());
  if (J) J->resize(A_.rows(), A_.cols());
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    const Variable& xi = x.at(keys_[i]);
    const int dim = variableDim(x0_[i]);
    local.segment(offsets_[i], dim) = localVariable(x0_[i], xi);
    if (J) J->middleCols(offsets_[i], dim) = A_.middleCols(offsets_[i], dim) * localJacobian(x0_[i], xi);
  }
  r = A_ * local - d_;
}

double LinearMarginal::error(const Values& x) const {
  Eigen::VectorXd r;
  evaluate(x, r);
  return 0.5 * r.squaredNorm();
}

}  // namespace rilo
