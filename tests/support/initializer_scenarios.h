#pragma once
// The scenarios and parameters the initializer tests share: a walk that
// moves from the start (25 % NLOS by default) and the initializer's
// parameters for a scenario, bias priors as the device's turn-on spread.
#include <cstdint>

#include "estimation/init/initializer.h"
#include "sim/range_imu_scenario.h"
#include "support/online_run.h"

namespace rilo::testing {

inline sim::Scenario movingScenario(std::uint64_t seed, double range_rate_hz, double duration_s) {
  sim::ScenarioParams sp;  // 25 % NLOS by default
  sp.seed = seed;
  sp.range_rate_hz = range_rate_hz;
  sp.duration_s = duration_s;
  return sim::simulateScenario(sp);
}

inline InitializerParams initializerParamsFor(const sim::Scenario& s) {
  InitializerParams p;
  p.graph = graphParamsFor(s);
  // Bias priors as the device's turn-on spread: 3 sigma of the simulator's.
  p.graph.first_accel_bias_sigma = 3.0 * s.params.accel_bias_init_sigma;
  p.graph.first_gyro_bias_sigma = 3.0 * s.params.gyro_bias_init_sigma;
  return p;
}

}  // namespace rilo::testing
