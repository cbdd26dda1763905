#pragma once
// IMU-rate extrapolation of the smoothed state (like PX4's output predictor):
// the publisher thread feeds every IMU sample and gets the navigation state at
// that sample's time; when the smoother hands over a new (delayed) state, the
// buffered IMU samples newer than it are re-integrated from it, so the output
// moves to the re-integrated value at once and then continues from there.
//
// Integration per IMU interval [t0, t1] (midpoint rule, second order):
//   w = (w0 + w1)/2 - b_g,  R1 = R0 Exp(w dt)  (exact SO(3) exponential)
//   a = (R0 (f0 - b_a) + R1 (f1 - b_a))/2 + g_w,   g_w = (0, 0, -g), z up
//   p1 = p0 + v0 dt + a dt^2/2,   v1 = v0 + a dt
// with the measurements (w, f) at t0 and t1; the measurement at a smoothed
// state's time is interpolated between the buffered samples around it.
//
// Covariance: the smoothed covariance grown with the time dt since the
// smoothed state (a coarse bound, not a propagated covariance; cross terms kept
// from the smoother, not grown):
//   position  += Sigma_v dt^2 + q_p^2 dt     (smoothed velocity error held,
//                                             plus a random walk)
//   rotation  += q_r^2 dt
//   velocity  += q_v^2 dt                    (twist, linear block)
//   angular rate block: one gyro sample's white noise (density^2 over the
//                       interval between raw samples) plus the bias's
//                       variance (gyro_noise_density, gyro_bias_sigma);
//                       both 0: the smoother's, unchanged.
//
// Not thread-safe: one thread (the publisher) owns it. No heap allocation
// after construction.
#include <cstddef>
#include <cstdint>

#include "math/types.h"
#include "runtime/fixed_ring.h"
#include "runtime/navigation_state.h"
#include "sensors/samples.h"

namespace rilo {

struct OutputPredictorParams {
  /// IMU samples kept for re-integration; must cover the smoother's delay
  /// (ranging period + update time) at the IMU rate. 2048 = 2.5 s at 800 Hz.
  std::size_t imu_buffer_capacity = 2048;
  double gravity_m_s2 = 9.81;              ///< magnitude of gravity (m/s^2)
  double position_random_walk = 0.05;      ///< q_p, m/sqrt(s)
  double rotation_random_walk = 2.0e-3;    ///< q_r, rad/sqrt(s)
  double velocity_random_walk = 0.05;      ///< q_v, m/s/sqrt(s)
  /// The body rate published is one gyro sample less the estimated bias:
  /// its variance per axis is the sample's white noise, density^2 / dt (dt
  /// the sample interval), plus the bias's variance, gyro_bias_sigma^2.
  /// Both 0: the angular block stays as the smoothed state gave it.
  double gyro_noise_density = 0.0;         ///< rad/s/sqrt(Hz)
  double gyro_bias_sigma = 0.0;            ///< rad/s

  /// Throws std::invalid_argument naming the first bad field: capacity >= 2,
  /// gravity and random walks finite and >= 0.
  void validate() const;
};

class OutputPredictor {
 public:
  /// Allocates the IMU ring. Throws std::invalid_argument on bad params.
  explicit OutputPredictor(const OutputPredictorParams& params = {});

  /// Buffers the sample and, once a valid smoothed state is known, integrates
  /// to its time and returns the state there. A sample not after the output
  /// time (the smoothed state is ahead of the IMU stream) only waits in the
  /// ring: the state returned is then still at the smoothed time, so a caller
  /// publishing per sample checks t_ns == sample.t_ns. A sample not newer than the
  /// previous one is rejected (counted, not buffered) and the state returned
  /// unchanged; so is the state while no valid smoothed state is known
  /// (valid == false). A full ring drops its oldest sample (counted).
  const NavigationState& onImu(const ImuSample& sample) noexcept;

  /// Takes a new smoothed state and re-integrates the buffered samples newer
  /// than it; returns the state at the newest buffered sample (or the smoothed
  /// state itself if no sample is newer). An invalid state (valid == false)
  /// stops the output until the next valid one. If the ring no longer holds the
  /// sample at or before the smoothed time (overwritten), the first interval
  /// holds the oldest buffered sample constant; counted as truncated.
  const NavigationState& onSmoothed(const NavigationState& smoothed) noexcept;

  /// The current output (the last value returned).
  const NavigationState& state() const noexcept { return out_; }

  std::size_t bufferedSamples() const noexcept { return imu_.size(); }
  std::uint64_t droppedSamples() const noexcept { return dropped_; }    ///< overwritten in a full ring
  std::uint64_t rejectedSamples() const noexcept { return rejected_; }  ///< time not increasing
  std::uint64_t truncatedReintegrations() const noexcept { return truncated_; }

 private:
  // Integrates imu_[first..size) from out_; `first` >= 0 is the first sample newer than out_.t_ns.
  void integrateFrom(std::size_t first) noexcept;
  void step(const ImuSample& sample) noexcept;
  void growCovariance() noexcept;

  OutputPredictorParams params_;
  Vec3 g_w_;                              ///< gravity in world (m/s^2)
  FixedRing<ImuSample> imu_;              ///< raw samples, strictly increasing t_ns
  NavigationState out_;                   ///< current output
  Mat3 R_w_b_ = Mat3::Identity();         ///< out_.q_w_b as a matrix
  std::int64_t smoothed_t_ns_ = 0;        ///< time of the last smoothed state
  Mat6 smoothed_pose_cov_ = Mat6::Identity();
  Mat6 smoothed_twist_cov_ = Mat6::Identity();
  // Raw measurement at out_.t_ns (start of the next interval); valid once has_prev_.
  Vec3 prev_gyro_rad_s_ = Vec3::Zero();
  Vec3 prev_accel_m_s2_ = Vec3::Zero();
  bool has_prev_ = false;
  double omega_var_ = 0.0;  ///< variance of out_.omega_b per axis, from the last step (0: none yet)
  std::int64_t prev_sample_t_ns_ = 0;  ///< the raw sample before the one stepped to (0: none)
  std::uint64_t dropped_ = 0;
  std::uint64_t rejected_ = 0;
  std::uint64_t truncated_ = 0;
};

}  // namespace rilo
