#pragma once
// A loss counted at a fraction of its weight: rho_w(r) = w rho(r), so the
// factor's information is w times the inner loss's while its shape, and the
// branch an asymmetric mixture takes at r, stay the inner loss's. Used where
// several measurements share one error and together count as one
// (range_repeats.h): each of k gets w = 1 / k.
#include <string>

#include "estimation/noise/robust_loss.h"

namespace rilo {

class WeightedLoss final : public RobustLoss {
 public:
  /// Throws std::invalid_argument for a null inner loss or w outside (0, 1].
  WeightedLoss(RobustLossPtr inner, double w);

  double loss(double r) const override { return w_ * inner_->loss(r); }
  double derivative(double r) const override { return w_ * inner_->derivative(r); }
  double weight(double r) const override { return w_ * inner_->weight(r); }
  bool isSymmetric() const override { return inner_->isSymmetric(); }
  std::string name() const override;

  double w() const { return w_; }
  const RobustLossPtr& inner() const { return inner_; }

 private:
  RobustLossPtr inner_;
  double w_;
};

}  // namespace rilo
