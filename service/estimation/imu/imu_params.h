#pragma once
// IMU noise model shared by preintegration and the IMU/bias factors.
//
// Measurements (body frame):  a_m = a + b_a + n_a,   w_m = w + b_g + n_g,
// n_a, n_g white with the noise densities below (discrete std per sample =
// density / sqrt(dt)).
//
// Bias model, per axis, accelerometer and gyroscope separately: first-order
// Gauss-Markov (Ranging-IMU Fusion paper, Sec. III-A)
//     db/dt = -b / tau + w,   w white with driving density q.
// Parametrized by (q, tau) so that both cases are one formula:
//   - tau finite: transition Phi(dt) = exp(-dt/tau), added variance
//     q^2 tau/2 (1 - exp(-2 dt/tau)), steady-state sigma = q sqrt(tau/2);
//   - tau = +inf: random walk, Phi = 1, added variance q^2 dt (the limit of
//     the formula above), no steady state.
// To specify a process by its steady-state sigma instead, use
// set*BiasGaussMarkov(sigma, tau), which sets q = sigma sqrt(2/tau).
#include <limits>

#include "math/types.h"

namespace rilo {

/// exp(-dt/tau): discrete transition of db/dt = -b/tau over dt (1 for tau = +inf).
double gaussMarkovTransition(double dt_s, double tau_s);
/// Variance added over dt by driving density q: q^2 tau/2 (1 - exp(-2 dt/tau)),
/// q^2 dt for tau = +inf. Units: (units of q)^2 * s.
double gaussMarkovVariance(double q, double tau_s, double dt_s);

struct ImuParams {
  static constexpr double kRandomWalk = std::numeric_limits<double>::infinity();  ///< tau for a random walk

  // White measurement noise. Defaults: Bosch BMI270 datasheet (BMI263 is the
  // same family): gyro 0.008 dps/sqrt(Hz) = 1.4e-4 rad/s/sqrt(Hz)
  // (performance mode < 0.007), accel 160 ug/sqrt(Hz) = 1.6e-3 m/s^2/sqrt(Hz).
  double gyro_noise_density = 1.4e-4;   ///< rad/s/sqrt(Hz)
  double accel_noise_density = 1.6e-3;  ///< m/s^2/sqrt(Hz)

  // Bias processes (driving density q and correlation time tau, see above).
  // The datasheet gives no bias stability figure. Defaults are the order of
  // magnitude of Allan-variance fits of consumer MEMS IMUs with similar noise
  // densities (Kalibr/EuRoC-style, inflated), with tau long enough that a
  // window of a few seconds sees almost a random walk; the resulting
  // steady-state sigmas, 0.026 dps and 2.3 mg, are of the size of the
  // in-run (temperature) drift after factory calibration; the turn-on offset
  // belongs in the bias prior. UNVERIFIED for the BMI263: fit them to an
  // Allan-variance recording of the device, as the Ranging-IMU Fusion paper did.
  double gyro_bias_random_walk = 2.0e-5;   ///< q_g, rad/s^2/sqrt(Hz)
  double accel_bias_random_walk = 1.0e-3;  ///< q_a, m/s^3/sqrt(Hz)
  double gyro_bias_tau_s = 1000.0;         ///< gyro bias correlation time (s); kRandomWalk = random walk
  double accel_bias_tau_s = 1000.0;        ///< accel bias correlation time (s); kRandomWalk = random walk

  /// Position noise density added during preintegration to cover the Euler
  /// discretization (variance density^2 * dt on the position block), m/s/sqrt(Hz).
  /// Small; GTSAM's examples use the equivalent of 1e-4.
  double integration_noise_density = 1.0e-4;

  double gravity_m_s2 = 9.81;  ///< magnitude of gravity (m/s^2); world gravity is (0, 0, -g), z up

  // Missing samples. A sample interval longer than gap_threshold_s means the
  // IMU dropped samples: the held sample stands for motion nobody measured.
  // Such an interval gets, on top of the white noise, a per-interval input
  // variance of (gap sigma)^2, i.e. an unknown constant accel/rate deviation
  // over the gap: velocity sigma gap_accel * dt, rotation sigma gap_gyro * dt.
  // Without it a gap was integrated as exactly known and the smoother pushed
  // the error into the biases (measured: docs/noise-models.md, Figures behind
  // the defaults). Defaults: a walking person's accel and turn-rate
  // variability. Must exceed the nominal sample interval (0.02 s: IMU rates
  // >= 50 Hz).
  double gap_threshold_s = 0.02;
  double gap_accel_sigma_m_s2 = 2.0;
  double gap_gyro_sigma_rad_s = 0.5;

  /// Steady-state bias standard deviation q sqrt(tau/2): rad/s (gyro), m/s^2
  /// (accel); +inf for a random walk.
  double gyroBiasSigma() const;
  double accelBiasSigma() const;
  /// Sets (q, tau) from the steady-state sigma (rad/s, m/s^2) and tau (s, finite).
  void setGyroBiasGaussMarkov(double sigma, double tau_s);
  void setAccelBiasGaussMarkov(double sigma, double tau_s);

  Vec3 gravityWorld() const { return Vec3(0.0, 0.0, -gravity_m_s2); }  ///< m/s^2, world frame
  /// Per-axis bias transition over dt, ordered [accel xyz, gyro xyz] like ImuBias.
  Vec6 biasTransition(double dt_s) const;
  /// Per-axis bias variance added over dt, same order: m^2/s^4 (accel), rad^2/s^2 (gyro).
  Vec6 biasDiscreteVariance(double dt_s) const;

  /// Throws std::invalid_argument naming the first bad field: densities must be
  /// finite and > 0 (integration_noise_density >= 0), tau > 0 (may be +inf),
  /// gravity finite and >= 0, gap threshold > 0 and gap sigmas >= 0.
  void validate() const;
};

}  // namespace rilo
