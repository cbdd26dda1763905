#pragma once
// One IMU step of the error-state EKF: the nominal midpoint integration and
// its exact error-state Jacobian F (the discrete transition of dx).
//
// The interval [t0, t1], dt = t1 - t0, has the IMU samples (w0, a0) at t0 and
// (w1, a1) at t1 (bias-corrected with the nominal bias: w = w_m - b_g,
// a = a_m - b_a). Midpoint (trapezoidal) rule, as in VINS-Mono:
//   w_bar = (w0 + w1) / 2,      dR = Exp(w_bar dt),   R1 = R0 dR
//   a_bar = (R0 a0 + R1 a1) / 2 + g_w                 (world, g_w = (0, 0, -g))
//   p1 = p0 + v0 dt + a_bar dt^2 / 2,    v1 = v0 + a_bar dt
//   b1 = Phi b0                    (Gauss-Markov mean decay, Phi = exp(-dt/tau), 1 for a random walk)
// Global error O(dt^2) (Euler's is O(dt)).
//
// F = d dx1 / d dx0 in the chart of ekf_state.h, exact for this discrete map
// (tested against finite differences):
//   dtheta1 = dR^T dtheta0 - Jr(w_bar dt) dt dbg
//   da_bar  = A_theta dtheta0 + A_ba dba + A_bg dbg, with
//             A_theta = -(R0 [a0]x + R1 [a1]x dR^T) / 2,  A_ba = -(R0 + R1) / 2,
//             A_bg    = R1 [a1]x Jr(w_bar dt) dt / 2
//   dp1 = dp0 + dt dv0 + dt^2/2 da_bar,   dv1 = dv0 + dt da_bar
//   dba1 = Phi_a dba0,  dbg1 = Phi_g dbg0
// With w1 = w0, a1 = a0 it is the Euler step with the sample held over dt.
#include "estimation/ekf/ekf_state.h"

namespace rilo {

/// IMU readings at both ends of one propagation interval (body frame, raw: bias not removed).
struct ImuInterval {
  Vec3 gyro0_rad_s;   ///< at t0
  Vec3 accel0_m_s2;   ///< at t0
  Vec3 gyro1_rad_s;   ///< at t1
  Vec3 accel1_m_s2;   ///< at t1
  double dt_s;        ///< t1 - t0 (s), > 0
};

/// Propagates `x` over the interval; writes F (15x15) when F_x1_x0 is not null.
/// bias_transition: per-axis Phi over dt, ordered [accel xyz, gyro xyz]
/// (ImuParams::biasTransition). Never allocates.
EkfState integrateImuMidpoint(const EkfState& x, const ImuInterval& m, const Vec3& g_w, const Vec6& bias_transition,
                              Mat15* F_x1_x0);

}  // namespace rilo
