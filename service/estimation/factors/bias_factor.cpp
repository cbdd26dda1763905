#include "estimation/factors/bias_factor.h"

#include <cmath>
#include <stdexcept>

namespace rilo {

BiasGaussMarkovFactor::BiasGaussMarkovFactor(Key bias_i, Key bias_j, double dt_s, const ImuParams& params)
    : Factor({bias_i, bias_j}), dt_s_(dt_s) {
  if (!(std::isfinite(dt_s) && dt_s > 0.0)) {
    throw std::invalid_argument("BiasGaussMarkovFactor: dt_s must be finite and > 0, got " + std::to_string(dt_s));
  }
  params.validate();
  phi_ = params.biasTransition(dt_s);
  sigma_ = params.biasDiscreteVariance(dt_s).cwiseSqrt();
  inv_sigma_ = sigma_.cwiseInverse();
}

void BiasGaussMarkovFactor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  const Vec6 b_i = x.bias(keys()[0]).vector();
  const Vec6 b_j = x.bias(keys()[1]).vector();
  r = inv_sigma_.cwiseProduct(b_j - phi_.cwiseProduct(b_i));
  if (!H) return;
  (*H)[0].setZero(6, 6);
  (*H)[0].diagonal() = -inv_sigma_.cwiseProduct(phi_);
  (*H)[1].setZero(6, 6);
  (*H)[1].diagonal() = inv_sigma_;
}

}  // namespace rilo
