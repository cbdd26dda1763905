#include "estimation/noise/cauchy_loss.h"

#include <cmath>
#include <stdexcept>

namespace rilo {

CauchyLoss::CauchyLoss(double c) : c_(c), inv_c2_(1.0 / (c * c)) {
  if (!std::isfinite(c) || c <= 0.0) {
    throw std::invalid_argument("CauchyLoss: c must be finite and > 0 (got " + std::to_string(c) + ")");
  }
}

double CauchyLoss::loss(double r) const { return 0.5 * c_ * c_ * std::log1p(r * r * inv_c2_); }

double CauchyLoss::derivative(double r) const { return r * weight(r); }

double CauchyLoss::weight(double r) const { return 1.0 / (1.0 + r * r * inv_c2_); }

}  // namespace rilo
