#pragma once
// What the sliding-window smoother's update (sliding_window_smoother.cpp) and
// its marginalization (sliding_window_marginalization.cpp) share. Not an
// interface: only those two files include it.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <tuple>

#include <Eigen/Core>

#include "estimation/graph/factor.h"
#include "estimation/graph/values.h"

namespace rilo::sliding_window_detail {

// Callers that never drain must not grow memory without bound.
inline constexpr std::size_t kMaxUndrainedMarginalized = 100'000;
/// lambda below this fraction of max(diag(J^T J)): the step is Gauss-Newton's,
/// so a small step or change means convergence (at a large lambda every step is small).
inline constexpr double kNegligibleDamping = 1e-6;

using BlockProduct = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxVarDim, kMaxVarDim>;
using BlockVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxVarDim, 1>;

/// sqrt of the IRLS weight of Factor::linearize at an (unweighted) residual.
inline double sqrtWeight(const Factor& f, const Residual& r) {
  const RobustLoss* loss = f.loss();
  if (!loss) return 1.0;
  const double w = r.size() == 1 ? loss->weight(r(0)) : loss->weight(r.norm());
  return std::sqrt(std::max(w, 0.0));
}

/// Factor::linearize (IRLS: r and H scaled by sqrt(w)) and Factor::error of
/// the same evaluation, so the error costs no second pass.
inline void linearizeFactor(const Factor& f, const Values& x, Residual& r, Jacobians& H, double& error) {
  f.evaluate(x, r, &H);
  error = f.errorOfResidual(r);  // throws for an asymmetric loss on a vector residual, as linearize() does
  if (!f.loss()) return;
  const double sw = sqrtWeight(f, r);
  r *= sw;
  for (std::size_t k = 0; k < f.keys().size(); ++k) H[k] *= sw;
}

/// Elimination order: timed variables by time (the IMU chain stays a band),
/// untimed ones (anchors) last (a border): no fill outside band and border.
struct OrderKey {
  bool untimed;
  std::int64_t t_ns;
  Key key;
  bool operator<(const OrderKey& o) const { return std::tie(untimed, t_ns, key) < std::tie(o.untimed, o.t_ns, o.key); }
};

}  // namespace rilo::sliding_window_detail
