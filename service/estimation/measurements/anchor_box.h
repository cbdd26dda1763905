#pragma once
// The surveyed anchors' horizontal bounding box, and how far a position lies
// beyond it. Beyond the box the ranging geometry fits mirror solutions as
// well as the truth (initializer.h: a start is refused past
// max_outside_anchors_m) or holds nothing at all (localizer.h: tracking ends
// past its own max_outside_anchors_m).
#include <cmath>
#include <limits>
#include <vector>

#include "math/types.h"

namespace rilo {

/// Whether an anchor position is the placeholder of an unused id (hal
/// uwbAnchorsById puts them 1e6 m away): any coordinate this far (>= 1e5 m),
/// or not finite. The anchors' box and the height band's floor check skip them.
template <class V>
bool isAnchorPlaceholder(const V& p_w) {
  return !(std::abs(p_w.x()) < 1e5 && std::abs(p_w.y()) < 1e5 && std::abs(p_w.z()) < 1e5);
}

class AnchorBox {
 public:
  /// Placeholders of unused ids (isAnchorPlaceholder) are left out.
  explicit AnchorBox(const std::vector<Vec3>& p_w_anchors) {
    min_xy_.setConstant(std::numeric_limits<double>::infinity());
    max_xy_.setConstant(-std::numeric_limits<double>::infinity());
    for (const Vec3& a : p_w_anchors) {
      if (isAnchorPlaceholder(a)) continue;
      min_xy_ = min_xy_.cwiseMin(a.head<2>());
      max_xy_ = max_xy_.cwiseMax(a.head<2>());
    }
  }

  /// Horizontal distance (m) of p_w beyond the box: 0 inside, and 0 when no anchor was surveyed.
  double outside(const Vec3& p_w) const {
    if (!(min_xy_.x() <= max_xy_.x())) return 0.0;
    const Eigen::Vector2d below = (min_xy_ - p_w.head<2>()).cwiseMax(0.0);
    const Eigen::Vector2d above = (p_w.head<2>() - max_xy_).cwiseMax(0.0);
    return (below + above).norm();
  }

 private:
  Eigen::Vector2d min_xy_, max_xy_;  ///< box corners (m, world)
};

}  // namespace rilo
