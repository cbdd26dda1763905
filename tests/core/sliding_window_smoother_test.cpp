// SlidingWindowSmoother (IMU-Ultrasonic-UWB paper, Sec. III-C6 / III-D4) against batch
// Levenberg-Marquardt and dense references:
//   - no marginalization (window 0, or longer than the run): the batch optimum;
//   - a linear Gaussian problem: marginalization is exact, so every variable
//     in the window equals the batch solution over everything ever added;
//   - the Ranging-IMU Fusion paper's range + IMU walk: the newest state stays close to batch;
//   - bookkeeping: drained variables, input validation, rank deficiency,
//     covariance, bounded priors, FEJ linearization points.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <map>
#include <random>
#include <set>
#include <string>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/factors/prior_factors.h"
#include "estimation/factors/range_factor.h"
#include "estimation/smoother/sliding_window_smoother.h"
#include "estimation/solver/batch_lm.h"
#include "sim/range_imu_scenario.h"
#include "support/dense_reference.h"
#include "support/incremental_feed.h"
#include "support/online_run.h"
#include "support/smoother_graphs.h"

namespace rilo {
namespace {

using sym::B;
using sym::L;
using sym::V;
using sym::X;
using testing::Increment;

// ------------------------------------------------------------------ helpers

struct Walk {
  sim::Scenario scenario;
  RangeImuGraph graph;
  Values initial;
};

Walk makeWalk(const sim::ScenarioParams& sp, const std::string& loss, std::int64_t same_state_window_ns = 5'000'000) {
  Walk w{sim::simulateScenario(sp), {}, {}};
  RangeImuGraphParams gp = testing::graphParamsFor(w.scenario, loss);
  gp.same_state_window_ns = same_state_window_ns;
  const sim::KinematicState st0 = w.scenario.truthAt(w.scenario.ranges.front().t_ns);
  w.graph = buildRangeImuGraph(w.scenario.imu, w.scenario.ranges, w.scenario.p_w_anchors, st0.T_w_b, st0.v_w, gp);
  sim::TruthPerturbation perturbation;
  perturbation.seed = sp.seed + 11;
  w.initial = sim::truthValues(w.scenario, w.graph.state_t_ns, w.graph.anchor_keys, &perturbation);
  return w;
}

Walk makeWalk(double seconds, double range_hz, std::uint64_t seed, const std::string& loss) {
  sim::ScenarioParams sp;
  sp.seed = seed;
  sp.duration_s = seconds;
  sp.range_rate_hz = range_hz;
  return makeWalk(sp, loss);
}

/// 10 states per second, each with the 4 ranges of one cycle, line of sight only.
Walk makeCleanWalk(double seconds, std::uint64_t seed) {
  sim::ScenarioParams sp;
  sp.seed = seed;
  sp.duration_s = seconds;
  sp.range_rate_hz = 40.0;
  sp.ranges_per_cycle = 4;
  sp.nlos_fraction = 0.0;
  sp.outlier_probability = 0.0;
  return makeWalk(sp, "huber", 80'000'000);
}

/// Converges each update fully: the references are optima, not iterates.
SlidingWindowParams tightParams(double window_s) {
  SlidingWindowParams p;
  p.window_s = window_s;
  p.max_iterations = 100;
  p.relative_error_tolerance = 1e-14;
  p.absolute_error_tolerance = 1e-14;
  p.step_tolerance = 1e-12;
  p.gradient_tolerance = 1e-12;
  return p;
}

LmParams tightBatch() {
  LmParams p;
  p.max_iterations = 200;
  p.relative_error_tolerance = 1e-14;
  p.absolute_error_tolerance = 1e-14;
  p.step_tolerance = 1e-12;
  p.gradient_tolerance = 1e-12;
  return p;
}

/// Largest tangent difference over the keys both hold; `worst_key` names it.
double worstDifference(const SlidingWindowSmoother& s, const Values& reference, std::string* worst_key = nullptr) {
  double worst = 0.0;
  for (const auto& [key, value] : reference) {
    if (!s.exists(key)) continue;
    const double e = localVariable(value, s.estimate(key)).cwiseAbs().maxCoeff();
    if (e > worst) {
      worst = e;
      if (worst_key) *worst_key = keyString(key);
    }
  }
  return worst;
}

bool allFinite(const Values& values) {
  for (const auto& [key, value] : values) {
    if (const auto* T = std::get_if<Pose3>(&value)) {
      if (!T->R.allFinite() || !T->p.allFinite()) return false;
    } else if (const auto* v = std::get_if<Vec3>(&value)) {
      if (!v->allFinite()) return false;
    } else if (!std::get<ImuBias>(value).vector().allFinite()) {
      return false;
    }
  }
  return true;
}

/// r = (x_b - x_a - d) / sigma on two Vec3 variables: a linear factor.
class Vec3BetweenFactor final : public Factor {
 public:
  Vec3BetweenFactor(Key a, Key b, const Vec3& d, double sigma) : Factor({a, b}), d_(d), inv_sigma_(1.0 / sigma) {}
  int dim() const override { return 3; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    r = inv_sigma_ * (x.vec3(keys()[1]) - x.vec3(keys()[0]) - d_);
    if (H) {
      (*H)[0] = -inv_sigma_ * Mat3::Identity();
      (*H)[1] = inv_sigma_ * Mat3::Identity();
    }
  }

 private:
  Vec3 d_;
  double inv_sigma_;
};

// ------------------------------------------------------------------ params

TEST(SlidingWindowParams, InvalidFieldsThrowNamingTheField) {
  auto expectThrowNaming = [](const char* field, auto edit) {
    SlidingWindowParams p;
    edit(p);
    try {
      SlidingWindowSmoother s(p);
      ADD_FAILURE() << field << ": no exception";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  expectThrowNaming("window_s", [](auto& p) { p.window_s = -1.0; });
  expectThrowNaming("window_s", [](auto& p) { p.window_s = std::nan(""); });
  expectThrowNaming("max_iterations", [](auto& p) { p.max_iterations = 0; });
  expectThrowNaming("lambda_min", [](auto& p) { p.lambda_min = 0.0; });
  expectThrowNaming("lambda_max", [](auto& p) { p.lambda_max = 1e-20; });
  expectThrowNaming("lambda_initial", [](auto& p) { p.lambda_initial = -1.0; });
  expectThrowNaming("min_gain_ratio", [](auto& p) { p.min_gain_ratio = 1.0; });
  expectThrowNaming("relative_error_tolerance", [](auto& p) { p.relative_error_tolerance = -1.0; });
  expectThrowNaming("absolute_error_tolerance", [](auto& p) { p.absolute_error_tolerance = -1.0; });
  expectThrowNaming("step_tolerance", [](auto& p) { p.step_tolerance = -1.0; });
  expectThrowNaming("gradient_tolerance", [](auto& p) { p.gradient_tolerance = -1.0; });
  expectThrowNaming("rank_tolerance", [](auto& p) { p.rank_tolerance = 0.0; });
  expectThrowNaming("indeterminate_pivot_ratio", [](auto& p) { p.indeterminate_pivot_ratio = 1.0; });
  EXPECT_NO_THROW(SlidingWindowSmoother(SlidingWindowParams{}));
}

// ------------------------------------------------------------------ without marginalization: batch

TEST(SlidingWindowSmoother, WholeGraphInOneUpdateEqualsBatchLm) {
  for (const char* loss : {"gaussian", "huber", "asymmetric"}) {
    const Walk w = makeWalk(4.0, 20.0, 3, loss);
    SlidingWindowSmoother smoother(tightParams(0.0));
    const UpdateStats st = smoother.update(w.graph.graph, w.initial);
    EXPECT_EQ(st.variables_added, static_cast<int>(w.initial.size()));
    EXPECT_EQ(st.factors_added, static_cast<int>(w.graph.graph.size()));
    EXPECT_EQ(st.variables_marginalized, 0);
    EXPECT_TRUE(st.step_accepted);
    EXPECT_GT(st.step_tries, 1);
    EXPECT_LT(st.error_after, st.error_before);
    BatchLevenbergMarquardt lm(tightBatch());
    const auto batch = lm.optimize(w.graph.graph, w.initial);
    ASSERT_TRUE(batch.result.converged()) << batch.result.message;
    std::string worst_key;
    EXPECT_LT(worstDifference(smoother, batch.values, &worst_key), 1e-8) << loss << " at " << worst_key;
    EXPECT_NEAR(smoother.error(), batch.result.final_error, 1e-9 * batch.result.final_error) << loss;
    EXPECT_NEAR(smoother.error(), smoother.errorFromScratch(), 1e-9 * smoother.error());
    // Same Hessian at the same optimum: same marginal covariance (up to the
    // conditioning of J^T J, ~1e9, under two elimination orders).
    for (Key key : {X(0), V(10), B(20), w.graph.anchor_keys.front()}) {
      const auto sw = smoother.marginalCovariance(key);
      const auto lm_cov = lm.marginalCovariance(key);
      ASSERT_TRUE(sw.has_value() && lm_cov.has_value()) << keyString(key);
      EXPECT_LT((Eigen::MatrixXd(*sw) - Eigen::MatrixXd(*lm_cov)).cwiseAbs().maxCoeff(),
                1e-5 * Eigen::MatrixXd(*lm_cov).cwiseAbs().maxCoeff())
          << loss << " " << keyString(key);
    }
  }
}

TEST(SlidingWindowSmoother, StateByStateWithoutMarginalizationConvergesToBatch) {
  // window 0 (keep everything) and a window longer than the run: same thing.
  const Walk w = makeWalk(4.0, 20.0, 5, "huber");
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  BatchLevenbergMarquardt lm(tightBatch());
  const auto batch = lm.optimize(w.graph.graph, w.initial);
  ASSERT_TRUE(batch.result.converged()) << batch.result.message;
  for (double window : {0.0, 100.0}) {
    SlidingWindowSmoother smoother(tightParams(window));
    for (const Increment& inc : increments) {
      const UpdateStats st = smoother.update(inc.factors, inc.values, inc.timestamps);
      ASSERT_EQ(st.variables_marginalized, 0);
      EXPECT_LE(st.error_after, st.error_before * (1.0 + 1e-12));
      EXPECT_NEAR(smoother.error(), smoother.errorFromScratch(), 1e-9 * std::max(1.0, smoother.error()));
    }
    smoother.update({}, {});  // one more pass: the last update converged to its own optimum already
    EXPECT_EQ(smoother.variableCount(), static_cast<int>(w.initial.size()));
    std::string worst_key;
    EXPECT_LT(worstDifference(smoother, batch.values, &worst_key), 1e-7) << "window " << window << " at " << worst_key;
    EXPECT_NEAR(smoother.error(), batch.result.final_error, 1e-9 * batch.result.final_error);
    std::vector<std::pair<Key, Variable>> drained;
    smoother.drainMarginalized(drained);
    EXPECT_TRUE(drained.empty());
  }
}

TEST(SlidingWindowSmoother, UpdateWithoutChangesReusesTheSymbolicAnalysis) {
  const Walk w = makeWalk(2.0, 20.0, 6, "huber");
  SlidingWindowSmoother smoother(tightParams(0.0));
  smoother.update(w.graph.graph, w.initial);
  const int analyses = smoother.symbolicAnalyses();
  EXPECT_EQ(analyses, 1);
  const UpdateStats st = smoother.update({}, {});
  EXPECT_EQ(smoother.symbolicAnalyses(), analyses);
  EXPECT_LE(st.step_tries, 1);  // already converged
  ASSERT_TRUE(smoother.marginalCovariance(X(3)).has_value());
  EXPECT_EQ(smoother.symbolicAnalyses(), analyses);
}

// ------------------------------------------------------------------ linear Gaussian: exact marginalization

struct LinearChain {
  FactorGraph all;
  std::vector<Increment> increments;
};

/// Vec3 states every 0.1 s linked by between factors, a prior on the first,
/// noisy absolute fixes on some, and two untimed "anchor" variables tied to
/// many states (they stay in the window and collect the priors).
LinearChain makeLinearChain(int states, std::uint64_t seed) {
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::normal_distribution<double> n01(0.0, 1.0);
  auto noise = [&](double s) { return Vec3(s * n01(rng), s * n01(rng), s * n01(rng)); };
  LinearChain c;
  c.increments.resize(static_cast<std::size_t>(states));
  Vec3 truth = Vec3::Zero();
  const Vec3 anchor_truth[2] = {Vec3(3, -1, 2), Vec3(-2, 4, 1)};
  for (int i = 0; i < states; ++i) {
    Increment& inc = c.increments[static_cast<std::size_t>(i)];
    auto add = [&](FactorPtr f) {
      inc.factors.add(f);
      c.all.add(f);
    };
    const Vec3 step = noise(0.5);
    if (i == 0) {
      add(std::make_shared<PriorVec3Factor>(X(0), Vec3(truth + noise(0.1)), Vec3(Vec3::Constant(0.1))));
      for (int j = 0; j < 2; ++j) {
        add(std::make_shared<PriorVec3Factor>(L(j), Vec3(anchor_truth[j] + noise(0.3)), Vec3(Vec3::Constant(0.3))));
        inc.values.insert(L(j), Variable(Vec3(anchor_truth[j] + noise(1.0))));
      }
    } else {
      truth += step;
      add(std::make_shared<Vec3BetweenFactor>(X(i - 1), X(i), step + noise(0.05), 0.05));
    }
    if (i % 3 == 1) add(std::make_shared<PriorVec3Factor>(X(i), Vec3(truth + noise(0.2)), Vec3(Vec3::Constant(0.2))));
    if (i % 2 == 0) add(std::make_shared<Vec3BetweenFactor>(X(i), L(i / 2 % 2), Vec3(anchor_truth[i / 2 % 2] - truth + noise(0.1)), 0.1));
    inc.values.insert(X(i), Variable(Vec3(truth + noise(2.0))));
    inc.timestamps[X(i)] = 100'000'000LL * i;
  }
  return c;
}

TEST(SlidingWindowSmoother, LinearProblemWindowEqualsBatchSolutionExactly) {
  for (bool fej : {true, false}) {
    const LinearChain c = makeLinearChain(40, 17);
    SlidingWindowParams p = tightParams(0.35);
    p.first_estimate_jacobians = fej;
    SlidingWindowSmoother smoother(p);
    FactorGraph so_far;
    Values initial_so_far;
    int marginalized = 0, drained_checked = 0;
    for (std::size_t k = 0; k < c.increments.size(); ++k) {
      const Increment& inc = c.increments[k];
      const UpdateStats st = smoother.update(inc.factors, inc.values, inc.timestamps);
      marginalized += st.variables_marginalized;
      for (const FactorPtr& f : inc.factors) so_far.add(f);
      for (const auto& [key, value] : inc.values) initial_so_far.insert(key, value);
      // Linear least squares over everything so far (one Gauss-Newton step is exact).
      const auto dense = testing::linearizeDense(so_far, {}, initial_so_far);
      const auto delta = testing::solveDense(dense);
      double worst = 0.0, scale = 1.0;
      for (const auto& [key, d] : delta) {
        const Vec3 batch = initial_so_far.vec3(key) + d;
        scale = std::max(scale, batch.cwiseAbs().maxCoeff());
        if (smoother.exists(key)) worst = std::max(worst, (std::get<Vec3>(smoother.estimate(key)) - batch).cwiseAbs().maxCoeff());
      }
      EXPECT_LT(worst / scale, 1e-10) << "fej " << fej << ", update " << k;
      // A drained state is its estimate when it left: the batch solution of this update.
      std::vector<std::pair<Key, Variable>> drained;
      smoother.drainMarginalized(drained);
      for (const auto& [key, value] : drained) {
        const Vec3 batch = initial_so_far.vec3(key) + delta.at(key);
        EXPECT_LT((std::get<Vec3>(value) - batch).cwiseAbs().maxCoeff() / scale, 1e-10) << keyString(key);
        ++drained_checked;
      }
      // The newest variable's covariance is the batch one too.
      if (k % 5 == 4) {
        const Eigen::MatrixXd info = dense.A.transpose() * dense.A;
        const Eigen::MatrixXd cov = info.inverse();
        const int off = dense.offset.at(X(k));
        const auto sw = smoother.marginalCovariance(X(k));
        ASSERT_TRUE(sw.has_value());
        EXPECT_LT((Eigen::MatrixXd(*sw) - cov.block(off, off, 3, 3)).cwiseAbs().maxCoeff(), 1e-9 * cov.block(off, off, 3, 3).norm());
      }
      EXPECT_LE(smoother.linearMarginals().size(), 1u);
      EXPECT_TRUE(smoother.exists(L(0)) && smoother.exists(L(1)));
    }
    EXPECT_EQ(marginalized, 40 - 4);  // 0.35 s at 0.1 s: the newest four states stay
    EXPECT_EQ(drained_checked, marginalized);
    EXPECT_EQ(smoother.variableCount(), 4 + 2);
  }
}

// ------------------------------------------------------------------ range + IMU walk against batch

// The reference is the batch optimum of everything fed so far, warm-started
// from the previous check's optimum (new variables at the values the
// smoother got). Early in a walk the yaw is barely observable (sigma
// 0.2-0.5 rad over the first seconds): there a fixed-lag smoother, whose
// priors are linear in the yaw it had when states left, and a batch that
// relinearizes everything may differ by a good part of a sigma. Position and
// tilt are compared tightly, yaw against the smoother's own sigma.

/// Forwards to a SlidingWindowSmoother and records what it is fed.
class RecordingSmoother final : public Smoother {
 public:
  explicit RecordingSmoother(const SlidingWindowParams& p) : inner(p) {}
  UpdateStats update(const FactorGraph& f, const Values& v, const KeyTimestamps& t) override {
    const UpdateStats st = inner.update(f, v, t);
    for (const FactorPtr& factor : f) all.add(factor);
    for (const auto& [key, value] : v) fed.insert(key, value);
    return st;
  }
  Values estimate() const override { return inner.estimate(); }
  Variable estimate(Key key) const override { return inner.estimate(key); }
  bool exists(Key key) const override { return inner.exists(key); }
  std::optional<CovarianceBlock> marginalCovariance(Key key, std::string* failure) override {
    return inner.marginalCovariance(key, failure);
  }
  double error() const override { return inner.error(); }
  void drainMarginalized(std::vector<std::pair<Key, Variable>>& out) override { inner.drainMarginalized(out); }

  SlidingWindowSmoother inner;
  FactorGraph all;
  Values fed;  // initial values as fed
};

struct WalkFigures {
  double worst_position_m = 0.0;
  double mean_position_m = 0.0;
  double worst_tilt_rad = 0.0;
  double worst_yaw_sigmas = 0.0;  ///< |yaw difference| / the smoother's yaw sigma
  int marginalized = 0;
  int checks = 0;
};

/// Compares the newest state of `s` with the batch optimum (see above);
/// `reference` carries the warm start from check to check.
void compareNewest(RecordingSmoother& s, Key newest, Values& reference, WalkFigures& fig) {
  for (const auto& [key, value] : s.fed) {
    if (!reference.exists(key)) reference.insert(key, value);
  }
  BatchLevenbergMarquardt lm(tightBatch());
  const auto batch = lm.optimize(s.all, reference);
  EXPECT_TRUE(batch.result.converged()) << batch.result.message;
  reference = batch.values;
  ASSERT_TRUE(s.exists(newest));
  const Pose3& T_batch = batch.values.pose(newest);
  const Pose3 T_sw = std::get<Pose3>(s.estimate(newest));
  const double dp = (T_batch.p - T_sw.p).norm();
  const Vec3 e_w = so3::log(T_sw.R * T_batch.R.transpose());  // world frame: x, y tilt, z yaw
  std::string why;
  const auto cov = s.marginalCovariance(newest, &why);
  ASSERT_TRUE(cov.has_value()) << why;
  // Yaw variance in the world frame from the body-frame rotation block.
  const Vec3 z_b = T_sw.R.transpose().col(2);
  const double yaw_sigma = std::sqrt(z_b.dot(cov->topLeftCorner(3, 3) * z_b));
  fig.worst_position_m = std::max(fig.worst_position_m, dp);
  fig.mean_position_m += dp;
  fig.worst_tilt_rad = std::max(fig.worst_tilt_rad, e_w.head<2>().norm());
  fig.worst_yaw_sigmas = std::max(fig.worst_yaw_sigmas, std::abs(e_w.z()) / yaw_sigma);
  ++fig.checks;
  EXPECT_TRUE(allFinite(s.estimate()));
}

/// State-by-state increments of a batch graph (initial values: the perturbed truth).
WalkFigures runIncrements(const Walk& w, const SlidingWindowParams& p, int check_every) {
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  RecordingSmoother smoother(p);
  Values reference;
  WalkFigures fig;
  for (std::size_t k = 0; k < increments.size(); ++k) {
    const Increment& inc = increments[k];
    fig.marginalized += smoother.update(inc.factors, inc.values, inc.timestamps).variables_marginalized;
    EXPECT_NEAR(smoother.error(), smoother.inner.errorFromScratch(), 1e-8 * std::max(1.0, smoother.error()))
        << "update " << k;
    if (k % static_cast<std::size_t>(check_every) == 0 || k + 1 == increments.size()) {
      compareNewest(smoother, X(k), reference, fig);
    }
  }
  fig.mean_position_m /= std::max(1, fig.checks);
  return fig;
}

/// Online through RangeImuEstimator: new states predicted by the IMU from the smoother's estimate.
WalkFigures runOnline(const sim::Scenario& s, const SlidingWindowParams& p, int check_every) {
  auto owned = std::make_unique<RecordingSmoother>(p);
  RecordingSmoother& smoother = *owned;
  RangeImuEstimator estimator(s.p_w_anchors, testing::graphParamsFor(s), std::move(owned));
  Values reference;
  WalkFigures fig;
  int updates = 0;
  testing::runOnline(s, estimator, [&](const UpdateStats& st, const RangeImuEstimator& e) {
    fig.marginalized += st.variables_marginalized;
    if (++updates % check_every == 0) compareNewest(smoother, X(e.latest().index), reference, fig);
  });
  fig.mean_position_m /= std::max(1, fig.checks);
  return fig;
}

std::string describe(const WalkFigures& fig) {
  return "position worst " + std::to_string(fig.worst_position_m) + " m, mean " + std::to_string(fig.mean_position_m) +
         " m; tilt worst " + std::to_string(fig.worst_tilt_rad) + " rad; yaw worst " +
         std::to_string(fig.worst_yaw_sigmas) + " sigma; " + std::to_string(fig.checks) + " checks";
}

struct WalkBounds {
  double window_s;
  bool fej;
  double worst_position_m, mean_position_m, tilt_rad, yaw_sigmas;
};

void expectWithin(const WalkFigures& fig, const WalkBounds& b) {
  EXPECT_LT(fig.worst_position_m, b.worst_position_m);
  EXPECT_LT(fig.mean_position_m, b.mean_position_m);
  EXPECT_LT(fig.worst_tilt_rad, b.tilt_rad);
  EXPECT_LT(fig.worst_yaw_sigmas, b.yaw_sigmas);
}

// First-estimate Jacobians are checked on windows of several states only:
// with one state in the window every state is frozen at the estimate of the
// update it arrived in, and on this walk the yaw then drifts 4-8 of its own
// sigmas from the batch (without FEJ: 0.6). See SlidingWindowParams.
TEST(SlidingWindowSmoother, RangeImuWalkStateByStateNewestStaysCloseToBatch) {
  // The fixed-lag Bayes tree's scenario, state by state from perturbed
  // initial values, on a walk that determines its states (4 ranges per
  // state, line of sight): windows of several states and one shorter than a
  // state interval (each state leaves in the update after it came).
  const Walk w = makeCleanWalk(8.0, 4);
  // Measured (worst / mean position, tilt, yaw sigmas): window 2 s 9 / 3 mm,
  // 1.4 mrad, 0.09 (FEJ 22 / 5 mm, 8.5 mrad, 0.56); 0.5 s 14 / 2.7 cm, 8 mrad,
  // 0.5 (FEJ 0.83); 0.05 s 30 / 6 cm, 12 mrad, 0.57.
  for (const WalkBounds& b : {WalkBounds{2.0, false, 0.03, 0.01, 0.01, 1.0}, WalkBounds{2.0, true, 0.05, 0.015, 0.02, 1.5},
                              WalkBounds{0.5, false, 0.25, 0.05, 0.02, 1.5}, WalkBounds{0.5, true, 0.25, 0.05, 0.02, 1.5},
                              WalkBounds{0.05, false, 0.4, 0.1, 0.03, 1.5}}) {
    SlidingWindowParams p;
    p.window_s = b.window_s;
    p.first_estimate_jacobians = b.fej;
    // New states start 0.3 m / 0.05 rad off (not IMU-predicted): IMU errors
    // near 1e9 take 4-6 iterations, and a state left unconverged would be
    // marginalized as it is: here every update converges, so that what is
    // measured is what marginalization costs.
    p.max_iterations = 20;
    p.absolute_error_tolerance = 1e-3;
    const WalkFigures fig = runIncrements(w, p, 4);
    SCOPED_TRACE("window " + std::to_string(b.window_s) + (b.fej ? " FEJ: " : ": ") + describe(fig));
    EXPECT_GT(fig.marginalized, 3 * 55);
    EXPECT_GT(fig.checks, 15);
    expectWithin(fig, b);
  }
}

TEST(SlidingWindowSmoother, RangeImuWalkOnlineNewestStaysCloseToBatch) {
  // The Ranging-IMU Fusion paper's setting (40 Hz ranging with NLOS, asymmetric loss) through the
  // online estimator, service defaults otherwise (1-2 iterations per update).
  // Measured (worst / mean position, tilt, yaw sigmas): window 2 s 7.6 /
  // 2.5 cm, 17 mrad, 0.25 (FEJ 10.8 / 4.2 cm, 17 mrad, 0.82); 0.5 s 8.5 /
  // 3.5 cm, 17 mrad, 0.53; 0.02 s (one state) 9.2 / 4.1 cm, 11 mrad, 0.69.
  sim::ScenarioParams sp;
  sp.duration_s = 8.0;
  sp.seed = 9;
  const sim::Scenario s = sim::simulateScenario(sp);
  for (const WalkBounds& b : {WalkBounds{2.0, false, 0.2, 0.05, 0.03, 1.0}, WalkBounds{2.0, true, 0.25, 0.07, 0.04, 2.0},
                              WalkBounds{0.5, false, 0.2, 0.06, 0.03, 1.5}, WalkBounds{0.02, false, 0.2, 0.08, 0.03, 1.5}}) {
    SlidingWindowParams p;
    p.window_s = b.window_s;
    p.first_estimate_jacobians = b.fej;
    const WalkFigures fig = runOnline(s, p, 25);
    SCOPED_TRACE("window " + std::to_string(b.window_s) + (b.fej ? " FEJ: " : ": ") + describe(fig));
    EXPECT_GT(fig.marginalized, 3 * 200);
    EXPECT_GT(fig.checks, 10);
    expectWithin(fig, b);
  }
}

TEST(SlidingWindowSmoother, OnlineEstimatorTracksTheTruth) {
  // The Ranging-IMU Fusion paper's setting through RangeImuEstimator (states predicted from the
  // smoother's own estimate): the newest state stays near the truth.
  sim::ScenarioParams sp;
  sp.duration_s = 15.0;
  sp.seed = 5;
  const sim::Scenario s = sim::simulateScenario(sp);
  SlidingWindowParams p;
  p.window_s = 2.0;
  RangeImuEstimator estimator(s.p_w_anchors, testing::graphParamsFor(s), std::make_unique<SlidingWindowSmoother>(p));
  double sum_error = 0.0;
  int n = 0, marginalized = 0;
  testing::runOnline(s, estimator, [&](const UpdateStats& st, const RangeImuEstimator& e) {
    sum_error += (e.latest().T_w_b.p - s.truthAt(e.latest().t_ns).T_w_b.p).norm();
    marginalized += st.variables_marginalized;
    ++n;
  });
  EXPECT_GT(n, 400);
  EXPECT_GT(marginalized, 3 * 400);
  EXPECT_LT(sum_error / n, 0.25);
  RecordProperty("mean_online_error_mm", static_cast<int>(1000 * sum_error / n));
}

// ------------------------------------------------------------------ bookkeeping

TEST(SlidingWindowSmoother, DrainMarginalizedReturnsEveryVariableOnceInOrder) {
  const Walk w = makeWalk(5.0, 10.0, 7, "huber");
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  SlidingWindowParams p;
  p.window_s = 0.6;
  SlidingWindowSmoother smoother(p);
  std::vector<std::pair<Key, Variable>> drained;
  int marginalized = 0;
  for (std::size_t k = 0; k < increments.size(); ++k) {
    const UpdateStats st = smoother.update(increments[k].factors, increments[k].values, increments[k].timestamps);
    marginalized += st.variables_marginalized;
    if (k % 3 == 0) {
      const std::size_t before = drained.size();
      smoother.drainMarginalized(drained);
      for (std::size_t i = before; i < drained.size(); ++i) {
        EXPECT_FALSE(smoother.exists(drained[i].first));
        // The final estimate of a marginalized variable is its last estimate in the window.
      }
    }
  }
  smoother.drainMarginalized(drained);
  std::vector<std::pair<Key, Variable>> again;
  smoother.drainMarginalized(again);
  EXPECT_TRUE(again.empty());
  EXPECT_EQ(static_cast<int>(drained.size()), marginalized);
  std::set<Key> seen;
  std::int64_t last_t = std::numeric_limits<std::int64_t>::min();
  for (const auto& [key, value] : drained) {
    EXPECT_TRUE(seen.insert(key).second) << keyString(key) << " drained twice";
    ASSERT_TRUE(testing::isStateKey(key)) << keyString(key) << ": untimed variables are never marginalized";
    const std::int64_t t = w.graph.state_t_ns[keyIndex(key)];
    EXPECT_GE(t, last_t) << keyString(key) << " out of order";
    last_t = t;
  }
  // Every state is either drained or still in the window; nothing else.
  for (const auto& [key, value] : w.initial) {
    if (!testing::isStateKey(key)) {
      EXPECT_TRUE(smoother.exists(key));
      continue;
    }
    EXPECT_NE(seen.count(key) != 0, smoother.exists(key)) << keyString(key);
  }
  EXPECT_TRUE(smoother.exists(X(increments.size() - 1)));
}

TEST(SlidingWindowSmoother, InvalidInputThrowsAndLeavesTheSmootherUnchanged) {
  const Walk w = makeWalk(3.0, 10.0, 10, "huber");
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  SlidingWindowParams p;
  p.window_s = 0.5;
  SlidingWindowSmoother smoother(p);
  SlidingWindowSmoother twin(p);  // gets only the valid input
  for (std::size_t k = 0; k + 1 < increments.size(); ++k) {
    smoother.update(increments[k].factors, increments[k].values, increments[k].timestamps);
    twin.update(increments[k].factors, increments[k].values, increments[k].timestamps);
  }
  ASSERT_FALSE(smoother.exists(X(0)));
  const Values before = smoother.estimate();
  const int factors = smoother.factorCount();
  const double error = smoother.error();
  const Key newest = X(increments.size() - 2);

  auto expectRejected = [&](const std::string& what, const FactorGraph& f, const Values& v, const KeyTimestamps& t,
                            const std::string& mention) {
    SCOPED_TRACE(what);
    try {
      smoother.update(f, v, t);
      ADD_FAILURE() << "accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(mention), std::string::npos) << e.what();
    }
    EXPECT_TRUE(testing::sameValues(before, smoother.estimate()));
    EXPECT_EQ(factors, smoother.factorCount());
    EXPECT_EQ(error, smoother.error());
  };
  {
    FactorGraph f;
    f.emplace<RangeFactor>(X(0), L(0), 3.0, 0.1, Vec3::Zero());
    expectRejected("factor on a marginalized variable", f, {}, {}, keyString(X(0)));
  }
  {
    Values v;
    v.insert(newest, Pose3());
    FactorGraph f;
    f.emplace<PriorPose3Factor>(newest, Pose3(), Vec6(Vec6::Constant(1.0)));
    expectRejected("value for an existing variable", f, v, {}, keyString(newest));
  }
  {
    FactorGraph f;
    f.emplace<RangeFactor>(X(999), L(0), 3.0, 0.1, Vec3::Zero());
    expectRejected("factor key without a value", f, {}, {}, keyString(X(999)));
  }
  {
    Values v;
    v.insert(X(998), Pose3());
    expectRejected("new variable without a factor", {}, v, {}, keyString(X(998)));
  }
  {
    FactorGraph f;
    f.emplace<PriorPose3Factor>(newest, Pose3(), Vec6(Vec6::Constant(1.0)));
    expectRejected("timestamp of an existing variable", f, {}, {{newest, 0}}, keyString(newest));
  }
  {
    Values v;
    v.insert(X(997), Variable(Vec3::Zero()));  // a Vec3 where the factor wants a pose
    FactorGraph f;
    f.emplace<PriorPose3Factor>(X(997), Pose3(), Vec6(Vec6::Constant(1.0)));
    expectRejected("wrong variable type", f, v, {}, keyString(X(997)));
  }
  {
    FactorGraph f;
    f.add(nullptr);
    expectRejected("null factor", f, {}, {}, "null");
  }
  // Afterwards it behaves exactly as if the bad input had never come.
  const Increment& last = increments.back();
  smoother.update(last.factors, last.values, last.timestamps);
  twin.update(last.factors, last.values, last.timestamps);
  EXPECT_TRUE(testing::sameValues(twin.estimate(), smoother.estimate()));
  EXPECT_EQ(twin.error(), smoother.error());
}

TEST(SlidingWindowSmoother, EstimateOfUnknownKeyThrowsAndCovarianceSaysWhy) {
  SlidingWindowSmoother smoother;
  EXPECT_THROW(smoother.estimate(X(0)), std::out_of_range);
  std::string why;
  EXPECT_FALSE(smoother.marginalCovariance(X(0), &why).has_value());
  EXPECT_NE(why.find("unknown"), std::string::npos) << why;
}

// ------------------------------------------------------------------ numerics

TEST(SlidingWindowSmoother, RankDeficientWindowProducesNoNaN) {
  // Poses with nothing but one or two ranges (no motion model, no prior):
  // each is determined in 1-2 of its 6 directions. The LM damping keeps the
  // solve defined; marginalization drops the unconstrained directions.
  const std::vector<Vec3> anchors = {Vec3(5, 0, 2.5), Vec3(-5, 1, 2.0), Vec3(0, -5, 0.5)};
  SlidingWindowParams p;
  p.window_s = 0.3;
  SlidingWindowSmoother smoother(p);
  std::mt19937 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  int marginalized = 0;
  for (int k = 0; k < 40; ++k) {
    FactorGraph f;
    Values v;
    KeyTimestamps t;
    if (k == 0) {
      for (int j = 0; j < 3; ++j) {
        f.emplace<PriorVec3Factor>(L(j), anchors[j], Vec3(Vec3::Constant(0.05)));
        v.insert(L(j), Variable(anchors[j]));
      }
    }
    const Vec3 p_true(std::cos(0.1 * k), std::sin(0.1 * k), 1.0);
    for (int j = 0; j < 1 + k % 2; ++j) {
      f.emplace<RangeFactor>(X(k), L(j), (p_true - anchors[j]).norm() + 0.05 * n01(rng), 0.05, Vec3::Zero());
    }
    v.insert(X(k), Pose3(Mat3::Identity(), p_true + Vec3(0.1, -0.1, 0.05)));
    t[X(k)] = 100'000'000LL * k;
    const UpdateStats st = smoother.update(f, v, t);
    marginalized += st.variables_marginalized;
    ASSERT_TRUE(allFinite(smoother.estimate())) << "update " << k;
    ASSERT_TRUE(std::isfinite(smoother.error())) << "update " << k;
    for (const auto& prior : smoother.linearMarginals()) {
      ASSERT_TRUE(prior->A().allFinite() && prior->d().allFinite()) << "update " << k;
    }
  }
  EXPECT_GT(marginalized, 30);
  EXPECT_GT(smoother.rankDeficientMarginalizations(), 30);
  std::string why;
  EXPECT_FALSE(smoother.marginalCovariance(X(39), &why).has_value());
  EXPECT_NE(why.find("indeterminate"), std::string::npos) << why;
  // The anchors (priors plus the ranges) stay determined and near their survey.
  for (int j = 0; j < 3; ++j) EXPECT_LT((std::get<Vec3>(smoother.estimate(L(j))) - anchors[j]).norm(), 0.2);
}

TEST(SlidingWindowSmoother, ImuStatesWithoutRangesStayDetermined) {
  // A ranging gap: IMU-only states in the window (and marginalized) are still
  // determined through the motion model: covariance available, no NaN.
  Walk w = makeWalk(4.0, 10.0, 12, "huber");
  FactorGraph without_ranges;
  for (const FactorPtr& f : w.graph.graph) {
    const bool range = f->keys().size() == 2 && keySymbol(f->keys()[1]) == 'l';
    const std::uint64_t i = keyIndex(f->keys()[0]);
    if (range && i >= 10 && i < 25) continue;  // 1.5 s without ranging
    without_ranges.add(f);
  }
  const auto increments = testing::splitIntoIncrements(without_ranges, w.initial, w.graph.state_t_ns);
  SlidingWindowParams p;
  p.window_s = 0.8;
  SlidingWindowSmoother smoother(p);
  for (std::size_t k = 0; k < increments.size(); ++k) {
    smoother.update(increments[k].factors, increments[k].values, increments[k].timestamps);
    ASSERT_TRUE(allFinite(smoother.estimate())) << "update " << k;
    std::string why;
    const auto cov = smoother.marginalCovariance(X(k), &why);
    ASSERT_TRUE(cov.has_value()) << "update " << k << ": " << why;
    EXPECT_TRUE(cov->allFinite());
    EXPECT_GT(cov->diagonal().minCoeff(), 0.0);
  }
  EXPECT_EQ(smoother.rankDeficientMarginalizations(), 0);
}

TEST(SlidingWindowSmoother, MarginalCovarianceIsTheInverseOfTheWindowHessian) {
  const Walk w = makeWalk(3.0, 10.0, 13, "huber");
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  SlidingWindowParams p;
  p.window_s = 0.7;
  p.first_estimate_jacobians = false;  // the prior's Jacobian is then the exact one linearizeDense takes
  SlidingWindowSmoother smoother(p);
  int checked = 0;
  for (std::size_t k = 0; k < increments.size(); ++k) {
    smoother.update(increments[k].factors, increments[k].values, increments[k].timestamps);
    if (k % 4 != 3) continue;
    const auto dense = testing::linearizeDense(smoother.nonlinearFactors(), smoother.linearMarginals(), smoother.estimate());
    // (J^T J)^-1 = R^-1 R^-T from a QR of J: no squared condition number.
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(dense.A);
    const int n = static_cast<int>(dense.A.cols());
    const Eigen::MatrixXd R = qr.matrixQR().topRows(n).triangularView<Eigen::Upper>();
    const Eigen::MatrixXd Ri = R.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(n, n));
    const Eigen::MatrixXd cov = Ri * Ri.transpose();
    // The newest pose, the oldest one (under the prior) and an anchor.
    Key oldest = X(k);
    for (std::uint64_t i = 0; i <= k; ++i) {
      if (smoother.exists(X(i))) {
        oldest = X(i);
        break;
      }
    }
    for (Key key : {X(k), oldest, w.graph.anchor_keys.front()}) {
      std::string why;
      const auto sw = smoother.marginalCovariance(key, &why);
      ASSERT_TRUE(sw.has_value()) << keyString(key) << ": " << why;
      const int off = dense.offset.at(key);
      const int dim = static_cast<int>(sw->rows());
      const Eigen::MatrixXd expected = cov.block(off, off, dim, dim);
      // CHOLMOD on J^T J against QR of J: the window's condition number (stiff
      // IMU chains, ~1e9) leaves a few 1e-7 of relative difference.
      EXPECT_LT((Eigen::MatrixXd(*sw) - expected).cwiseAbs().maxCoeff(), 1e-5 * expected.cwiseAbs().maxCoeff())
          << keyString(key) << " after update " << k;
    }
    ++checked;
  }
  EXPECT_GT(checked, 5);
}

TEST(SlidingWindowSmoother, FirstEstimatesStayFixedWhileTheEstimateMoves) {
  const Walk w = makeWalk(4.0, 10.0, 14, "huber");
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  SlidingWindowParams p;
  p.window_s = 1.0;
  p.first_estimate_jacobians = true;
  SlidingWindowSmoother smoother(p);
  std::map<Key, Variable> first;
  int frozen_checks = 0;
  double moved = 0.0;
  for (const Increment& inc : increments) {
    smoother.update(inc.factors, inc.values, inc.timestamps);
    std::set<Key> in_priors;
    for (const auto& prior : smoother.linearMarginals()) {
      for (std::size_t i = 0; i < prior->keys().size(); ++i) {
        const Key key = prior->keys()[i];
        in_priors.insert(key);
        // A prior's linearization point is its variables' first estimate.
        const auto fe = smoother.firstEstimate(key);
        ASSERT_TRUE(fe.has_value()) << keyString(key);
        EXPECT_TRUE(localVariable(*fe, prior->linearizationPoint(i)).isZero(0.0)) << keyString(key);
      }
    }
    for (Key key : in_priors) {
      const Variable fe = *smoother.firstEstimate(key);
      auto [it, inserted] = first.emplace(key, fe);
      if (!inserted) {
        EXPECT_TRUE(localVariable(it->second, fe).isZero(0.0)) << keyString(key) << " first estimate changed";
        ++frozen_checks;
      }
      moved = std::max(moved, localVariable(fe, smoother.estimate(key)).cwiseAbs().maxCoeff());
    }
  }
  EXPECT_GT(frozen_checks, 50);
  EXPECT_GT(moved, 0.0) << "the estimate of a frozen variable never moved: nothing was tested";
  // Without FEJ the priors are linearized at the estimate of the moment.
  p.first_estimate_jacobians = false;
  SlidingWindowSmoother plain(p);
  for (const Increment& inc : increments) plain.update(inc.factors, inc.values, inc.timestamps);
  EXPECT_FALSE(plain.firstEstimate(w.graph.anchor_keys.front()).has_value());
}

TEST(SlidingWindowSmoother, PriorsOnRangeOnlyPosesStayBounded) {
  // Poses without a motion model, each ranging to the same anchors: every
  // marginalized pose leaves a prior on the anchors alone, which must be
  // merged into the next rather than accumulate.
  const std::vector<Vec3> anchors = {Vec3(5, 0, 2.5), Vec3(-5, 1, 2.0), Vec3(0, -5, 0.5), Vec3(1, 5, 1.5)};
  SlidingWindowParams p;
  p.window_s = 0.3;
  SlidingWindowSmoother smoother(p);
  std::mt19937 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::size_t most_priors = 0;
  int most_variables = 0, most_factors = 0;
  for (int k = 0; k < 300; ++k) {
    FactorGraph f;
    Values v;
    KeyTimestamps t;
    if (k == 0) {
      for (int j = 0; j < 4; ++j) {
        f.emplace<PriorVec3Factor>(L(j), anchors[j], Vec3(Vec3::Constant(0.05)));
        v.insert(L(j), Variable(anchors[j]));
      }
    }
    const Vec3 p_true(2.0 * std::cos(0.01 * k), 2.0 * std::sin(0.01 * k), 1.0);
    f.emplace<PriorPose3Factor>(X(k), Pose3(Mat3::Identity(), p_true), Vec6((Vec6() << 0.1, 0.1, 0.1, 2, 2, 2).finished()));
    for (int j = 0; j < 4; ++j) {
      f.emplace<RangeFactor>(X(k), L(j), (p_true - anchors[j]).norm() + 0.05 * n01(rng), 0.05, Vec3::Zero());
    }
    v.insert(X(k), Pose3(Mat3::Identity(), p_true + Vec3(0.1, 0.1, -0.1)));
    t[X(k)] = 100'000'000LL * k;
    const UpdateStats st = smoother.update(f, v, t);
    if (k > 10) {
      most_priors = std::max(most_priors, smoother.linearMarginals().size());
      most_variables = std::max(most_variables, st.variables_total);
      most_factors = std::max(most_factors, st.factors_total);
      EXPECT_EQ(st.marginal_factors_created, 1);
      EXPECT_EQ(st.marginal_factors_merged, 1);
    }
  }
  EXPECT_EQ(most_priors, 1u);
  EXPECT_LE(most_variables, 4 + 4);
  EXPECT_LE(most_factors, 4 * 5 + 4 + 1);  // 4 poses, anchor surveys, one prior
}

TEST(SlidingWindowSmoother, StatsDescribeTheUpdate) {
  const Walk w = makeWalk(3.0, 10.0, 15, "huber");
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  SlidingWindowParams p;
  p.window_s = 0.5;
  SlidingWindowSmoother smoother(p);
  int total_vars = 0, total_marginalized = 0;
  for (const Increment& inc : increments) {
    const UpdateStats st = smoother.update(inc.factors, inc.values, inc.timestamps);
    total_vars += st.variables_added;
    total_marginalized += st.variables_marginalized;
    EXPECT_EQ(st.variables_added, static_cast<int>(inc.values.size()));
    EXPECT_EQ(st.factors_added, static_cast<int>(inc.factors.size()));
    EXPECT_EQ(st.variables_total, smoother.variableCount());
    EXPECT_EQ(st.factors_total, smoother.factorCount());
    EXPECT_EQ(total_vars - total_marginalized, smoother.variableCount());
    EXPECT_GE(st.step_tries, 1);
    EXPECT_LE(st.step_tries, p.max_iterations);
    EXPECT_TRUE(st.step_accepted);
    EXPECT_GT(st.lambda, 0.0);
    EXPECT_GE(st.time_s, 0.0);
    EXPECT_DOUBLE_EQ(st.error_after, smoother.error());
    if (st.variables_marginalized > 0) {
      EXPECT_EQ(st.marginal_factors_created, 1);
    }
  }
  EXPECT_GT(total_marginalized, 50);
}

}  // namespace
}  // namespace rilo
