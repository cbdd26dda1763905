// BayesTreeSmoother against dense and batch references on the Ranging-IMU Fusion paper's range +
// IMU graphs fed state by state.
#include <gtest/gtest.h>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/smoother/bayes_tree_smoother.h"
#include "estimation/solver/batch_lm.h"
#include "sim/range_imu_scenario.h"
#include "support/online_run.h"
#include "support/smoother_graphs.h"

namespace rilo {
namespace {

struct Walk {
  sim::Scenario scenario;
  RangeImuGraph graph;
  Values truth;
  Values initial;
};

Walk makeWalk(double seconds, double range_hz, std::uint64_t seed, const std::string& loss = "asymmetric") {
  sim::ScenarioParams sp;
  sp.seed = seed;
  sp.duration_s = seconds;
  sp.range_rate_hz = range_hz;
  Walk w{sim::simulateScenario(sp), {}, {}, {}};
  const RangeImuGraphParams gp = testing::graphParamsFor(w.scenario, loss);
  const sim::KinematicState st0 = w.scenario.truthAt(w.scenario.ranges.front().t_ns);
  w.graph = buildRangeImuGraph(w.scenario.imu, w.scenario.ranges, w.scenario.p_w_anchors, st0.T_w_b, st0.v_w, gp);
  w.truth = sim::truthValues(w.scenario, w.graph.state_t_ns, w.graph.anchor_keys);
  sim::TruthPerturbation perturbation;
  perturbation.seed = seed + 11;
  w.initial = sim::truthValues(w.scenario, w.graph.state_t_ns, w.graph.anchor_keys, &perturbation);
  return w;
}

using testing::exactParams;
using testing::maxRelativeDeltaError;

TEST(BayesTreeSmoother, IncrementalLinearSolutionEqualsDenseWithoutRelinearization) {
  const Walk w = makeWalk(4.0, 10.0, 3);
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial);
  BayesTreeSmoother smoother(exactParams(SmootherParams::Method::kGaussNewton));
  FactorGraph so_far;
  for (std::size_t k = 0; k < increments.size(); ++k) {
    smoother.update(increments[k].factors, increments[k].values);
    for (const auto& f : increments[k].factors) so_far.add(f);
    ASSERT_EQ(smoother.checkInvariants(), "") << "after increment " << k;
    EXPECT_LT(maxRelativeDeltaError(smoother, so_far), 1e-9) << "after increment " << k;
  }
}

TEST(BayesTreeSmoother, ConvergedEstimateMatchesBatchLm) {
  const Walk w = makeWalk(4.0, 20.0, 5, "huber");
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial);
  for (auto method : {SmootherParams::Method::kGaussNewton, SmootherParams::Method::kDamped, SmootherParams::Method::kDogleg}) {
    SmootherParams p;
    p.method = method;
    p.wildfire_threshold = 0.0;
    p.default_pose_threshold.setConstant(1e-10);
    p.default_bias_threshold.setConstant(1e-10);
    p.default_vec3_threshold.setConstant(1e-10);
    BayesTreeSmoother smoother(p);
    for (const auto& inc : increments) {
      smoother.update(inc.factors, inc.values);
      ASSERT_EQ(smoother.checkInvariants(), "");
    }
    for (int i = 0; i < 30; ++i) smoother.update({}, {});
    BatchLevenbergMarquardt lm;
    const auto batch = lm.optimize(w.graph.graph, w.initial);
    ASSERT_TRUE(batch.result.converged());
    double worst = 0.0;
    for (Key k : batch.values.keys()) {
      worst = std::max(worst, localVariable(batch.values.at(k), smoother.estimate(k)).cwiseAbs().maxCoeff());
    }
    EXPECT_LT(worst, 1e-6) << "method " << static_cast<int>(method);
    EXPECT_NEAR(smoother.error(), w.graph.graph.error(batch.values), 1e-6 * w.graph.graph.error(batch.values));
    EXPECT_NEAR(smoother.error(), smoother.errorFromScratch(), 1e-9 * smoother.error());
  }
}

TEST(BayesTreeSmoother, DampedNeverAcceptsAnErrorIncrease) {
  const Walk w = makeWalk(6.0, 40.0, 8);
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial);
  BayesTreeSmoother smoother;  // D-iSAM2 defaults (wildfire, fluid relinearization)
  int tries = 0;
  for (const auto& inc : increments) {
    const UpdateStats st = smoother.update(inc.factors, inc.values);
    EXPECT_LE(st.error_after, st.error_before * (1.0 + 1e-12));
    tries += st.step_tries;
    ASSERT_EQ(smoother.checkInvariants(), "");
  }
  EXPECT_NEAR(smoother.error(), smoother.errorFromScratch(), 1e-9 * smoother.error());
  EXPECT_GE(tries, static_cast<int>(increments.size()));
}

TEST(BayesTreeSmoother, FixedLagMatchesDenseSchurComplementAtSameLinearization) {
  const Walk w = makeWalk(6.0, 10.0, 4);
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  SmootherParams p = exactParams(SmootherParams::Method::kGaussNewton);
  p.lag_s = 1.0;
  BayesTreeSmoother smoother(p);
  FactorGraph all;
  int marginalized = 0;
  for (std::size_t k = 0; k < increments.size(); ++k) {
    const UpdateStats st = smoother.update(increments[k].factors, increments[k].values, increments[k].timestamps);
    marginalized += st.variables_marginalized;
    for (const auto& f : increments[k].factors) all.add(f);
    ASSERT_EQ(smoother.checkInvariants(), "") << "after increment " << k;
    // Without relinearization every variable is linearized at its initial
    // value: the full dense problem restricted to the kept variables is the
    // Schur complement the smoother must hold.
    const auto dense = testing::linearizeDense(all, {}, w.initial);
    const auto reference = testing::solveDense(dense);
    double scale = 1e-12, worst = 0.0;
    for (const auto& [key, x] : reference) {
      if (!smoother.exists(key)) continue;
      scale = std::max(scale, x.cwiseAbs().maxCoeff());
      worst = std::max(worst, (smoother.delta(key) - x).cwiseAbs().maxCoeff());
    }
    EXPECT_LT(worst / scale, 1e-8) << "after increment " << k;
  }
  EXPECT_GT(marginalized, 0);
  EXPECT_FALSE(smoother.linearMarginals().empty());
}

}  // namespace
}  // namespace rilo
