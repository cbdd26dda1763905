#include "estimation/noise/huber_loss.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rilo {

HuberLoss::HuberLoss(double k) : k_(k) {
  if (!std::isfinite(k) || k <= 0.0) {
    throw std::invalid_argument("HuberLoss: k must be finite and > 0 (got " + std::to_string(k) + ")");
  }
}

double HuberLoss::loss(double r) const {
  const double a = std::abs(r);
  return a <= k_ ? 0.5 * r * r : k_ * (a - 0.5 * k_);
}

double HuberLoss::derivative(double r) const { return std::clamp(r, -k_, k_); }

double HuberLoss::weight(double r) const {
  const double a = std::abs(r);
  return a <= k_ ? 1.0 : k_ / a;
}

}  // namespace rilo
