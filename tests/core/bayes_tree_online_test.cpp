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

namespace rilo {
namespace {

struct OnlineFigures {
  double mean_error_m = 0.0;
  double mean_tries = 0.0;
  int rejected = 0;
  int updates = 0;
};

/// The 20 s walk (seed 5, the scenario's default NLOS) both tests below run.
sim::Scenario walk() {
  sim::ScenarioParams sp;
  sp.duration_s = 20.0;
  sp.seed = 5;
  return sim::simulateScenario(sp);
}

OnlineFigures runWalk(SmootherParams params) {
  const sim::Scenario s = walk();
  params.lag_s = 5.0;
  RangeImuEstimator estimator(s.p_w_anchors, testing::graphParamsFor(s), std::make_unique<BayesTreeSmoother>(params));
  OnlineFigures fig;
  int n = 0;
  testing::runOnline(s, estimator, [&](const UpdateStats& st, const RangeImuEstimator& e) {
    fig.mean_error_m += (e.latest().T_w_b.p - s.truthAt(e.latest().t_ns).T_w_b.p).norm();
    fig.mean_tries += st.step_tries;
    fig.rejected += st.step_accepted ? 0 : 1;
    ++n;
  });
  fig.updates = n;
  fig.mean_error_m /= n;
  fig.mean_tries /= n;
  return fig;
}

TEST(BayesTreeOnline, DampedFactorsAcceptanceTracksLikeGaussNewtonInAboutOneTry) {
  // The default D-iSAM2 acceptance looks at the damped variables' factors:
  // on a walk with NLOS it must neither reject good steps (the failure of the
  // whole-graph test with stale linearization points: 1.5-2.5% of updates)
  // nor cost retries.
  SmootherParams gn;
  gn.method = SmootherParams::Method::kGaussNewton;
  SmootherParams damped;  // defaults: D-iSAM2, kDampedFactors
  const OnlineFigures a = runWalk(gn);
  const OnlineFigures b = runWalk(damped);
  EXPECT_LT(a.mean_error_m, 0.5);
  EXPECT_LE(b.mean_error_m, 1.1 * a.mean_error_m + 0.01) << "iSAM2 " << a.mean_error_m;
  EXPECT_LE(b.rejected, b.updates / 100) << "of " << b.updates;
  EXPECT_LT(b.mean_tries, 1.5);
}

struct AfterRejection {
  int rejections = 0;
  int whole_tree_refreshes = 0;  ///< updates after a rejection that re-eliminated >= 90% of a grown tree
  int largest_refresh = 0;       ///< most cliques re-eliminated by an update after a rejection
  int largest_tree = 0;
  double mean_error_m = 0.0;
};

AfterRejection runWithRejections(double after_rejection_max_age_s) {
  // One damped try per update (lambda_max = lambda_initial): rejections are
  // frequent, so the update after one is exercised many times.
  const sim::Scenario s = walk();
  SmootherParams params;
  params.lag_s = 5.0;
  params.d_isam2.lambda_initial = 1e-5;
  params.d_isam2.lambda_max = 1e-5;
  params.after_rejection_max_age_s = after_rejection_max_age_s;
  auto owned = std::make_unique<BayesTreeSmoother>(params);
  BayesTreeSmoother& smoother = *owned;
  RangeImuEstimator estimator(s.p_w_anchors, testing::graphParamsFor(s), std::move(owned));
  AfterRejection r;
  bool previous_rejected = false;
  int n = 0;
  testing::runOnline(s, estimator, [&](const UpdateStats& st, const RangeImuEstimator& e) {
    ASSERT_EQ(smoother.checkInvariants(), "");
    if (previous_rejected) {
      r.largest_refresh = std::max(r.largest_refresh, st.cliques_reeliminated);
      r.largest_tree = std::max(r.largest_tree, st.cliques_total);
      // (A tree of a few cliques, at the start, is all young.)
      if (st.cliques_total >= 20 && st.cliques_reeliminated >= 0.9 * st.cliques_total) ++r.whole_tree_refreshes;
    }
    previous_rejected = !st.step_accepted;
    r.rejections += previous_rejected ? 1 : 0;
    r.mean_error_m += (e.latest().T_w_b.p - s.truthAt(e.latest().t_ns).T_w_b.p).norm();
    ++n;
  });
  r.mean_error_m /= std::max(n, 1);
  return r;
}

TEST(BayesTreeOnline, TheRefreshAfterARejectionCanBeBoundedToTheYoungStates) {
  // SmootherParams::after_rejection_max_age_s: after a rejected D-iSAM2 step
  // the whole window is relinearized at the kept estimate (every state is in
  // the chain to the root: the whole tree is re-eliminated, the real-time
  // tail); bounded, only the last second's states are, and the tree below
  // them stays.
  const AfterRejection whole = runWithRejections(0.0);
  const AfterRejection bounded = runWithRejections(1.0);
  ASSERT_GE(whole.rejections, 5);
  ASSERT_GE(bounded.rejections, 5);
  EXPECT_GE(whole.whole_tree_refreshes, whole.rejections / 2) << "of " << whole.rejections;
  EXPECT_EQ(bounded.whole_tree_refreshes, 0) << "of " << bounded.rejections;
  EXPECT_LT(bounded.largest_refresh, bounded.largest_tree / 2) << "tree " << bounded.largest_tree;
  // Both keep tracking the walk.
  EXPECT_LT(whole.mean_error_m, 0.6);
  EXPECT_LT(bounded.mean_error_m, 0.6);
}

}  // namespace
}  // namespace rilo
