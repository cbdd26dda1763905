#include "estimation/ekf/ekf_propagation.h"

namespace rilo {

EkfState integrateImuMidpoint(const EkfState& x, const ImuInterval& m, const Vec3& g_w, const Vec6& bias_transition,
                              Mat15* F_x1_x0) {
  using namespace ekf_index;
  const double dt = m.dt_s;
  const Vec3 w0 = m.gyro0_rad_s - x.bias.gyro;
  const Vec3 w1 = m.gyro1_rad_s - x.bias.gyro;
  const Vec3 a0 = m.accel0_m_s2 - x.bias.accel;
  const Vec3 a1 = m.accel1_m_s2 - x.bias.accel;
  const Vec3 phi = 0.5 * (w0 + w1) * dt;
  const Mat3 dR = so3::exp(phi);
  const Mat3& R0 = x.R_w_b;
  const Mat3 R1 = R0 * dR;
  const Vec3 a_bar = 0.5 * (R0 * a0 + R1 * a1) + g_w;

  EkfState out;
  out.R_w_b = R1;
  out.p_w_b = x.p_w_b + x.v_w * dt + 0.5 * dt * dt * a_bar;
  out.v_w = x.v_w + a_bar * dt;
  out.bias = ImuBias(bias_transition.head<3>().cwiseProduct(x.bias.accel),
                     bias_transition.tail<3>().cwiseProduct(x.bias.gyro));

  if (F_x1_x0 != nullptr) {
    Mat15& F = *F_x1_x0;
    F.setZero();
    const Mat3 Jr_dt = so3::rightJacobian(phi) * dt;
    const Mat3 R1_a1x = R1 * so3::hat(a1);
    const Mat3 A_theta = -0.5 * (R0 * so3::hat(a0) + R1_a1x * dR.transpose());
    const Mat3 A_ba = -0.5 * (R0 + R1);
    const Mat3 A_bg = 0.5 * R1_a1x * Jr_dt;
    const double half_dt2 = 0.5 * dt * dt;

    F.block<3, 3>(kTheta, kTheta) = dR.transpose();
    F.block<3, 3>(kTheta, kGyroBias) = -Jr_dt;

    F.block<3, 3>(kPos, kTheta) = half_dt2 * A_theta;
    F.block<3, 3>(kPos, kPos).setIdentity();
    F.block<3, 3>(kPos, kVel) = dt * Mat3::Identity();
    F.block<3, 3>(kPos, kAccelBias) = half_dt2 * A_ba;
    F.block<3, 3>(kPos, kGyroBias) = half_dt2 * A_bg;

    F.block<3, 3>(kVel, kTheta) = dt * A_theta;
    F.block<3, 3>(kVel, kVel).setIdentity();
    F.block<3, 3>(kVel, kAccelBias) = dt * A_ba;
    F.block<3, 3>(kVel, kGyroBias) = dt * A_bg;

    F.block<3, 3>(kAccelBias, kAccelBias) = bias_transition.head<3>().asDiagonal();
    F.block<3, 3>(kGyroBias, kGyroBias) = bias_transition.tail<3>().asDiagonal();
  }
  return out;
}

}  // namespace rilo
