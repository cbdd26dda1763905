#pragma once
// Where the tag's body is when a range (two-way, TDoA row or ultrasonic) is
// measured dt after its state: the state's velocity carries it on (the
// factors' RangeTimeOffset, the same model). One definition for every place
// that predicts a state's later measurements outside the factors (dynamic
// covariance, TDoA gap excess, range consistency, the ranges topic), so they
// judge what the smoother fits.
#include <cstdint>

#include "math/pose3.h"
#include "math/types.h"

namespace rilo {

/// T_w_b moved by v_w over range_t_ns - state_t_ns (rotation kept).
inline Pose3 poseAtRangeTime(const Pose3& T_w_b, const Vec3& v_w, std::int64_t state_t_ns, std::int64_t range_t_ns) {
  Pose3 T_w_b_at_range = T_w_b;
  T_w_b_at_range.p += 1e-9 * static_cast<double>(range_t_ns - state_t_ns) * v_w;
  return T_w_b_at_range;
}

}  // namespace rilo
