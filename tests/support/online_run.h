#pragma once
// Drives a RangeImuEstimator through a simulated scenario in time order (a
// range before an IMU sample with the same time), as the service would: add
// a sample, process what is ready.
#include <functional>

#include "estimation/tracking/localizer.h"
#include "estimation/tracking/range_imu_estimator.h"
#include "sim/range_imu_scenario.h"

namespace rilo::testing {

/// Graph parameters matching the scenario's sensors.
inline RangeImuGraphParams graphParamsFor(const sim::Scenario& s, const std::string& loss = "asymmetric",
                                          bool anchors_as_variables = true) {
  RangeImuGraphParams gp;
  gp.p_b_tag = s.p_b_tag;
  gp.range_loss = loss;
  gp.range_noise.sigma_m = s.params.range_sigma_m;
  gp.imu = sim::imuParamsOf(s.params);
  gp.anchors_as_variables = anchors_as_variables;
  return gp;
}

/// The Localizer tests' settings: the scenario's sensors, a 5 s lag and a 5 s start-up window.
inline LocalizerParams localizerParamsFor(const sim::Scenario& s) {
  LocalizerParams p;
  p.graph = graphParamsFor(s);
  p.smoother.lag_s = 5.0;
  p.init.window_s = 5.0;
  return p;
}

/// Starts at the true state at the first range (initialization from scratch
/// is the pipeline's job) and feeds everything. `on_update` sees every
/// update's statistics and the estimator after it.
inline void runOnline(const sim::Scenario& s, RangeImuEstimator& estimator,
                      const std::function<void(const UpdateStats&, const RangeImuEstimator&)>& on_update) {
  const std::int64_t t0 = s.ranges.front().t_ns;
  const sim::KinematicState st0 = s.truthAt(t0);
  on_update(estimator.start(t0, st0.T_w_b, st0.v_w), estimator);
  std::vector<UpdateStats> stats;
  std::size_t i = 0, r = 0;
  while (i + 1 < s.imu.size() && s.imu[i + 1].t_ns <= t0) ++i;  // the sample in effect at t0 comes first
  while (i < s.imu.size() || r < s.ranges.size()) {
    const bool take_range = r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns);
    if (take_range) {
      estimator.addRange(s.ranges[r++]);
    } else {
      estimator.addImu(s.imu[i++]);
    }
    stats.clear();
    if (estimator.process(&stats) > 0) {
      for (const UpdateStats& st : stats) on_update(st, estimator);
    }
  }
  estimator.finish();
  stats.clear();
  estimator.process(&stats);
  for (const UpdateStats& st : stats) on_update(st, estimator);
}

}  // namespace rilo::testing
