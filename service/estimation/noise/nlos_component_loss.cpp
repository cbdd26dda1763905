#include "estimation/noise/nlos_component_loss.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

/// The prior weight is irrelevant here (only the density is used); any valid one.
constexpr double kUnusedWeight = 0.25;

}  // namespace

NlosComponentLoss::NlosComponentLoss(double gamma) : density_(gamma, kUnusedWeight) {
  if (!(gamma <= kMaxGamma)) {
    throw std::invalid_argument("NlosComponentLoss: gamma (NLOS scale / LOS sigma) must be <= " +
                                std::to_string(kMaxGamma) + ", got " + std::to_string(gamma) +
                                " (or turn the NLOS indicator off: nlos_power_gap_db = inf)");
  }
  // The mode: d(-log g)/deps changes sign once (g is unimodal). It is < 0 at
  // 0 (the half-Cauchy mass lies at c > 0) and > 0 far out.
  const auto slope = [this](double eps) {
    double d = 0.0;
    density_.nlosNegLogDensity(eps, &d);
    return d;
  };
  double lo = -1.0, hi = 1.0;
  while (slope(lo) > 0.0) lo *= 2.0;
  while (slope(hi) < 0.0) {
    hi *= 2.0;
    if (hi > AsymmetricLoss::kTableMaxEps) throw std::logic_error("NlosComponentLoss: no mode found");
  }
  for (int i = 0; i < 200 && hi - lo > 1e-12; ++i) {
    const double mid = 0.5 * (lo + hi);
    (slope(mid) < 0.0 ? lo : hi) = mid;
  }
  eps_m_ = 0.5 * (lo + hi);
  neg_log_mode_ = density_.nlosNegLogDensity(eps_m_, nullptr);
  slope_at_mode_ = slope(eps_m_);  // ~1e-13 from the bisection: removed so that rho'(0) = 0 exactly
  // Curvature at the mode by a central difference of the (C1, piecewise
  // cubic) slope; h well above the table's node spacing near the mode.
  const double h = 1e-3;
  const double kappa = (slope(eps_m_ + h) - slope(eps_m_ - h)) / (2.0 * h);
  if (!(kappa > 0.0) || !std::isfinite(kappa)) throw std::logic_error("NlosComponentLoss: not curved at its mode");
  scale_ = 1.0 / std::sqrt(kappa);
}

double NlosComponentLoss::loss(double r) const {
  return density_.nlosNegLogDensity(eps_m_ + scale_ * r, nullptr) - neg_log_mode_;
}

double NlosComponentLoss::derivative(double r) const {
  double d = 0.0;
  density_.nlosNegLogDensity(eps_m_ + scale_ * r, &d);
  return scale_ * (d - slope_at_mode_);
}

double NlosComponentLoss::weight(double r) const {
  // Limit 1 at r = 0 by the choice of scale_; a small band avoids 0/0.
  if (std::abs(r) < 1e-6) return 1.0;
  return std::max(0.0, derivative(r) / r);
}

}  // namespace rilo
