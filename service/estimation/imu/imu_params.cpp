#include "estimation/imu/imu_params.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

[[noreturn]] void fail(const char* field, const char* rule, double value) {
  throw std::invalid_argument(std::string("ImuParams: ") + field + " must be " + rule + ", got " +
                              std::to_string(value));
}
void requirePositiveFinite(double v, const char* field) {
  if (!(std::isfinite(v) && v > 0.0)) fail(field, "finite and > 0", v);
}
void requireTau(double tau_s, const char* field) {
  if (!(tau_s > 0.0)) fail(field, "> 0 (+inf for a random walk)", tau_s);  // also rejects NaN
}

}  // namespace

double gaussMarkovTransition(double dt_s, double tau_s) { return std::isinf(tau_s) ? 1.0 : std::exp(-dt_s / tau_s); }

double gaussMarkovVariance(double q, double tau_s, double dt_s) {
  if (std::isinf(tau_s)) return q * q * dt_s;
  // q^2 tau/2 (1 - exp(-2 dt/tau)); expm1 keeps precision when dt << tau.
  return -0.5 * q * q * tau_s * std::expm1(-2.0 * dt_s / tau_s);
}

double ImuParams::gyroBiasSigma() const { return gyro_bias_random_walk * std::sqrt(0.5 * gyro_bias_tau_s); }
double ImuParams::accelBiasSigma() const { return accel_bias_random_walk * std::sqrt(0.5 * accel_bias_tau_s); }

void ImuParams::setGyroBiasGaussMarkov(double sigma, double tau_s) {
  requirePositiveFinite(sigma, "gyro bias sigma");
  requirePositiveFinite(tau_s, "gyro_bias_tau_s");
  gyro_bias_random_walk = sigma * std::sqrt(2.0 / tau_s);
  gyro_bias_tau_s = tau_s;
}

void ImuParams::setAccelBiasGaussMarkov(double sigma, double tau_s) {
  requirePositiveFinite(sigma, "accel bias sigma");
  requirePositiveFinite(tau_s, "accel_bias_tau_s");
  accel_bias_random_walk = sigma * std::sqrt(2.0 / tau_s);
  accel_bias_tau_s = tau_s;
}

Vec6 ImuParams::biasTransition(double dt_s) const {
  Vec6 phi;
  phi.head<3>().setConstant(gaussMarkovTransition(dt_s, accel_bias_tau_s));
  phi.tail<3>().setConstant(gaussMarkovTransition(dt_s, gyro_bias_tau_s));
  return phi;
}

Vec6 ImuParams::biasDiscreteVariance(double dt_s) const {
  Vec6 var;
  var.head<3>().setConstant(gaussMarkovVariance(accel_bias_random_walk, accel_bias_tau_s, dt_s));
  var.tail<3>().setConstant(gaussMarkovVariance(gyro_bias_random_walk, gyro_bias_tau_s, dt_s));
  return var;
}

void ImuParams::validate() const {
  requirePositiveFinite(gyro_noise_density, "gyro_noise_density");
  requirePositiveFinite(accel_noise_density, "accel_noise_density");
  requirePositiveFinite(gyro_bias_random_walk, "gyro_bias_random_walk");
  requirePositiveFinite(accel_bias_random_walk, "accel_bias_random_walk");
  requireTau(gyro_bias_tau_s, "gyro_bias_tau_s");
  requireTau(accel_bias_tau_s, "accel_bias_tau_s");
  // > 0: with a single sample the p/v covariance block is otherwise exactly rank 3.
  if (!(std::isfinite(integration_noise_density) && integration_noise_density > 0.0)) {
    fail("integration_noise_density", "finite and > 0", integration_noise_density);
  }
  if (!(std::isfinite(gravity_m_s2) && gravity_m_s2 >= 0.0)) fail("gravity_m_s2", "finite and >= 0", gravity_m_s2);
  requirePositiveFinite(gap_threshold_s, "gap_threshold_s");
  if (!(std::isfinite(gap_accel_sigma_m_s2) && gap_accel_sigma_m_s2 >= 0.0)) {
    fail("gap_accel_sigma_m_s2", "finite and >= 0", gap_accel_sigma_m_s2);
  }
  if (!(std::isfinite(gap_gyro_sigma_rad_s) && gap_gyro_sigma_rad_s >= 0.0)) {
    fail("gap_gyro_sigma_rad_s", "finite and >= 0", gap_gyro_sigma_rad_s);
  }
}

}  // namespace rilo
