// BayesTreeSmoother driven online by the range + IMU estimator on a simulated
// walk: the tree's solution must equal the dense least-squares solution of
// everything it holds, at its own linearization point, after every update.
#include <gtest/gtest.h>

#include "estimation/smoother/bayes_tree_smoother.h"
#include "support/online_run.h"
#include "support/smoother_graphs.h"

namespace rilo {
namespace {

TEST(BayesTreeOnline, TreeSolutionEqualsDenseAfterEveryUpdateWithRelinearizationAndLag) {
  sim::ScenarioParams sp;
  sp.duration_s = 5.0;
  sp.range_rate_hz = 20.0;
  sp.nlos_fraction = 0.0;
  sp.outlier_probability = 0.0;
  const sim::Scenario s = sim::simulateScenario(sp);
  SmootherParams params;
  params.method = SmootherParams::Method::kGaussNewton;
  params.wildfire_threshold = 0.0;
  params.lag_s = 1.0;
  auto owned = std::make_unique<BayesTreeSmoother>(params);
  BayesTreeSmoother& smoother = *owned;
  RangeImuEstimator estimator(s.p_w_anchors, testing::graphParamsFor(s, "gaussian", false), std::move(owned));
  int updates = 0;
  testing::runOnline(s, estimator, [&](const UpdateStats&, const RangeImuEstimator&) {
    ++updates;
    ASSERT_EQ(smoother.checkInvariants(), "");
    const testing::DeltaComparison c = testing::compareDeltaWithDense(smoother, smoother.nonlinearFactors());
    ASSERT_LT(c.worst, 1e-9 * std::max(c.scale, 1e-2)) << "update " << updates << " at " << c.worst_key;
  });
  EXPECT_GT(updates, 50);
}

}  // namespace
}  // namespace rilo
