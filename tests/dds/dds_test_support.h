#pragma once
// Shared set-up of the DDS tests: a private domain on the loopback interface
// and topic names unique to this process, so concurrent test runs on the same
// machine (ctest -j, other people's builds) never see each other's samples.
#include <spawn.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "dds/participant.h"
#include "dds/topics.h"
#include "runtime/navigation_state.h"
#include "runtime/service_status.h"

extern char** environ;

namespace rilo::dds::testing {

inline constexpr std::chrono::seconds kMatchTimeout{10};

/// Domain id in [100, 230) derived from the PID (valid with Cyclone's default ports, away from ROS's 0).
inline std::uint32_t uniqueDomainId() { return 100u + static_cast<std::uint32_t>(::getpid()) % 130u; }

inline ParticipantOptions loopbackOptions(std::uint32_t domain_id = uniqueDomainId()) {
  return ParticipantOptions{domain_id, loopbackConfigXml()};
}

/// Default names with a per-process, per-test suffix.
inline TopicNames uniqueTopicNames(const std::string& test_name) {
  // Built by appending: GCC 12's -Wrestrict misfires on "literal" + std::string.
  std::string suffix = "_";
  suffix += std::to_string(::getpid());
  suffix += "_";
  suffix += test_name;
  TopicNames names;
  names.odometry += suffix;
  names.pose += suffix;
  names.status += suffix;
  names.tf += suffix;
  names.ranges += suffix;
  return names;
}

inline Eigen::Vector3d randomVector(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0.0, scale);
  return {n(rng), n(rng), n(rng)};
}

inline Eigen::Quaterniond randomQuaternion(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
}

/// Random symmetric positive definite 6x6 with distinct entries everywhere.
inline Eigen::Matrix<double, 6, 6> randomCovariance(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0.0, scale);
  Eigen::Matrix<double, 6, 6> A;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) A(r, c) = n(rng);
  }
  return A * A.transpose() + 0.01 * scale * scale * Eigen::Matrix<double, 6, 6>::Identity();
}

inline NavigationState randomState(std::mt19937& rng, std::int64_t t_ns) {
  NavigationState s;
  s.t_ns = t_ns;
  s.q_w_b = randomQuaternion(rng);
  s.p_w_b = randomVector(rng, 5.0);
  s.v_w_b = randomVector(rng, 1.0);
  s.omega_b = randomVector(rng, 0.5);
  s.accel_bias_m_s2 = randomVector(rng, 0.05);
  s.gyro_bias_rad_s = randomVector(rng, 0.01);
  s.pose_covariance = randomCovariance(rng, 0.1);
  s.twist_covariance = randomCovariance(rng, 0.05);
  s.valid = true;
  return s;
}

inline ServiceStatus sampleStatus(std::int64_t t_ns) {
  ServiceStatus s;
  s.t_ns = t_ns;
  s.state = TrackingState::kDegraded;
  s.imu_samples = 123456789012ULL;
  s.range_samples = 4567;
  s.tdoa_samples = 8901;
  s.ultrasonic_samples = 234;
  s.queue_overflows = 3;
  s.late_updates = 7;
  s.sensor_faults = 11;
  s.sensor_silences = 13;
  s.reinitializations = 2;
  s.rejected_ranges = 99;
  s.deep_nlos_tdoa_rows = 41;
  s.published_odometry = 123450000;
  s.non_finite_samples = 19;
  s.duplicate_samples = 23;
  s.out_of_order_samples = 29;
  s.imu_gaps = 31;
  s.ranging_gaps = 37;
  s.out_of_bounds_samples = 53;
  s.beyond_full_scale_samples = 59;
  s.far_future_samples = 61;
  s.time_jumps = 67;
  s.last_update_ms = 1.25;
  s.mean_update_ms = 0.875;
  s.max_update_ms = 14.5;
  s.p99_update_ms = 2.25;
  s.estimator_queue_high_water = 41;
  s.publisher_queue_high_water = 43;
  s.last_cliques_reeliminated = 17;
  s.last_relinearized = 5;
  s.last_lambda = 1e-3;
  s.odometry_latency_ms = 0.31;
  s.pose_latency_ms = 22.0;
  const std::string fault = "dwm3000 /dev/spidev0.0: RX timeout";
  fault.copy(s.last_fault.data(), s.last_fault.size() - 1);
  const std::string reason = "no ranging for 12.4 s (IMU only)";
  reason.copy(s.reason.data(), s.reason.size() - 1);
  return s;
}

/// Re-executes this test binary with this process's environment plus
/// `extra_env` ("NAME=value"); the child recognizes its role by one of those
/// variables before main(). The child's pid, or -1.
inline pid_t spawnSelf(const std::vector<std::string>& extra_env) {
  std::vector<std::string> env;
  for (char** e = environ; *e != nullptr; ++e) env.emplace_back(*e);
  env.insert(env.end(), extra_env.begin(), extra_env.end());
  std::vector<char*> envp;
  for (std::string& s : env) envp.push_back(s.data());
  envp.push_back(nullptr);
  std::string self = "/proc/self/exe";
  std::vector<char*> argv{self.data(), nullptr};
  pid_t pid = -1;
  if (posix_spawn(&pid, self.c_str(), nullptr, nullptr, argv.data(), envp.data()) != 0) return -1;
  return pid;
}

}  // namespace rilo::dds::testing
