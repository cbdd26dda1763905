#pragma once
// A smooth analytic body motion with exact derivatives for the runtime tests
// (the simulator library is not linked into rilo_test_runtime): position is a
// sum of sinusoids, orientation R = Rz(yaw) Ry(pitch) Rx(roll) with sinusoidal
// angles, so the body rate and the ideal IMU reading are closed-form.
#include <cmath>
#include <cstdint>

#include "math/types.h"
#include "runtime/navigation_state.h"
#include "sensors/samples.h"

namespace rilo::testing {

struct MotionPoint {
  Mat3 R_w_b;
  Vec3 p_w;      ///< m
  Vec3 v_w;      ///< m/s
  Vec3 a_w;      ///< m/s^2
  Vec3 omega_b;  ///< rad/s
};

inline Mat3 rotX(double a) { return Eigen::AngleAxisd(a, Vec3::UnitX()).toRotationMatrix(); }
inline Mat3 rotY(double a) { return Eigen::AngleAxisd(a, Vec3::UnitY()).toRotationMatrix(); }
inline Mat3 rotZ(double a) { return Eigen::AngleAxisd(a, Vec3::UnitZ()).toRotationMatrix(); }

/// Walking-like motion: ~1 m/s, 0.5 rad/s turns, small roll/pitch, vertical bob.
inline MotionPoint motionAt(double t) {
  struct Sine {  // a sin(w t + phi) and its first two derivatives
    double a, w, phi;
    double x(double s) const { return a * std::sin(w * s + phi); }
    double dx(double s) const { return a * w * std::cos(w * s + phi); }
    double ddx(double s) const { return -a * w * w * std::sin(w * s + phi); }
  };
  const Sine px{3.0, 0.35, 0.0}, py{2.0, 0.5, 0.7}, pz{0.05, 1.9, 0.0};
  const Sine yaw{1.0, 0.45, 0.3}, pitch{0.06, 1.3, 0.2}, roll{0.08, 1.7, 0.0};
  MotionPoint m;
  m.p_w = Vec3(px.x(t), py.x(t), 1.2 + pz.x(t));
  m.v_w = Vec3(px.dx(t), py.dx(t), pz.dx(t));
  m.a_w = Vec3(px.ddx(t), py.ddx(t), pz.ddx(t));
  const Mat3 Rz = rotZ(yaw.x(t)), Ry = rotY(pitch.x(t)), Rx = rotX(roll.x(t));
  m.R_w_b = Rz * Ry * Rx;
  // R^T dR/dt = hat(omega_b) with omega_b = yaw' (Ry Rx)^T e_z + pitch' Rx^T e_y + roll' e_x.
  m.omega_b = yaw.dx(t) * (Ry * Rx).transpose() * Vec3::UnitZ() + pitch.dx(t) * Rx.transpose() * Vec3::UnitY() +
              roll.dx(t) * Vec3::UnitX();
  return m;
}

inline double toSeconds(std::int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }

/// Ideal IMU at t_ns plus constant biases: gyro = omega_b + b_g,
/// accel = R^T (a_w - g_w) + b_a with g_w = (0, 0, -g).
inline ImuSample idealImuAt(std::int64_t t_ns, double gravity = 9.81, const Vec3& accel_bias = Vec3::Zero(),
                            const Vec3& gyro_bias = Vec3::Zero()) {
  const MotionPoint m = motionAt(toSeconds(t_ns));
  ImuSample s;
  s.t_ns = t_ns;
  s.gyro_rad_s = m.omega_b + gyro_bias;
  s.accel_m_s2 = m.R_w_b.transpose() * (m.a_w - Vec3(0.0, 0.0, -gravity)) + accel_bias;
  return s;
}

/// The true navigation state at t_ns (valid, with the given bias estimates).
inline NavigationState truthAt(std::int64_t t_ns, const Vec3& accel_bias = Vec3::Zero(),
                               const Vec3& gyro_bias = Vec3::Zero()) {
  const MotionPoint m = motionAt(toSeconds(t_ns));
  NavigationState s;
  s.t_ns = t_ns;
  s.q_w_b = Quat(m.R_w_b);
  s.p_w_b = m.p_w;
  s.v_w_b = m.v_w;
  s.omega_b = m.omega_b;
  s.accel_bias_m_s2 = accel_bias;
  s.gyro_bias_rad_s = gyro_bias;
  s.pose_covariance = Mat6::Identity() * 1e-4;
  s.twist_covariance = Mat6::Identity() * 1e-3;
  s.valid = true;
  return s;
}

}  // namespace rilo::testing
