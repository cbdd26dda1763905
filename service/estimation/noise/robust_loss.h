#pragma once
// Robust loss on a whitened residual r (unitless, r = sqrt_info * e).
//
// Conventions every loss follows (tested in tests/core/noise_test.cpp):
// - rho(0) = 0 and rho(r) = r^2 / 2 + O(r^3) near 0 (the Gaussian core);
// - rho is continuous and non-decreasing in |r| on each side of 0;
// - weight(r) = rho'(r) / r (IRLS weight), its limit 1 at r = 0, always >= 0.
// One exception by design: WeightedLoss (weighted_loss.h) is w times a loss
// that follows them (rho ~ w r^2 / 2, weight w at 0).
// Scalar factors pass the *signed* residual; the sign convention of range-like
// factors is r > 0 <=> measured longer than predicted (the NLOS side), so
// asymmetric losses see the sign both when weighting and when the smoother
// evaluates the nonlinear error for step acceptance.
#include <memory>
#include <string>

namespace rilo {

class RobustLoss {
 public:
  virtual ~RobustLoss() = default;
  /// rho(r): negative log-likelihood up to a constant, rho(0) = 0.
  virtual double loss(double r) const = 0;
  /// rho'(r).
  virtual double derivative(double r) const = 0;
  /// IRLS weight rho'(r)/r, with its limit at r = 0.
  virtual double weight(double r) const;
  /// False for losses that treat r and -r differently (they need scalar residuals).
  virtual bool isSymmetric() const { return true; }
  virtual std::string name() const = 0;
};

using RobustLossPtr = std::shared_ptr<const RobustLoss>;

}  // namespace rilo
