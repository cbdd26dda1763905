#pragma once
// Smooth analytic trajectories with exact derivatives, so that IMU
// measurements can be generated without numerical differentiation and
// preintegration can be checked against the exact motion.
#include "math/pose3.h"

namespace rilo::sim {

struct KinematicState {
  Pose3 T_w_b;    ///< pose world-from-body
  Vec3 v_w;       ///< velocity in world (m/s)
  Vec3 a_w;       ///< acceleration in world (m/s^2)
  Vec3 omega_b;   ///< angular velocity in body (rad/s)
};

class Trajectory {
 public:
  virtual ~Trajectory() = default;
  virtual KinematicState at(double t_s) const = 0;
};

/// A walking-like motion: Lissajous path in the horizontal plane around
/// `center`, gentle height bob, heading swinging with the path, small roll and
/// pitch oscillations. All components are sinusoids: derivatives are exact.
class LissajousWalk final : public Trajectory {
 public:
  struct Params {
    Vec3 center{0.0, 0.0, 1.2};
    Vec3 amplitude{4.0, 3.0, 0.05};    ///< m
    Vec3 omega{0.25, 0.35, 1.8};       ///< rad/s per axis
    Vec3 phase{0.0, 0.7, 0.0};         ///< rad
    double yaw0 = 0.3, yaw_amp = 1.2, yaw_omega = 0.3;   ///< rad, rad, rad/s
    double roll_amp = 0.08, roll_omega = 1.7;            ///< rad, rad/s
    double pitch_amp = 0.06, pitch_omega = 1.3;          ///< rad, rad/s
  };
  LissajousWalk() : LissajousWalk(Params{}) {}
  explicit LissajousWalk(const Params& p) : p_(p) {}
  KinematicState at(double t_s) const override;

 private:
  Params p_;
};

/// Ideal IMU reading of a kinematic state: gyro = omega_b, accel = specific
/// force R^T (a_w - g_w) with g_w = (0, 0, -gravity).
struct ImuReading {
  Vec3 gyro;   ///< rad/s
  Vec3 accel;  ///< m/s^2
};
ImuReading idealImu(const KinematicState& s, double gravity = 9.81);

}  // namespace rilo::sim
