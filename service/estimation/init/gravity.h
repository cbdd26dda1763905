#pragma once
// Roll and pitch from the accelerometer: the mean specific force over an
// interval, each sample rotated into the body frame at the interval's start
// by the integrated gyro (so rotation during the interval does not blur it).
// Over a still interval that mean is gravity (up to the accelerometer bias,
// ~0.2 deg per 0.03 m/s^2). While moving it is R_w_b^T (g e_z + dv_w / T):
// the motion averages out over a long window (T = 10 s and a speed change of
// 1.5 m/s leave ~0.9 deg), and the tilt uncertainty handed to the later
// solvers says so. Yaw is not observable from gravity (left at 0 here).
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "math/pose3.h"
#include "sensors/samples.h"

namespace rilo {

struct GravityParams {
  double still_min_s = 0.5;            ///< a still interval shorter than this is not used (s)
  double still_block_s = 0.25;         ///< still detection works on blocks of this length (s)
  double still_accel_std_m_s2 = 0.1;   ///< per-axis accelerometer std-dev below this in a still block
  double still_gyro_rad_s = 0.03;      ///< mean |gyro| below this in a still block (rad/s)
  double max_speed_change_m_s = 1.5;   ///< moving: assumed bound of |dv_w| over the interval (tilt sigma)
  double min_tilt_sigma_rad = 0.01;    ///< floor of the reported tilt uncertainty (rad)
  double gravity_tolerance_m_s2 = 1.5; ///< |mean specific force| must be within g +- this

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

struct GravityAlignment {
  bool valid = false;
  std::string message;             ///< how it was obtained, or why it failed
  bool still = false;              ///< from a still interval at the start (else the whole window)
  double interval_s = 0.0;         ///< length of the averaged interval (s)
  Vec3 up_b = Vec3::UnitZ();       ///< world "up" in the body frame at t_ref: R_w_b^T e_z
  Mat3 R_w_b = Mat3::Identity();   ///< roll and pitch from gravity, yaw 0 (ZYX)
  double tilt_sigma_rad = 0.0;     ///< uncertainty of roll/pitch (rad, 1 sigma)
  double mean_specific_force_m_s2 = 0.0;  ///< |mean specific force| over the interval
  double accel_std_m_s2 = 0.0;     ///< largest per-axis accelerometer std-dev over the first block
};

/// Gravity direction at t_ref_ns from the samples of [t_ref_ns, t_end_ns].
/// Never throws on data: an empty or useless interval gives valid == false.
GravityAlignment alignGravity(std::span<const ImuSample> imu, std::int64_t t_ref_ns, std::int64_t t_end_ns,
                              double gravity_m_s2, const GravityParams& params = {});

/// A still interval [t0_ns, t1_ns): consecutive still blocks (accelerometer
/// std-dev and mean |gyro| below the GravityParams thresholds), at least
/// still_min_s long.
struct StillInterval {
  std::int64_t t0_ns = 0, t1_ns = 0;
};
/// Still intervals of [t0_ns, t1_ns), in time order. A body-worn device is
/// never this quiet while it moves (gait shakes the accelerometer, turns show
/// in the gyro); a device gliding without rotation at constant velocity
/// would be taken for still.
std::vector<StillInterval> findStillIntervals(std::span<const ImuSample> imu, std::int64_t t0_ns, std::int64_t t1_ns,
                                              const GravityParams& params = {});

/// Yaw (rad) of a rotation in the ZYX convention: atan2(R(1,0), R(0,0)).
double yawOf(const Mat3& R_w_b);
/// Rotation about world z by yaw_rad.
Mat3 yawRotation(double yaw_rad);

}  // namespace rilo
