#pragma once
// The robust loss of the initializer's small solvers (multilateration, coarse
// alignment) on a whitened range residual r = (measured - predicted) / sigma.
// Positive residuals (measured too long: the NLOS side) use the estimator's
// configured range loss (by default the Ranging-IMU Fusion paper's asymmetric one, which gives
// them a heavy tail); negative residuals use Huber, because far from the
// solution (a start on the wrong side of the anchors, a rare early first
// path) a purely Gaussian short side would let one range drag the fix.
#include <algorithm>
#include <cmath>

#include "estimation/noise/robust_loss.h"

namespace rilo {

struct InitRangeLoss {
  RobustLossPtr long_side;  ///< loss for r > 0 (must not be null)
  double short_side_k = 3.0;  ///< Huber threshold for r < 0 (sigmas)

  double rho(double r) const {
    if (r > 0.0) return long_side->loss(r);
    const double a = -r;
    return a <= short_side_k ? 0.5 * a * a : short_side_k * a - 0.5 * short_side_k * short_side_k;
  }
  /// IRLS weight rho'(r) / r (>= 0).
  double weight(double r) const {
    if (r > 0.0) return long_side->weight(r);
    return std::min(1.0, short_side_k / std::max(-r, 1e-300));
  }
};

}  // namespace rilo
