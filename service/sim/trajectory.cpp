#include "sim/trajectory.h"

#include <cmath>

namespace rilo::sim {

KinematicState LissajousWalk::at(double t) const {
  KinematicState s;
  Vec3 pos, vel, acc;
  for (int i = 0; i < 3; ++i) {
    const double w = p_.omega(i), A = p_.amplitude(i), ph = p_.phase(i);
    pos(i) = p_.center(i) + A * std::sin(w * t + ph);
    vel(i) = A * w * std::cos(w * t + ph);
    acc(i) = -A * w * w * std::sin(w * t + ph);
  }
  // ZYX Euler angles and their rates.
  const double yaw = p_.yaw0 + p_.yaw_amp * std::sin(p_.yaw_omega * t);
  const double yaw_d = p_.yaw_amp * p_.yaw_omega * std::cos(p_.yaw_omega * t);
  const double pitch = p_.pitch_amp * std::sin(p_.pitch_omega * t);
  const double pitch_d = p_.pitch_amp * p_.pitch_omega * std::cos(p_.pitch_omega * t);
  const double roll = p_.roll_amp * std::sin(p_.roll_omega * t);
  const double roll_d = p_.roll_amp * p_.roll_omega * std::cos(p_.roll_omega * t);

  const Mat3 R = (Eigen::AngleAxisd(yaw, Vec3::UnitZ()) * Eigen::AngleAxisd(pitch, Vec3::UnitY()) *
                  Eigen::AngleAxisd(roll, Vec3::UnitX()))
                     .toRotationMatrix();
  // Body rates of a ZYX sequence.
  const double sr = std::sin(roll), cr = std::cos(roll), sp = std::sin(pitch), cp = std::cos(pitch);
  s.omega_b = Vec3(roll_d - yaw_d * sp, pitch_d * cr + yaw_d * sr * cp, -pitch_d * sr + yaw_d * cr * cp);
  s.T_w_b = Pose3(R, pos);
  s.v_w = vel;
  s.a_w = acc;
  return s;
}

ImuReading idealImu(const KinematicState& s, double gravity) {
  ImuReading m;
  m.gyro = s.omega_b;
  m.accel = s.T_w_b.R.transpose() * (s.a_w + Vec3(0.0, 0.0, gravity));
  return m;
}

}  // namespace rilo::sim
