#pragma once
// A scenario's IMU readings made a wearer's, for tests of the standstill
// prior: resting over a time span (gravity, a small bias, deterministic
// sub-noise jitter, turning on the spot), and with gait outside it if asked
// (the analytic walk glides without the steps a body-worn IMU feels). Only
// the IMU changes, so the factors' structure is under test, not the fit.
#include <cmath>
#include <cstdint>

#include "sim/range_imu_scenario.h"

namespace rilo::testing {

inline sim::Scenario withRestingImu(sim::Scenario s, double t_from_s, double t_to_s, bool gait_outside = true) {
  for (std::size_t k = 0; k < s.imu.size(); ++k) {
    const double t = 1e-9 * static_cast<double>(s.imu[k].t_ns - s.t0_ns);
    if (t < t_from_s || t > t_to_s) {
      // Two steps a second: a 1 m/s^2 vertical bounce.
      if (gait_outside) s.imu[k].accel_m_s2.z() += 1.0 * std::sin(2.0 * M_PI * 2.0 * t);
      continue;
    }
    const double j = 0.02 * std::sin(0.7 * static_cast<double>(k));  // a 0.014 m/s^2 std-dev
    s.imu[k].accel_m_s2 = Vec3(0.02 + j, -0.03 - j, 9.81 + j);
    s.imu[k].gyro_rad_s = Vec3(0.001, -0.002, 0.8);  // turning on the spot
  }
  return s;
}

}  // namespace rilo::testing
