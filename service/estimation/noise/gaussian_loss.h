#pragma once
// Plain least squares on a whitened residual: rho(r) = r^2 / 2, weight 1.
// Header-only: the smoother treats it like any other RobustLoss so the range
// factor can switch models from the configuration without special cases.
#include <string>

#include "estimation/noise/robust_loss.h"

namespace rilo {

class GaussianLoss final : public RobustLoss {
 public:
  double loss(double r) const override { return 0.5 * r * r; }
  double derivative(double r) const override { return r; }
  double weight(double /*r*/) const override { return 1.0; }
  std::string name() const override { return "gaussian"; }
};

}  // namespace rilo
