// End to end on the estimation core: a simulated range + IMU walk built into
// the Ranging-IMU Fusion paper's factor graph and solved by batch LM from a perturbed start.
#include <gtest/gtest.h>

#include <cmath>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/solver/batch_lm.h"
#include "evaluation/trajectory_error.h"
#include "sim/range_imu_scenario.h"

namespace rilo {
namespace {

struct Problem {
  sim::Scenario scenario;
  RangeImuGraph graph;
  Values truth;
  Values initial;
};

Problem makeProblem(double seconds, double nlos_fraction, const std::string& loss, std::uint64_t seed) {
  sim::ScenarioParams sp;
  sp.seed = seed;
  sp.duration_s = seconds;
  sp.nlos_fraction = nlos_fraction;
  if (nlos_fraction == 0.0) sp.outlier_probability = 0.0;
  Problem pr{sim::simulateScenario(sp), {}, {}, {}};
  const sim::Scenario& s = pr.scenario;

  RangeImuGraphParams gp;
  gp.p_b_tag = s.p_b_tag;
  gp.range_loss = loss;
  gp.range_noise.sigma_m = sp.range_sigma_m;
  gp.imu = sim::imuParamsOf(sp);
  // The simulator's IMU is exactly zero-order held: no discretization noise to
  // cover, so the statistical check below sees the model's true noise level.
  gp.imu.integration_noise_density = 1e-8;
  gp.first_accel_bias_sigma = 3.0 * sp.accel_bias_init_sigma;
  gp.first_gyro_bias_sigma = 3.0 * sp.gyro_bias_init_sigma;
  const sim::KinematicState st0 = s.truthAt(s.ranges.front().t_ns);
  pr.graph = buildRangeImuGraph(s.imu, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp);

  pr.truth = sim::truthValues(s, pr.graph.state_t_ns, pr.graph.anchor_keys);
  sim::TruthPerturbation perturbation;
  perturbation.seed = seed + 7;
  pr.initial = sim::truthValues(s, pr.graph.state_t_ns, pr.graph.anchor_keys, &perturbation);
  return pr;
}

PositionErrorStats errors(const Problem& pr, const Values& v) {
  std::vector<Vec3> est, tru;
  for (std::size_t i = 0; i < pr.graph.state_t_ns.size(); ++i) {
    est.push_back(v.pose(sym::X(i)).p);
    tru.push_back(pr.truth.pose(sym::X(i)).p);
  }
  return positionErrorStats(est, tru);
}

int tangentDim(const Values& v) {
  int n = 0;
  for (const auto& kv : v) n += variableDim(kv.second);
  return n;
}

TEST(BatchRangeImu, GraphHasOneStatePerRangingTimeAndAllFactors) {
  const Problem pr = makeProblem(5.0, 0.0, "gaussian", 3);
  EXPECT_EQ(pr.graph.range_factors, pr.scenario.ranges.size());
  EXPECT_EQ(pr.graph.imu_factors + 1, pr.graph.state_t_ns.size());
  // 40 Hz ranges, each at its own time, 5 % dropped.
  EXPECT_GT(pr.graph.state_t_ns.size(), 170u);
  EXPECT_LE(pr.graph.state_t_ns.size(), 200u);
  // Every factor is evaluable at the truth with a finite error.
  for (const auto& f : pr.graph.graph) EXPECT_TRUE(std::isfinite(f->error(pr.truth)));
}

TEST(BatchRangeImu, RangingGapGetsImuOnlyStatesAndStaysSolvable) {
  sim::ScenarioParams sp;
  sp.duration_s = 12.0;
  sp.nlos_fraction = 0.0;
  sp.outlier_probability = 0.0;
  sim::Scenario s = sim::simulateScenario(sp);
  // A 4 s blackout in the middle of the walk.
  const std::int64_t gap_start = s.t0_ns + 4'000'000'000, gap_end = s.t0_ns + 8'000'000'000;
  std::erase_if(s.ranges, [&](const RangeSample& r) { return r.t_ns > gap_start && r.t_ns < gap_end; });
  RangeImuGraphParams gp;
  gp.p_b_tag = s.p_b_tag;
  gp.max_state_interval_ns = 400'000'000;
  const sim::KinematicState st0 = s.truthAt(s.ranges.front().t_ns);
  const RangeImuGraph g = buildRangeImuGraph(s.imu, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp);
  for (std::size_t i = 1; i < g.state_t_ns.size(); ++i) {
    ASSERT_GT(g.state_t_ns[i], g.state_t_ns[i - 1]);
    ASSERT_LE(g.state_t_ns[i] - g.state_t_ns[i - 1], gp.max_state_interval_ns);
  }
  EXPECT_EQ(g.imu_factors + 1, g.state_t_ns.size());
  const Values truth = sim::truthValues(s, g.state_t_ns, g.anchor_keys);
  BatchLevenbergMarquardt lm;
  const auto out = lm.optimize(g.graph, truth);
  EXPECT_TRUE(out.result.converged()) << out.result.message;
  std::vector<Vec3> est, tru;
  for (std::size_t i = 0; i < g.state_t_ns.size(); ++i) {
    est.push_back(out.values.pose(sym::X(i)).p);
    tru.push_back(truth.pose(sym::X(i)).p);
  }
  // IMU-only bridging of 4 s with a smoothed bias: well under a metre.
  EXPECT_LT(positionErrorStats(est, tru).ape_3d.max, 1.0);

  RangeImuGraphParams bad = gp;
  bad.same_state_window_ns = -1;
  EXPECT_THROW(buildRangeImuGraph(s.imu, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, bad), std::invalid_argument);
}

TEST(BatchRangeImu, RecoversTrajectoryFromPerturbedStartAndReachesNoiseFloor) {
  const Problem pr = makeProblem(10.0, 0.0, "gaussian", 11);
  const double error_truth = pr.graph.graph.error(pr.truth);
  const double error_initial = pr.graph.graph.error(pr.initial);
  ASSERT_GT(error_initial, 10.0 * error_truth);

  BatchLevenbergMarquardt lm;
  const auto out = lm.optimize(pr.graph.graph, pr.initial);
  ASSERT_TRUE(out.result.converged()) << out.result.message;
  EXPECT_EQ(out.result.indeterminate_factorizations, 0);

  const PositionErrorStats e = errors(pr, out.values);
  EXPECT_LT(e.ape_3d.mean, 0.08) << "3D APE mean";
  EXPECT_LT(e.ape_3d.max, 0.30) << "3D APE max";

  // At the optimum the cost is below the truth's by about half the number of
  // parameters (2 (E_true - E_min) ~ chi^2(n) for a near-linear Gaussian model).
  const double n = tangentDim(out.values);
  const double decrease = error_truth - out.result.final_error;
  EXPECT_NEAR(out.result.final_error, pr.graph.graph.error(out.values), 1e-6 * out.result.final_error);
  EXPECT_GT(decrease, 0.0);
  EXPECT_NEAR(decrease, 0.5 * n, 8.0 * std::sqrt(0.5 * n)) << "n = " << n;
}

TEST(BatchRangeImu, AsymmetricModelBeatsGaussianUnderPersistentNlos) {
  int asymmetric_wins = 0;
  for (std::uint64_t seed : {21u, 22u, 23u}) {
    double ape[2];
    int k = 0;
    for (const char* loss : {"gaussian", "asymmetric"}) {
      const Problem pr = makeProblem(20.0, 0.35, loss, seed);
      BatchLevenbergMarquardt lm;
      const auto out = lm.optimize(pr.graph.graph, pr.initial);
      EXPECT_NE(out.result.status, LmStatus::kNonFiniteError);
      ape[k++] = errors(pr, out.values).ape_3d.mean;
    }
    if (ape[1] < ape[0]) ++asymmetric_wins;
  }
  EXPECT_GE(asymmetric_wins, 2);
}

}  // namespace
}  // namespace rilo
