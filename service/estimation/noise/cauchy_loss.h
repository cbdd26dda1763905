#pragma once
// Cauchy (Lorentzian) loss on a whitened residual: the negative log of a
// Student-t with one degree of freedom, scaled so the core is r^2 / 2.
//   rho(r) = c^2 / 2 * log(1 + (r / c)^2),  weight(r) = 1 / (1 + (r / c)^2).
// c = 2.3849 gives 95 % efficiency on Gaussian data.
#include <string>

#include "estimation/noise/robust_loss.h"

namespace rilo {

class CauchyLoss final : public RobustLoss {
 public:
  static constexpr double kDefaultC = 2.3849;

  /// c: scale in whitened units (sigmas); finite and > 0, else std::invalid_argument.
  explicit CauchyLoss(double c = kDefaultC);

  double loss(double r) const override;
  double derivative(double r) const override;
  double weight(double r) const override;
  std::string name() const override { return "cauchy"; }

  double c() const { return c_; }

 private:
  double c_;
  double inv_c2_;  ///< 1 / c^2
};

}  // namespace rilo
