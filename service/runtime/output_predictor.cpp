#include "runtime/output_predictor.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "math/so3.h"

namespace rilo {
namespace {

constexpr double kNsToS = 1e-9;

void requireFiniteNonNegative(double value, const char* name) {
  if (!std::isfinite(value) || value < 0.0) {
    throw std::invalid_argument(std::string("OutputPredictorParams.") + name +
                                " must be finite and >= 0, got " + std::to_string(value));
  }
}

const OutputPredictorParams& validated(const OutputPredictorParams& params) {
  params.validate();
  return params;
}

}  // namespace

void OutputPredictorParams::validate() const {
  if (imu_buffer_capacity < 2) {
    throw std::invalid_argument("OutputPredictorParams.imu_buffer_capacity must be >= 2, got " +
                                std::to_string(imu_buffer_capacity));
  }
  requireFiniteNonNegative(gravity_m_s2, "gravity_m_s2");
  requireFiniteNonNegative(position_random_walk, "position_random_walk");
  requireFiniteNonNegative(rotation_random_walk, "rotation_random_walk");
  requireFiniteNonNegative(velocity_random_walk, "velocity_random_walk");
  requireFiniteNonNegative(gyro_noise_density, "gyro_noise_density");
  requireFiniteNonNegative(gyro_bias_sigma, "gyro_bias_sigma");
}

OutputPredictor::OutputPredictor(const OutputPredictorParams& params)
    : params_(validated(params)),
      g_w_(0.0, 0.0, -params.gravity_m_s2),
      imu_(params.imu_buffer_capacity) {}

const NavigationState& OutputPredictor::onImu(const ImuSample& sample) noexcept {
  if (!imu_.empty() && sample.t_ns <= imu_.newest().t_ns) {
    ++rejected_;
    return out_;
  }
  if (imu_.push(sample)) ++dropped_;
  // A sample not after the output time (smoothed state ahead of the IMU) only waits in the ring.
  if (!out_.valid || sample.t_ns <= out_.t_ns) return out_;
  if (has_prev_) {
    step(sample);
  } else {
    integrateFrom(imu_.size() - 1);  // first sample after a smoothed state: interpolate at its time
  }
  growCovariance();
  return out_;
}

const NavigationState& OutputPredictor::onSmoothed(const NavigationState& smoothed) noexcept {
  out_ = smoothed;
  has_prev_ = false;
  if (!out_.valid) return out_;
  out_.q_w_b.normalize();
  R_w_b_ = out_.q_w_b.toRotationMatrix();
  smoothed_t_ns_ = smoothed.t_ns;
  smoothed_pose_cov_ = smoothed.pose_covariance;
  smoothed_twist_cov_ = smoothed.twist_covariance;
  // Samples newer than the smoothed state are the last ones: scan from the newest.
  std::size_t first = imu_.size();
  while (first > 0 && imu_[first - 1].t_ns > smoothed.t_ns) --first;
  if (first == imu_.size()) return out_;  // nothing newer yet; onImu continues from here
  if (first == 0 && dropped_ > 0) ++truncated_;
  integrateFrom(first);
  growCovariance();
  return out_;
}

void OutputPredictor::integrateFrom(std::size_t first) noexcept {
  // Measurement at the output time: linear interpolation between the samples
  // around it, or the first newer sample held constant if none is older.
  const ImuSample& after = imu_[first];
  if (first > 0) {
    const ImuSample& before = imu_[first - 1];
    const double alpha = static_cast<double>(out_.t_ns - before.t_ns) / static_cast<double>(after.t_ns - before.t_ns);
    prev_gyro_rad_s_ = before.gyro_rad_s + alpha * (after.gyro_rad_s - before.gyro_rad_s);
    prev_accel_m_s2_ = before.accel_m_s2 + alpha * (after.accel_m_s2 - before.accel_m_s2);
  } else {
    prev_gyro_rad_s_ = after.gyro_rad_s;
    prev_accel_m_s2_ = after.accel_m_s2;
  }
  has_prev_ = true;
  prev_sample_t_ns_ = first > 0 ? imu_[first - 1].t_ns : 0;
  for (std::size_t i = first; i < imu_.size(); ++i) step(imu_[i]);
}

void OutputPredictor::step(const ImuSample& sample) noexcept {
  const double dt_s = static_cast<double>(sample.t_ns - out_.t_ns) * kNsToS;
  const Vec3 w0_b = prev_gyro_rad_s_ - out_.gyro_bias_rad_s;
  const Vec3 w1_b = sample.gyro_rad_s - out_.gyro_bias_rad_s;
  const Vec3 f0_b = prev_accel_m_s2_ - out_.accel_bias_m_s2;
  const Vec3 f1_b = sample.accel_m_s2 - out_.accel_bias_m_s2;

  const Mat3 R0_w_b = R_w_b_;
  // Through the quaternion: keeps the rotation orthonormal over long IMU-only stretches.
  out_.q_w_b = Quat(R0_w_b * so3::exp((0.5 * dt_s) * (w0_b + w1_b))).normalized();
  R_w_b_ = out_.q_w_b.toRotationMatrix();

  const Vec3 a_w = 0.5 * (R0_w_b * f0_b + R_w_b_ * f1_b) + g_w_;
  out_.p_w_b += dt_s * out_.v_w_b + (0.5 * dt_s * dt_s) * a_w;
  out_.v_w_b += dt_s * a_w;
  out_.omega_b = w1_b;
  out_.t_ns = sample.t_ns;
  // Per raw sample interval, not the integration step: the first step after
  // a smoothed state covers only part of one (a 1 us step read as 0.28 rad/s).
  if (prev_sample_t_ns_ > 0 && sample.t_ns > prev_sample_t_ns_) {
    const double period_s = static_cast<double>(sample.t_ns - prev_sample_t_ns_) * kNsToS;
    omega_var_ = (params_.gyro_noise_density * params_.gyro_noise_density) / period_s +
                 params_.gyro_bias_sigma * params_.gyro_bias_sigma;
  }
  prev_sample_t_ns_ = sample.t_ns;

  prev_gyro_rad_s_ = sample.gyro_rad_s;
  prev_accel_m_s2_ = sample.accel_m_s2;
}

void OutputPredictor::growCovariance() noexcept {
  const double dt_s = static_cast<double>(out_.t_ns - smoothed_t_ns_) * kNsToS;
  const double var_p = params_.position_random_walk * params_.position_random_walk * dt_s;
  const double var_r = params_.rotation_random_walk * params_.rotation_random_walk * dt_s;
  const double var_v = params_.velocity_random_walk * params_.velocity_random_walk * dt_s;
  out_.pose_covariance = smoothed_pose_cov_;
  out_.pose_covariance.topLeftCorner<3, 3>() += (dt_s * dt_s) * smoothed_twist_cov_.topLeftCorner<3, 3>();
  out_.pose_covariance.topLeftCorner<3, 3>().diagonal().array() += var_p;
  out_.pose_covariance.bottomRightCorner<3, 3>().diagonal().array() += var_r;
  out_.twist_covariance = smoothed_twist_cov_;
  out_.twist_covariance.topLeftCorner<3, 3>().diagonal().array() += var_v;
  if (omega_var_ > 0.0) {
    out_.twist_covariance.topRightCorner<3, 3>().setZero();
    out_.twist_covariance.bottomLeftCorner<3, 3>().setZero();
    out_.twist_covariance.bottomRightCorner<3, 3>() = Mat3::Identity() * omega_var_;
  }
}

}  // namespace rilo
