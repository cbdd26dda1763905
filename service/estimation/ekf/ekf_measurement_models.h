#pragma once
// Measurement functions h(x) of the error-state EKF and their Jacobians
// H = dh/d dx in the error chart of ekf_state.h. The models are those of the
// smoother's factors (range_factor.h, tdoa_factor.h, ultrasonic_factor.h):
//   p_w_tag = R_w_b p_b_tag + p_w_b
//   range:       h = |p_w_tag - p_w_anchor|
//   TDoA:        h = |p_w_tag - p_w_anchor_b| - |p_w_tag - p_w_anchor_a|
//   ultrasonic:  h = [ |d_w| ; n^T d_w ],  d_w = p_w_tag - p_w_anchor, n = (0, 0, 1)
// The filter's innovation is y = z - h (z: measured range / difference /
// expected height difference delta_h), so y > 0 <=> measured LONGER than
// predicted, the same sign as the factors' scalar residuals (the NLOS side
// for ranges). (The factors' elevation row is h - delta_h, the opposite sign;
// it is Gaussian in the EKF, so only the range row's sign matters to a loss.)
//
// Only the [dtheta, dp] columns are non-zero: H is returned as M x 6 over
// those (the velocity and bias columns are zero):
//   dp_w_tag = -R_w_b [p_b_tag]x dtheta + dp.
// Near a singular configuration (tag on an anchor) the direction convention
// of rangeAndDirection() (range_factor.h) applies.
#include "estimation/ekf/ekf_state.h"

namespace rilo {

/// h (M x 1) and H over [dtheta, dp] (M x 6).
template <int M>
struct EkfPrediction {
  Eigen::Matrix<double, M, 1> h;
  Eigen::Matrix<double, M, 6> H;
};

/// Two-way range from the tag antenna (lever arm p_b_tag) to the anchor (m).
EkfPrediction<1> predictRange(const EkfState& x, const Vec3& p_w_anchor, const Vec3& p_b_tag);
/// Range difference |tag - B| - |tag - A| (m).
EkfPrediction<1> predictTdoa(const EkfState& x, const Vec3& p_w_anchor_a, const Vec3& p_w_anchor_b,
                             const Vec3& p_b_tag);
/// Ultrasonic receiver (lever arm p_b_us): [range (m); height above the anchor n^T d_w (m)].
EkfPrediction<2> predictUltrasonic(const EkfState& x, const Vec3& p_w_anchor, const Vec3& p_b_us);

}  // namespace rilo
