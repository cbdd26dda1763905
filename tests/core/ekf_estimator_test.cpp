// The EKF baseline as the pipeline drives it (EkfEstimator: measurement
// timing, grouping, losses from the graph parameters), started at the truth.
#include "estimation/tracking/ekf_estimator.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <limits>

#include "sim/range_imu_scenario.h"
#include "support/online_run.h"
#include "support/resting_imu.h"
#include "support/tdoa_row.h"

namespace rilo {
namespace {

struct FilterRun {
  double mean_error_m = 0.0;
  double max_error_m = 0.0;
  int updates = 0;
};

/// Feeds the scenario from its first range on, in time order, to a filter
/// started there; `on_updates(stats)` after each process() that updated, until it returns false.
template <typename OnUpdates>
void feed(EkfEstimator& ekf, const sim::Scenario& s, const Vec3& start_offset_m, OnUpdates on_updates) {
  const std::int64_t t0 = s.ranges.front().t_ns;
  const sim::KinematicState x0 = s.truthAt(t0);
  ekf.start(t0, Pose3(x0.T_w_b.R, x0.T_w_b.p + start_offset_m), x0.v_w, ImuBias());
  std::vector<UpdateStats> stats;
  std::size_t i = 0, r = 0;
  while (i < s.imu.size() && s.imu[i].t_ns < t0) ++i;
  while (i < s.imu.size() || r < s.ranges.size()) {
    if (r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns)) {
      ekf.addRange(s.ranges[r++]);
    } else {
      ekf.addImu(s.imu[i++]);
    }
    stats.clear();
    if (ekf.process(&stats) > 0 && !on_updates(stats)) return;
  }
}

FilterRun runFromTruth(const sim::Scenario& s, const std::string& loss) {
  EkfEstimator ekf(s.p_w_anchors, testing::graphParamsFor(s, loss));
  FilterRun run;
  feed(ekf, s, Vec3::Zero(), [&](const std::vector<UpdateStats>&) {
    const double e = (ekf.latest().T_w_b.p - s.truthAt(ekf.latest().t_ns).T_w_b.p).norm();
    run.mean_error_m += e;
    run.max_error_m = std::max(run.max_error_m, e);
    ++run.updates;
    return true;
  });
  if (run.updates > 0) run.mean_error_m /= run.updates;
  return run;
}

TEST(EkfEstimator, TracksACleanWalkFromTheTruth) {
  sim::ScenarioParams sp;
  sp.duration_s = 30.0;
  sp.seed = 3;
  sp.nlos_fraction = 0.0;
  const sim::Scenario s = sim::simulateScenario(sp);
  const FilterRun run = runFromTruth(s, "gaussian");
  EXPECT_GT(run.updates, 800);
  EXPECT_LT(run.mean_error_m, 0.3);  // measured 0.21 m (max 0.67)
}

TEST(EkfEstimator, TracksThroughNlosWithTheAsymmetricLoss) {
  sim::ScenarioParams sp;
  sp.duration_s = 30.0;
  sp.seed = 3;
  const sim::Scenario s = sim::simulateScenario(sp);
  const FilterRun run = runFromTruth(s, "asymmetric");
  EXPECT_GT(run.updates, 800);
  EXPECT_LT(run.mean_error_m, 0.7);  // measured 0.46 m (max 1.5)
}

TEST(EkfEstimator, GroupsMostlyGatedCountAsRejectedSteps) {
  sim::ScenarioParams sp;
  sp.duration_s = 10.0;
  sp.seed = 3;
  sp.nlos_fraction = 0.0;
  const sim::Scenario s = sim::simulateScenario(sp);
  const RangeImuGraphParams gp = testing::graphParamsFor(s, "gaussian");
  // Healthy: started at the truth, (nearly) every group is accepted.
  // Lock lost: started 6 m off with a confident covariance, the gate refuses the ranges.
  for (const double offset_m : {0.0, 6.0}) {
    EkfEstimator ekf(s.p_w_anchors, gp);
    std::vector<UpdateStats> stats;
    feed(ekf, s, Vec3(offset_m, 0.0, 0.0), [&](const std::vector<UpdateStats>& st) {
      stats.insert(stats.end(), st.begin(), st.end());
      return stats.size() < 100;
    });
    ASSERT_GE(stats.size(), 100u);
    int rejected = 0;
    for (const UpdateStats& st : stats) rejected += !st.step_accepted;
    if (offset_m == 0.0) {
      EXPECT_LT(rejected, 5) << "healthy tracking";
    } else {
      // Measured 81 of 100 (a lucky single range passes now and then).
      EXPECT_GT(rejected, 70) << "a filter that gates most measurements reports rejected steps";
    }
  }
}

TEST(EkfEstimator, HeightBandPullsTheFilterBackIntoTheBand) {
  ErrorStateEkf ekf;
  EkfState x;
  x.p_w_b = Vec3(1.0, 2.0, 0.2);  // below a 0.9-1.9 m band
  ekf.initialize(0, x, Mat15::Identity() * 0.25);
  ASSERT_TRUE(ekf.applyHeightBand(0.9, 1.9, 0.1));
  EXPECT_GT(ekf.state().p_w_b.z(), 0.8);
  EXPECT_NEAR(ekf.state().p_w_b.x(), 1.0, 1e-12) << "a height prior moves nothing horizontal";
  EXPECT_LT(ekf.covariance()(5, 5), 0.25);
  EXPECT_EQ(ekf.counters().height_band.accepted, 1u);
  // Inside the band: nothing.
  const Mat15 P = ekf.covariance();
  x.p_w_b.z() = 1.2;
  ekf.initialize(0, x, P);
  EXPECT_FALSE(ekf.applyHeightBand(0.9, 1.9, 0.1));
  EXPECT_EQ(ekf.state().p_w_b.z(), 1.2);
  EXPECT_THROW(ekf.applyHeightBand(2.0, 1.0, 0.1), std::invalid_argument);
  EXPECT_THROW(ekf.applyHeightBand(0.9, 1.9, 0.0), std::invalid_argument);
}

TEST(EkfEstimator, VerticalSpeedPriorPullsOnlyTheVerticalVelocity) {
  ErrorStateEkf ekf;
  EkfState x;
  x.v_w = Vec3(1.0, -0.5, 0.8);
  ekf.initialize(0, x, Mat15::Identity() * 0.25);
  ekf.applyVerticalSpeedPrior(0.1);
  // Kalman gain on v_z alone: 0.25 / (0.25 + 0.01) of the 0.8 m/s goes.
  EXPECT_NEAR(ekf.state().v_w.z(), 0.8 * 0.01 / 0.26, 1e-9);
  EXPECT_NEAR(ekf.state().v_w.x(), 1.0, 1e-12) << "uncorrelated states stay";
  EXPECT_NEAR(ekf.state().v_w.y(), -0.5, 1e-12);
  EXPECT_NEAR(ekf.covariance()(8, 8), 0.25 * 0.01 / 0.26, 1e-9);
  EXPECT_EQ(ekf.covariance()(6, 6), 0.25);
  EXPECT_EQ(ekf.counters().vertical_speed.accepted, 1u);
  // Never gated: a 20 m/s vertical speed is pulled too.
  x.v_w.z() = 20.0;
  ekf.initialize(0, x, Mat15::Identity() * 0.25);
  ekf.applyVerticalSpeedPrior(0.1);
  EXPECT_LT(ekf.state().v_w.z(), 1.0);
  EXPECT_THROW(ekf.applyVerticalSpeedPrior(0.0), std::invalid_argument);
}

TEST(EkfEstimator, ZeroVelocityPriorPullsEveryAxisAsOneUpdate) {
  ErrorStateEkf ekf;
  EkfState x;
  x.v_w = Vec3(1.0, -0.5, 0.8);
  Mat15 P = Mat15::Identity() * 0.25;
  P(6, 3) = P(3, 6) = 0.1;  // v_x correlated with p_x: the position follows
  ekf.initialize(0, x, P);
  ekf.applyZeroVelocityPrior(0.1);
  // Each axis keeps 0.01 / 0.26 of its speed (uncorrelated axes, diagonal noise).
  EXPECT_NEAR(ekf.state().v_w.x(), 1.0 * 0.01 / 0.26, 1e-9);
  EXPECT_NEAR(ekf.state().v_w.y(), -0.5 * 0.01 / 0.26, 1e-9);
  EXPECT_NEAR(ekf.state().v_w.z(), 0.8 * 0.01 / 0.26, 1e-9);
  EXPECT_NEAR(ekf.state().p_w_b.x(), 0.1 / 0.26 * -1.0, 1e-9) << "the correlated position moves with it";
  EXPECT_NEAR(ekf.state().p_w_b.y(), 0.0, 1e-12);
  for (int k = 6; k < 9; ++k) EXPECT_NEAR(ekf.covariance()(k, k), 0.25 * 0.01 / 0.26, 1e-9);
  EXPECT_EQ(ekf.counters().zero_velocity.accepted, 1u);
  EXPECT_EQ(ekf.counters().vertical_speed.accepted, 0u);
  // The same as three vertical-style scalar updates: symmetric, positive definite.
  EXPECT_LT((ekf.covariance() - ekf.covariance().transpose()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat15>(ekf.covariance()).eigenvalues().minCoeff(), 0.0);
  EXPECT_THROW(ekf.applyZeroVelocityPrior(0.0), std::invalid_argument);
  EXPECT_THROW(ekf.applyZeroVelocityPrior(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  ErrorStateEkf uninitialized;
  EXPECT_THROW(uninitialized.applyZeroVelocityPrior(0.1), std::logic_error);
}

// The graph's standstill prior, once per group, for groups the IMU shows still.
TEST(EkfEstimator, ZeroVelocityPriorOnGroupsTheImuShowsStill) {
  sim::ScenarioParams sp;
  sp.duration_s = 12.0;
  sp.seed = 3;
  const sim::Scenario s = testing::withRestingImu(sim::simulateScenario(sp), 4.0, 8.0);
  for (const double sigma : {0.0, 0.05}) {
    RangeImuGraphParams gp = testing::graphParamsFor(s, "asymmetric");
    gp.zero_velocity_sigma_m_s = sigma;
    gp.standstill.max_speed_m_s = std::numeric_limits<double>::infinity();  // only the IMU rests, not the truth
    EkfEstimator ekf(s.p_w_anchors, gp);
    std::uint64_t groups = 0, still_groups = 0, priors_in_walk = 0, priors_before = 0;
    feed(ekf, s, Vec3::Zero(), [&](const std::vector<UpdateStats>& st) {
      const std::uint64_t priors = ekf.filter().counters().zero_velocity.accepted;
      const double t = 1e-9 * static_cast<double>(ekf.latest().t_ns - s.t0_ns);
      groups += st.size();
      if (t > 4.6 && t < 8.0) still_groups += st.size();
      if ((t < 4.0 || t > 8.6) && priors > priors_before) ++priors_in_walk;
      priors_before = priors;
      return true;
    });
    const std::uint64_t priors = ekf.filter().counters().zero_velocity.accepted;
    EXPECT_GT(groups, 300u);
    if (sigma == 0.0) {
      EXPECT_EQ(priors, 0u);
    } else {
      EXPECT_GE(priors, still_groups) << "every still group";
      EXPECT_LE(priors, still_groups + 30) << "and the window's edges, no more";
      EXPECT_EQ(priors_in_walk, 0u);
    }
  }
  RangeImuGraphParams bad = testing::graphParamsFor(s, "asymmetric");
  bad.zero_velocity_sigma_m_s = -1.0;
  EXPECT_THROW(EkfEstimator(s.p_w_anchors, bad), std::invalid_argument);
}

// TDoA rows within same_state_window_ns are one joint update when the group
// closes (EkfParams::tdoa_group_update), as the graph puts them on one state;
// off, each row updates on arrival.
TEST(EkfEstimator, TdoaRowsOfAGroupAreOneJointUpdateAtItsClose) {
  const std::vector<Vec3> anchors = {Vec3(0, 0, 2.5), Vec3(10, 0, 2.4), Vec3(10, 8, 2.6), Vec3(0, 8, 2.5),
                                     Vec3(5, 0, 0.5)};
  RangeImuGraphParams gp;
  gp.same_state_window_ns = 25'000'000;
  const Vec3 p_w_b(4.0, 3.0, 1.2);
  auto diff = [&](std::uint32_t a, std::uint32_t b) {
    return (p_w_b - anchors[b]).norm() - (p_w_b - anchors[a]).norm();
  };
  auto imuAt = [](std::int64_t t_ns) {
    ImuSample s;
    s.t_ns = t_ns;
    s.gyro_rad_s = Vec3::Zero();
    s.accel_m_s2 = Vec3(0.0, 0.0, 9.81);
    return s;
  };
  for (const bool grouped : {true, false}) {
    EkfParams ep;
    ep.tdoa_group_update = grouped;
    EkfEstimator ekf(anchors, gp, ep);
    ekf.start(0, Pose3(Mat3::Identity(), p_w_b), Vec3::Zero(), ImuBias());
    std::int64_t t = 0;
    for (; t <= 100'000'000; t += 5'000'000) ekf.addImu(imuAt(t));
    // Four chained rows within 20 ms, then IMU past the window.
    const std::uint32_t chain[5] = {0, 1, 2, 3, 4};
    for (int k = 0; k < 4; ++k) {
      ekf.addTdoa(testing::tdoaRow(t + k * 5'000'000, chain[k], chain[k + 1], diff(chain[k], chain[k + 1])));
    }
    ekf.addImu(imuAt(t + 20'000'000));  // rows applied (their times passed), group still open
    EXPECT_EQ(ekf.filter().counters().tdoa.attempted(), grouped ? 0u : 4u) << grouped;
    std::vector<UpdateStats> stats;
    EXPECT_EQ(ekf.process(&stats), 0) << grouped;
    ekf.addImu(imuAt(t + 60'000'000));  // past the window: the group closes
    EXPECT_EQ(ekf.filter().counters().tdoa.accepted, 4u) << grouped;
    ASSERT_EQ(ekf.process(&stats), 1) << grouped;
    EXPECT_EQ(stats[0].factors_added, 4) << grouped;
    EXPECT_TRUE(stats[0].step_accepted) << grouped;
    // Grouped: the state when the group closed (the filter had moved on to the
    // IMU sample at +20 ms, inside the window: the graph's one state per group
    // smears its rows over the window the same way); sequential: the newest row's.
    EXPECT_EQ(ekf.latest().t_ns, t + (grouped ? 20'000'000 : 15'000'000)) << grouped;
    EXPECT_LT((ekf.latest().T_w_b.p - p_w_b).norm(), 1e-3) << grouped;  // exact rows, standing still
  }
}

}  // namespace
}  // namespace rilo
