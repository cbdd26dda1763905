#pragma once
// Huber loss on a whitened residual: quadratic core, linear tails.
//   rho(r) = r^2 / 2            for |r| <= k
//          = k |r| - k^2 / 2    otherwise,
// weight(r) = min(1, k / |r|). k = 1.345 gives 95 % efficiency on Gaussian data.
#include <string>

#include "estimation/noise/robust_loss.h"

namespace rilo {

class HuberLoss final : public RobustLoss {
 public:
  static constexpr double kDefaultK = 1.345;

  /// k: threshold in whitened units (sigmas); finite and > 0, else std::invalid_argument.
  explicit HuberLoss(double k = kDefaultK);

  double loss(double r) const override;
  double derivative(double r) const override;
  double weight(double r) const override;
  std::string name() const override { return "huber"; }

  double k() const { return k_; }

 private:
  double k_;
};

}  // namespace rilo
