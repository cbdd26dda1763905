#pragma once
// Strapdown integration of raw IMU samples from a reference time t_r, in the
// body frame at t_r, with first-order bias Jacobians (Forster et al., TRO
// 2017, rotation-matrix form). Unlike PreintegratedImu's tangent chart it has
// no 2 pi limit, so one integration spans a whole initialization window
// (tens of seconds with turns). The initializer evaluates the motion model
//   R(t) = R_r dR(t)
//   v(t) = v_r + g_w dt + R_r dv(t)
//   p(t) = p_r + v_r dt + g_w dt^2 / 2 + R_r dp(t)        (dt = t - t_r)
// for many hypotheses of (R_r, p_r, v_r, bias) at the same times, so the
// integration is done once and the bias enters through the Jacobians.
// Samples are held constant until the next one (zero-order hold, as the
// preintegration), and a query time between two samples splits the hold.
#include <cstdint>
#include <span>
#include <vector>

#include "math/imu_bias.h"
#include "math/pose3.h"
#include "sensors/samples.h"

namespace rilo {

/// The integrated motion from t_r to one query time, for zero bias.
struct StrapdownDelta {
  std::int64_t t_ns = 0;  ///< query time
  double dt_s = 0.0;      ///< t_ns - t_r (s)
  Mat3 dR = Mat3::Identity();  ///< R_r^T R(t)
  Vec3 dv = Vec3::Zero();      ///< m/s, frame of t_r (gravity not removed: specific force integrated)
  Vec3 dp = Vec3::Zero();      ///< m, frame of t_r
  Mat3 dR_dbg = Mat3::Zero();  ///< dR(b) ~= dR Exp(dR_dbg b_g) (rad per rad/s)
  Mat3 dv_dba = Mat3::Zero(), dv_dbg = Mat3::Zero();
  Mat3 dp_dba = Mat3::Zero(), dp_dbg = Mat3::Zero();

  struct Corrected {
    Mat3 dR;
    Vec3 dv, dp;
  };
  /// Deltas for bias b (first order in b).
  Corrected corrected(const ImuBias& b) const;
};

/// Navigation state at a query time from the state at t_r (world gravity (0, 0, -g)).
struct StrapdownState {
  Pose3 T_w_b;
  Vec3 v_w = Vec3::Zero();
};
StrapdownState propagate(const StrapdownDelta& d, const Pose3& T_w_r, const Vec3& v_w_r, const ImuBias& b,
                         double gravity_m_s2);

/// Integrates `imu` (strictly increasing times) from t_ref_ns to every time in
/// `query_t_ns` (ascending, each >= t_ref_ns) and returns one delta per query.
/// The sample in effect at a time is the last one at or before it; before the
/// first sample the first one is held, after the last one the last is held.
/// Returns an empty vector when `imu` is empty.
std::vector<StrapdownDelta> integrateStrapdown(std::span<const ImuSample> imu, std::int64_t t_ref_ns,
                                               const std::vector<std::int64_t>& query_t_ns);

}  // namespace rilo
