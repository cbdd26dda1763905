#include "estimation/noise/robust_loss.h"

#include <cmath>

namespace rilo {

double RobustLoss::weight(double r) const {
  // Every loss behaves as r^2/2 at the origin, so the weight tends to 1 there.
  if (std::abs(r) < 1e-9) return 1.0;
  return derivative(r) / r;
}

}  // namespace rilo
