#include "estimation/graph/factor.h"

#include <cmath>
#include <stdexcept>

namespace rilo {

Factor::Factor(std::vector<Key> keys, RobustLossPtr loss) : keys_(std::move(keys)), loss_(std::move(loss)) {
  if (keys_.empty() || keys_.size() > static_cast<std::size_t>(kMaxFactorKeys)) {
    throw std::invalid_argument("Factor: needs 1.." + std::to_string(kMaxFactorKeys) + " keys");
  }
}

double Factor::errorOfResidual(const Residual& r) const {
  if (!loss_) return 0.5 * r.squaredNorm();
  if (r.size() == 1) return loss_->loss(r(0));
  if (!loss_->isSymmetric()) throw std::logic_error("Factor: asymmetric loss on a vector residual");
  return loss_->loss(r.norm());
}

double Factor::error(const Values& x) const {
  Residual r;
  evaluate(x, r, nullptr);
  return errorOfResidual(r);
}

double Factor::linearize(const Values& x, Residual& r, Jacobians& H) const {
  evaluate(x, r, &H);
  if (!loss_) return 1.0;
  double w;
  if (r.size() == 1) {
    w = loss_->weight(r(0));
  } else {
    if (!loss_->isSymmetric()) throw std::logic_error("Factor: asymmetric loss on a vector residual");
    w = loss_->weight(r.norm());
  }
  const double sw = std::sqrt(std::max(w, 0.0));
  r *= sw;
  for (std::size_t k = 0; k < keys().size(); ++k) H[k] *= sw;
  return w;
}

double FactorGraph::error(const Values& x) const {
  double e = 0.0;
  for (const auto& f : factors_) e += f->error(x);
  return e;
}

}  // namespace rilo
