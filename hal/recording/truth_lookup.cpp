#include "hal/recording/truth_lookup.h"

#include <algorithm>

namespace rilo {

bool TruthLookup::at(std::int64_t t_ns, Mat3& R_w_b, Vec3& p_w_b) const {
  if (truth_.empty()) return false;
  const auto later = std::upper_bound(truth_.begin(), truth_.end(), t_ns,
                                      [](std::int64_t t, const GroundTruthPose& g) { return t < g.t_ns; });
  if (later == truth_.begin()) return false;
  const GroundTruthPose& g0 = *(later - 1);
  if (g0.t_ns == t_ns) {
    R_w_b = g0.q_w_b.normalized().toRotationMatrix();
    p_w_b = g0.p_w_b;
    return true;
  }
  if (later == truth_.end()) return false;
  const GroundTruthPose& g1 = *later;
  const std::int64_t gap_ns = g1.t_ns - g0.t_ns;
  if (gap_ns > max_gap_ns_) return false;
  const double s = static_cast<double>(t_ns - g0.t_ns) / static_cast<double>(gap_ns);
  p_w_b = (1.0 - s) * g0.p_w_b + s * g1.p_w_b;
  R_w_b = g0.q_w_b.normalized().slerp(s, g1.q_w_b.normalized()).toRotationMatrix();
  return true;
}

}  // namespace rilo
