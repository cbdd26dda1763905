#pragma once
// A synthetic ranging + IMU session over an analytic trajectory: noisy biased
// IMU samples, SS-TWR ranges to the strongest few anchors per cycle with
// persistent NLOS excursions, and the ground truth to evaluate against.
// Seeded and deterministic. (The office simulator with walls grows from this.)
#include <cstdint>
#include <memory>
#include <vector>

#include "estimation/graph/values.h"
#include "estimation/imu/imu_params.h"
#include "sensors/samples.h"
#include "sim/trajectory.h"

namespace rilo::sim {

struct ScenarioParams {
  std::uint64_t seed = 1;
  double duration_s = 60.0;
  double imu_rate_hz = 800.0;
  double range_rate_hz = 40.0;            ///< total ranges per second (all anchors)
  int ranges_per_cycle = 4;               ///< strongest anchors ranged per cycle
  double gravity_m_s2 = 9.81;
  // IMU errors (BMI263 class).
  double gyro_noise_density = 2.8e-4;     ///< rad/s/sqrt(Hz)
  double accel_noise_density = 1.6e-3;    ///< m/s^2/sqrt(Hz)
  double gyro_bias_walk = 2.0e-5;         ///< rad/s^2/sqrt(Hz)
  double accel_bias_walk = 2.0e-4;        ///< m/s^3/sqrt(Hz)
  double gyro_bias_init_sigma = 2e-3;     ///< rad/s
  double accel_bias_init_sigma = 0.03;    ///< m/s^2
  // Ranging errors.
  double range_sigma_m = 0.10;            ///< LOS first-path noise
  double nlos_fraction = 0.25;            ///< long-run fraction of time an anchor is NLOS
  double nlos_mean_duration_s = 3.0;      ///< persistence of an NLOS episode
  double nlos_scale_m = 0.4;              ///< half-Cauchy scale of the NLOS excess
  double nlos_max_excess_m = 8.0;         ///< physical cap on the excess
  double outlier_probability = 0.01;      ///< rare large multipath error on any range
  double range_dropout = 0.05;            ///< probability a range packet is lost
};

struct Scenario {
  ScenarioParams params;
  std::vector<Eigen::Vector3d> p_w_anchors;  ///< anchor positions, index = anchor_id
  Eigen::Vector3d p_b_tag = Eigen::Vector3d::Zero();  ///< UWB antenna lever arm
  std::vector<ImuSample> imu;
  std::vector<Eigen::Matrix<double, 6, 1>> imu_bias_truth;  ///< [accel; gyro] bias in effect for imu[k]
  std::vector<RangeSample> ranges;
  std::shared_ptr<const Trajectory> truth;
  Eigen::Vector3d gyro_bias0, accel_bias0;   ///< true initial biases
  std::int64_t t0_ns = 0;

  /// True [accel; gyro] bias at t_ns (the one in effect for the IMU sample at or before t_ns).
  Eigen::Matrix<double, 6, 1> biasAt(std::int64_t t_ns) const;
  KinematicState truthAt(std::int64_t t_ns) const { return truth->at(1e-9 * static_cast<double>(t_ns - t0_ns)); }
};

/// Eight anchors around the walking area at mixed heights (good vertical geometry).
std::vector<Eigen::Vector3d> defaultOfficeAnchors();

Scenario simulateScenario(const ScenarioParams& params);
/// The same sensors along another trajectory and anchor layout (tests of
/// motions the Lissajous walk lacks, such as a sit-down). Throws
/// std::invalid_argument for a null trajectory or no anchors.
Scenario simulateScenario(const ScenarioParams& params, std::shared_ptr<const Trajectory> truth,
                          std::vector<Eigen::Vector3d> p_w_anchors);

/// The IMU model that matches the simulated IMU (densities, random-walk biases).
ImuParams imuParamsOf(const ScenarioParams& params);

/// Per-state perturbation of the ground truth: the start of batch solves in
/// tests, benchmarks and the demo (until initialization from scratch lands).
struct TruthPerturbation {
  double rotation_rad = 0.05;
  double position_m = 0.3;
  double velocity_m_s = 0.2;
  std::uint64_t seed = 7;
};

/// Values for states X/V/B(i) at state_t_ns[i] and the anchors in anchor_keys
/// (sym::L(id), at their surveyed positions). With `perturbation` the poses and
/// velocities are perturbed and biases start at zero; without it, the exact truth.
Values truthValues(const Scenario& s, const std::vector<std::int64_t>& state_t_ns, const std::vector<Key>& anchor_keys,
                   const TruthPerturbation* perturbation = nullptr);

}  // namespace rilo::sim
