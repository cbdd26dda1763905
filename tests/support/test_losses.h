#pragma once
// Robust losses used only by tests, kept independent of estimation/noise so a
// factor test checks the loss plumbing, not a particular production loss.
#include <string>

#include "estimation/noise/robust_loss.h"

namespace rilo::testing {

/// Quadratic on both sides with a flatter positive (NLOS) side: sees the sign.
class TestAsymmetric final : public RobustLoss {
 public:
  double loss(double r) const override { return r > 0 ? 0.125 * r * r : 0.5 * r * r; }
  double derivative(double r) const override { return r > 0 ? 0.25 * r : r; }
  bool isSymmetric() const override { return false; }
  std::string name() const override { return "test_asymmetric"; }
};

}  // namespace rilo::testing
