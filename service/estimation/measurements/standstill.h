#pragma once
// Standstill of the tracked device from the IMU alone, causally: the samples
// of a trailing window are still when every accelerometer axis varies less
// than a walking body allows (gait shakes a body-worn accelerometer by
// 0.3 m/s^2 and more; a resting one shows its noise and some postural sway).
// What it is for: a wearer who stops has zero velocity, which the IMU factor
// alone does not know; the tracked states then get a zero-velocity prior
// like the initializer's batch (RangeImuGraphParams::zero_velocity_sigma_m_s).
//
// Rotation does not count against a standstill by default: a wearer turning
// on the spot keeps the body still (the sims turn at up to 1.5 rad/s at their
// stops, with an accelerometer std-dev below 0.07 m/s^2), and the prior is on
// velocity only. gyro_rad_s adds the initializer's turn test where wanted.
// Still by this test, although moving: a device gliding at constant velocity
// (a lift, a vehicle, a smooth synthetic trajectory without gait). The users
// of the test therefore also ask the estimate: a state already moving faster
// than max_speed_m_s is not taken as stopped (stillFor). Turn the prior off
// where such glides are the rule.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "estimation/measurements/growing_ring.h"
#include "math/types.h"
#include "sensors/samples.h"

namespace rilo {

struct StandstillParams {
  double window_s = 0.5;              ///< trailing window a standstill must fill (s), > 0
  double accel_std_m_s2 = 0.1;        ///< per-axis accelerometer std-dev below this
  /// Mean |gyro| below this as well (rad/s; the bias counts in it); +inf: no
  /// turn test (the default, see above).
  double gyro_rad_s = std::numeric_limits<double>::infinity();
  /// The estimated speed at the interval's start must be below this (m/s,
  /// > 0): a glide keeps its speed, a stop does not. Not lower: the estimate
  /// can drift past 0.5 m/s at stops (measured: docs/noise-models.md,
  /// "Standstill: a zero-velocity prior (session 21)"). +inf: the IMU alone decides.
  double max_speed_m_s = 1.0;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// The zero-velocity prior's std-dev on a state closing a still interval of
/// dt_ns, for sigma_m_s per second of standstill: sigma * sqrt(1 s / dt) (dt
/// at least 1 ms), the same weight per second at any state rate. The graph
/// stream and the EKF baseline both use it, so their priors agree.
inline double standstillPriorSigma(double sigma_m_s, std::int64_t dt_ns) {
  const double dt_s = std::max(1e-3, static_cast<double>(dt_ns) * 1e-9);
  return sigma_m_s * std::sqrt(1.0 / dt_s);
}

class StandstillDetector {
 public:
  explicit StandstillDetector(StandstillParams params = {}, std::size_t initial_capacity = 1024);

  /// Samples in time order (the caller checks the order).
  void add(const ImuSample& sample);
  /// Whether the device was still over [min(t_from_ns, t_to_ns - window), t_to_ns]:
  /// the samples there (which must reach back over 90 % of it) pass the test.
  bool stillOver(std::int64_t t_from_ns, std::int64_t t_to_ns) const;
  /// stillOver(), and the estimated velocity at t_from_ns is slow enough
  /// (max_speed_m_s) to be a stop rather than a glide.
  bool stillFor(std::int64_t t_from_ns, std::int64_t t_to_ns, const Vec3& v_w_from) const {
    return v_w_from.norm() < params_.max_speed_m_s && stillOver(t_from_ns, t_to_ns);
  }
  /// Forgets what no later stillOver(t >= t_ns, ...) can need.
  void dropBefore(std::int64_t t_ns);

  const StandstillParams& params() const { return params_; }
  std::size_t size() const { return samples_.size(); }

 private:
  StandstillParams params_;
  std::int64_t window_ns_;
  detail::GrowingRing<ImuSample> samples_;
};

}  // namespace rilo
