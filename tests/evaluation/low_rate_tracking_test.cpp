// Tracking at the Ranging-IMU Fusion paper's lowest ranging rate (1 Hz total, Table II) on a
// clean simulated office walk, started at the truth: what is left is the
// estimator's own behaviour, not initialization or NLOS. Before D-iSAM2 took
// the Gauss-Newton step for IMU-only states (SmootherParams,
// damping_min_new_error) and before recent states were exempt from the
// relinearization age limit (relinearize_min_recent_times), D-iSAM2 drifted
// to kilometres here within a minute; iSAM2 tracked.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <memory>

#include "estimation/smoother/bayes_tree_smoother.h"
#include "estimation/tracking/localizer.h"
#include "estimation/tracking/range_imu_estimator.h"
#include "evaluation/range_thinning.h"
#include "sim/office_scenario.h"

namespace rilo {
namespace {

struct TrackingError {
  double mean_m = 0.0;
  double max_m = 0.0;
  int states = 0;
};

TrackingError trackFromTruth(const sim::Scenario& s, const std::vector<RangeSample>& ranges,
                             SmootherParams::Method method, double vertical_speed_sigma_m_s = 0.0) {
  LocalizerParams lp;  // the pipeline's defaults, as rilo replay uses them
  lp.graph.imu = sim::imuParamsOf(s.params);
  lp.graph.p_b_tag = s.p_b_tag;
  lp.graph.height_band = lp.height_band;
  lp.graph.vertical_speed_sigma_m_s = vertical_speed_sigma_m_s;
  lp.smoother.method = method;
  lp.smoother.lag_s = 5.0;
  RangeImuEstimator estimator(s.p_w_anchors, lp.graph, std::make_unique<BayesTreeSmoother>(lp.smoother), lp.stream);

  const std::int64_t t_start = s.t0_ns + 5'000'000'000;
  const sim::KinematicState truth0 = s.truthAt(t_start);
  estimator.start(t_start, truth0.T_w_b, truth0.v_w);
  std::size_t i = 0, r = 0;
  while (s.imu[i].t_ns < t_start) ++i;
  while (r < ranges.size() && ranges[r].t_ns <= t_start) ++r;
  TrackingError e;
  while (i < s.imu.size() || r < ranges.size()) {
    if (r < ranges.size() && (i >= s.imu.size() || ranges[r].t_ns <= s.imu[i].t_ns)) {
      estimator.addRange(ranges[r++]);
    } else {
      estimator.addImu(s.imu[i++]);
    }
    if (estimator.process() == 0) continue;
    const StateEstimate& x = estimator.latest();
    const double err = (x.T_w_b.p - s.truthAt(x.t_ns).T_w_b.p).norm();
    e.mean_m += err;
    e.max_m = std::max(e.max_m, err);
    ++e.states;
  }
  if (e.states > 0) e.mean_m /= e.states;
  return e;
}

class LowRateTracking : public ::testing::TestWithParam<SmootherParams::Method> {};

TEST_P(LowRateTracking, OneHertzCleanWalkStaysOnTrack) {
  sim::OfficeScenarioParams p;
  p.seed = 1;
  p.duration_s = 90.0;
  p.plan = sim::OfficePlanKind::kRandom;
  p.channel.nlos_severity = 0.0;
  const sim::Scenario s = sim::simulateOfficeScenario(p);
  RangeThinningOptions thin;
  thin.rate_hz = 1.0;
  const std::vector<RangeSample> ranges = thinRanges(s.ranges, thin);
  ASSERT_GT(ranges.size(), 80u);

  const TrackingError e = trackFromTruth(s, ranges, GetParam());
  ASSERT_GT(e.states, 150);
  // Measured (seed 1), D-iSAM2 / iSAM2 / dog-leg: mean 0.61 / 0.61 / 0.62 m,
  // max 4.0 / 3.4 / 3.8 m with the height hold and range lever (issue 36);
  // without them 0.81 / 0.79 / 0.78 m, max 3.3 / 3.2 / 3.2 m. D-iSAM2 before
  // the fixes: mean 11.6 km; and 12 km again with a vertical speed prior
  // while motion priors counted as measurements for its damping.
  EXPECT_LT(e.mean_m, 1.0) << smootherMethodName(GetParam());
  EXPECT_LT(e.max_m, 5.0) << smootherMethodName(GetParam());

  // With a vertical speed prior of 0.3 m/s per 0.25 s on every state, IMU-only
  // states included: a motion prior is no measurement for D-iSAM2's damping
  // (Factor::markMotionPrior). Counted, it damped every IMU-only state and
  // D-iSAM2 ran to 12 km (mean) here. Measured: 0.61 / 0.61 / 0.62 m, max 3.9 / 3.3 / 3.9 m.
  const TrackingError v = trackFromTruth(s, ranges, GetParam(), 0.3);
  EXPECT_LT(v.mean_m, 1.0) << smootherMethodName(GetParam()) << " with the vertical speed prior";
  EXPECT_LT(v.max_m, 5.0) << smootherMethodName(GetParam()) << " with the vertical speed prior";
}

// From scratch at 1 Hz (issue 4): the Localizer initializes (the alignment's
// yaw gate at the window's end, a window of up to 45 s) and tracks from the
// batch's marginals (the hand-over), with no re-initialization. On the
// office/hall replays at 1 Hz, main's pipeline never initialized 3 of 7 and
// re-initialized 2 (online 4.9-5.9 m); without the covariance hand-over the
// same gates gave 7 re-initializations. Measured here: seed 1 initialized
// at 35 s, mean 0.40 m, max 0.75 m; seed 2 at 44 s, 0.39 m, 1.14 m.
struct FromScratch {
  bool initialized = false;
  std::uint64_t reinitializations = 0;
  double init_time_s = 0.0;
  TrackingError error;
  std::string status;
};

FromScratch localizeFromScratch(const sim::Scenario& s, const std::vector<RangeSample>& ranges) {
  LocalizerParams lp;  // the pipeline's defaults, as rilo replay uses them
  lp.graph.imu = sim::imuParamsOf(s.params);
  lp.graph.p_b_tag = s.p_b_tag;
  Localizer loc(s.p_w_anchors, lp);
  FromScratch out;
  std::size_t i = 0, r = 0;
  while (i < s.imu.size() || r < ranges.size()) {
    if (r < ranges.size() && (i >= s.imu.size() || ranges[r].t_ns <= s.imu[i].t_ns)) {
      loc.addRange(ranges[r++]);
    } else {
      loc.addImu(s.imu[i++]);
    }
    if (loc.process() == 0 || !loc.tracking()) continue;
    if (!out.initialized) out.init_time_s = 1e-9 * static_cast<double>(loc.latest().t_ns - s.t0_ns);
    out.initialized = true;
    const StateEstimate& x = loc.latest();
    const double err = (x.T_w_b.p - s.truthAt(x.t_ns).T_w_b.p).norm();
    out.error.mean_m += err;
    out.error.max_m = std::max(out.error.max_m, err);
    ++out.error.states;
  }
  if (out.error.states > 0) out.error.mean_m /= out.error.states;
  out.reinitializations = loc.reinitializations();
  out.status = loc.initStatus().message + " / " + loc.lastFailure();
  return out;
}

TEST(LowRateFromScratch, OneHertzWalkInitializesAndTracksWithoutReinitialization) {
  for (std::uint64_t seed : {1u, 2u}) {
    sim::OfficeScenarioParams p;
    p.seed = seed;
    p.duration_s = 120.0;
    p.plan = sim::OfficePlanKind::kRandom;
    p.channel.nlos_severity = 0.0;
    const sim::Scenario s = sim::simulateOfficeScenario(p);
    RangeThinningOptions thin;
    thin.rate_hz = 1.0;
    const std::vector<RangeSample> ranges = thinRanges(s.ranges, thin);
    const FromScratch f = localizeFromScratch(s, ranges);
    std::printf("1 Hz from scratch, seed %llu: initialized at %.1f s, %d states, mean %.2f m, max %.2f m, %llu re-inits\n",
                static_cast<unsigned long long>(seed), f.init_time_s, f.error.states, f.error.mean_m, f.error.max_m,
                static_cast<unsigned long long>(f.reinitializations));
    ASSERT_TRUE(f.initialized) << "seed " << seed << ": " << f.status;
    EXPECT_LT(f.init_time_s, 60.0) << "seed " << seed;
    EXPECT_EQ(f.reinitializations, 0u) << "seed " << seed << ": " << f.status;
    EXPECT_GT(f.error.states, 60) << "seed " << seed;
    EXPECT_LT(f.error.mean_m, 1.0) << "seed " << seed;
    EXPECT_LT(f.error.max_m, 3.0) << "seed " << seed;
  }
}

INSTANTIATE_TEST_SUITE_P(Smoothers, LowRateTracking,
                         ::testing::Values(SmootherParams::Method::kDamped, SmootherParams::Method::kGaussNewton,
                                           SmootherParams::Method::kDogleg),
                         [](const ::testing::TestParamInfo<SmootherParams::Method>& param_info) {
                           switch (param_info.param) {
                             case SmootherParams::Method::kDamped: return std::string("DIsam2");
                             case SmootherParams::Method::kGaussNewton: return std::string("Isam2");
                             default: return std::string("Dogleg");
                           }
                         });

}  // namespace
}  // namespace rilo
