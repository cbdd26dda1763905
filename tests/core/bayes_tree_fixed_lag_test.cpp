// Fixed-lag BayesTreeSmoother: after every update the kept variables carry
// exactly the dense Schur complement of everything ever added (relinearization
// off, so all of it is linearized at the initial values), in the situations
// that break GTSAM's IncrementalFixedLagSmoother:
//   #1638 / #1890 / PR #1639: a key to marginalize in the middle of a clique
//     (an old variable eliminated after a newer one);
//   #1680: the marginalized key left in the tree;
//   #1795: a variable with only a prior marginalized (SEGV);
//   #1101 / PR #1172: marginalizing a root, repeated partial marginalization
//     of one clique;
//   #1452 / #150: factor slots never reused, memory growing over hours;
// plus variables connected only to marginalized ones, several states at once,
// a lag shorter than one state interval, and anchors (no timestamp).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <string>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/smoother/bayes_tree_smoother.h"
#include "sim/range_imu_scenario.h"
#include "support/smoother_graphs.h"

namespace rilo {
namespace {

using sym::B;
using sym::L;
using sym::V;
using sym::X;
using testing::exactParams;
using testing::FeedOptions;
using testing::FeedOrder;
using testing::Increment;
using testing::makeRandomGraph;
using testing::makeSchedule;
using testing::RandomGraph;
using testing::RandomGraphOptions;
using Method = SmootherParams::Method;

SmootherParams lagParams(double lag_s, Method method = Method::kGaussNewton) {
  SmootherParams p = exactParams(method);
  p.lag_s = lag_s;
  return p;
}

/// Feeds a fixed-lag smoother and checks it against the full dense problem.
class LagHarness {
 public:
  explicit LagHarness(const SmootherParams& p) : smoother(p), lag_ns_(std::llround(p.lag_s * 1e9)) {}

  /// Drops what the smoother would rightly reject (a schedule's factors on
  /// variables already marginalized: late loop closures, or an older state
  /// arriving after its newer neighbour left the lag) and feeds the rest.
  UpdateStats feed(const Increment& inc) {
    Increment kept = filtered(inc);
    if (kept.factors.size() == 0 && kept.values.empty()) return {};
    const UpdateStats st = smoother.update(kept.factors, kept.values, kept.timestamps);
    for (const FactorPtr& f : kept.factors) all_.add(f);
    for (const auto& [key, value] : kept.values) all_initial_.insert(key, value);
    for (const auto& [key, t] : kept.timestamps) {
      time_[key] = t;
      newest_ = std::max(newest_, t);
    }
    marginalized_ += st.variables_marginalized;
    for (const auto& [key, value] : kept.values) gone_on_arrival_ += !smoother.exists(key);
    reordered_ += st.variables_reordered_for_marginalization;
    marginals_created_ += st.marginal_factors_created;
    ++updates_;
    return st;
  }

  /// Every check of one update; `what` goes into the failure messages.
  void check(const std::string& what, double tolerance = 1e-8) {
    SCOPED_TRACE(what);
    ASSERT_EQ(smoother.checkInvariants(), "");
    // Which variables are kept: timed ones not older than the lag, all untimed ones.
    const std::int64_t cutoff = newest_ - lag_ns_;
    for (const auto& [key, value] : all_initial_) {
      auto it = time_.find(key);
      const bool expected = it == time_.end() || it->second >= cutoff;
      EXPECT_EQ(smoother.exists(key), expected) << keyString(key) << (it == time_.end() ? " (no timestamp)" : "");
      if (!smoother.exists(key)) {
        EXPECT_THROW(smoother.estimate(key), std::out_of_range);
      }
    }
    EXPECT_EQ(smoother.variableCount(), static_cast<int>(smoother.estimate().size()));
    // Frozen keys are exactly those the linear marginals touch.
    std::set<Key> touched;
    for (const auto& m : smoother.linearMarginals()) touched.insert(m->keys().begin(), m->keys().end());
    const std::vector<Key> frozen = smoother.frozenKeys();
    EXPECT_EQ(std::vector<Key>(touched.begin(), touched.end()), frozen);
    for (Key k : frozen) EXPECT_TRUE(smoother.exists(k)) << "a marginal touches the marginalized " << keyString(k);
    // The Schur complement: the full dense solution restricted to the kept keys.
    const auto dense = testing::linearizeDense(all_, {}, all_initial_);
    const auto reference = testing::solveDense(dense);
    double scale = 1e-12, worst = 0.0;
    std::string worst_key;
    for (const auto& [key, x] : reference) {
      if (!smoother.exists(key)) continue;
      scale = std::max(scale, x.cwiseAbs().maxCoeff());
      const double e = (smoother.delta(key) - x).cwiseAbs().maxCoeff();
      if (e >= worst) {
        worst = e;
        worst_key = keyString(key);
      }
    }
    EXPECT_LT(worst / scale, tolerance) << "worst " << worst << " at " << worst_key << ", scale " << scale;
    EXPECT_NEAR(smoother.error(), smoother.errorFromScratch(), 1e-9 * std::max(1.0, smoother.errorFromScratch()));
    // Marginal covariances of kept variables are blocks of the full inverse:
    // the newest and the oldest kept pose (the one the marginals sit on).
    Key newest = 0, oldest = 0;
    for (const auto& [key, t] : time_) {
      if (keySymbol(key) != 'x' || !smoother.exists(key)) continue;
      if (!newest || t > time_.at(newest)) newest = key;
      if (!oldest || t < time_.at(oldest)) oldest = key;
    }
    if (!newest) return;
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(dense.A);
    const int n = static_cast<int>(dense.A.cols());
    const Eigen::MatrixXd R = qr.matrixQR().topRows(n).triangularView<Eigen::Upper>();
    const Eigen::MatrixXd Ri = R.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(n, n));
    for (Key key : {newest, oldest}) {
      std::string failure;
      const auto cov = smoother.marginalCovariance(key, &failure);
      ASSERT_TRUE(cov.has_value()) << keyString(key) << ": " << failure;
      const int off = dense.offset.at(key);
      const Eigen::MatrixXd expected = Ri.middleRows(off, 6) * Ri.middleRows(off, 6).transpose();
      EXPECT_LT((Eigen::MatrixXd(*cov) - expected).cwiseAbs().maxCoeff(), 1e-7 * expected.cwiseAbs().maxCoeff())
          << "covariance of " << keyString(key);
    }
  }

  /// `inc` without its factors on variables that are gone, and without the
  /// new states such a factor was the motion link of: a new state is kept
  /// only while a prior or a kept multi-state factor (IMU, bias) ties it to an
  /// existing or kept state; otherwise it would be an island that ranges alone
  /// leave under-determined.
  Increment filtered(const Increment& inc) const {
    Values values = inc.values;
    auto present = [&](Key k) { return values.exists(k) || smoother.exists(k); };
    auto is_state = [](Key k) { return testing::isStateKey(k); };
    for (bool changed = true; changed;) {
      changed = false;
      std::set<Key> anchored;
      for (const FactorPtr& f : inc.factors) {
        const auto& keys = f->keys();
        if (keys.size() == 1 && values.exists(keys[0])) anchored.insert(keys[0]);
      }
      for (bool grew = true; grew;) {
        grew = false;
        for (const FactorPtr& f : inc.factors) {
          const auto& keys = f->keys();
          if (!std::all_of(keys.begin(), keys.end(), present)) continue;
          if (std::count_if(keys.begin(), keys.end(), is_state) < 2) continue;
          const bool tied = std::any_of(keys.begin(), keys.end(), [&](Key k) {
            return is_state(k) && (smoother.exists(k) || anchored.count(k));
          });
          if (!tied) continue;
          for (Key k : keys) {
            if (values.exists(k) && anchored.insert(k).second) grew = true;
          }
        }
      }
      for (Key k : values.keys()) {
        if (is_state(k) && !anchored.count(k)) {
          values.erase(k);
          changed = true;
        }
      }
    }
    Increment kept;
    std::set<Key> covered;
    for (const FactorPtr& f : inc.factors) {
      const auto& keys = f->keys();
      if (!std::all_of(keys.begin(), keys.end(), present)) continue;
      kept.factors.add(f);
      covered.insert(keys.begin(), keys.end());
    }
    for (Key k : values.keys()) {
      if (covered.count(k)) kept.values.insert(k, values.at(k));
    }
    for (const auto& [key, t] : inc.timestamps) {
      if (kept.values.exists(key)) kept.timestamps[key] = t;
    }
    return kept;
  }

  BayesTreeSmoother smoother;
  int marginalized_ = 0, reordered_ = 0, marginals_created_ = 0, updates_ = 0, gone_on_arrival_ = 0;

 private:
  std::int64_t lag_ns_;
  FactorGraph all_;
  Values all_initial_;
  std::map<Key, std::int64_t> time_;
  std::int64_t newest_ = std::numeric_limits<std::int64_t>::min();
};

// ------------------------------------------------------------------ walks

struct Walk {
  sim::Scenario scenario;
  RangeImuGraph graph;
  Values initial;
};

Walk makeWalk(double seconds, double range_hz, std::uint64_t seed) {
  sim::ScenarioParams sp;
  sp.seed = seed;
  sp.duration_s = seconds;
  sp.range_rate_hz = range_hz;
  Walk w{sim::simulateScenario(sp), {}, {}};
  RangeImuGraphParams gp;
  gp.p_b_tag = w.scenario.p_b_tag;
  gp.range_noise.sigma_m = sp.range_sigma_m;
  gp.imu = sim::imuParamsOf(sp);
  const sim::KinematicState st0 = w.scenario.truthAt(w.scenario.ranges.front().t_ns);
  w.graph = buildRangeImuGraph(w.scenario.imu, w.scenario.ranges, w.scenario.p_w_anchors, st0.T_w_b, st0.v_w, gp);
  sim::TruthPerturbation perturbation;
  perturbation.seed = seed + 11;
  w.initial = sim::truthValues(w.scenario, w.graph.state_t_ns, w.graph.anchor_keys, &perturbation);
  return w;
}

TEST(BayesTreeFixedLag, MatchesDenseSchurComplementOnRangeImuWalk) {
  const Walk w = makeWalk(3.0, 10.0, 4);
  const auto increments = testing::splitIntoIncrements(w.graph.graph, w.initial, w.graph.state_t_ns);
  for (double lag : {0.5, 0.05}) {  // 0.05 s: shorter than a state interval
    LagHarness h(lagParams(lag));
    for (std::size_t k = 0; k < increments.size(); ++k) {
      h.feed(increments[k]);
      h.check("lag " + std::to_string(lag) + ", increment " + std::to_string(k));
      if (::testing::Test::HasFatalFailure()) return;
    }
    EXPECT_GT(h.marginalized_, 30);
    EXPECT_FALSE(h.smoother.linearMarginals().empty());
    for (Key a : w.graph.anchor_keys) EXPECT_TRUE(h.smoother.exists(a)) << "anchor " << keyString(a);
  }
}

// ------------------------------------------------------------------ random graphs

TEST(BayesTreeFixedLag, MatchesDenseSchurComplementOnRandomGraphs) {
  int marginalized = 0, reordered = 0;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    for (FeedOrder order : {FeedOrder::kTime, FeedOrder::kRandomGrowth}) {
      for (double lag : {0.5, 0.25}) {
        RandomGraphOptions go;
        go.states = 12;
        go.prior_state = order == FeedOrder::kTime ? 0 : 6;
        const RandomGraph g = makeRandomGraph(seed + 70, go);
        std::mt19937 rng(static_cast<unsigned>(seed));
        FeedOptions fo;
        fo.order = order;
        LagHarness h(lagParams(lag));
        const auto schedule = makeSchedule(g, rng, fo);
        for (std::size_t k = 0; k < schedule.size(); ++k) {
          h.feed(schedule[k]);
          h.check("seed " + std::to_string(seed) + (order == FeedOrder::kTime ? " time" : " growth") + " lag " +
                  std::to_string(lag) + " update " + std::to_string(k));
          if (::testing::Test::HasFatalFailure()) return;
        }
        marginalized += h.marginalized_;
        reordered += h.reordered_;
      }
    }
  }
  EXPECT_GT(marginalized, 100);
  RecordProperty("reordered", reordered);
}

TEST(BayesTreeFixedLag, OutOfOrderTimestampsMarginalizeOnInsertion) {
  // Random growth from a middle state: older states arrive after newer ones;
  // with a short lag some are older than the cutoff the moment they arrive.
  int marginalized = 0, gone_on_arrival = 0;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    RandomGraphOptions go;
    go.states = 10;
    go.prior_state = 7;
    const RandomGraph g = makeRandomGraph(seed + 80, go);
    std::mt19937 rng(static_cast<unsigned>(seed));
    FeedOptions fo;
    fo.order = FeedOrder::kRandomGrowth;
    fo.defer_probability = 0.0;
    LagHarness h(lagParams(0.3));
    for (const Increment& inc : makeSchedule(g, rng, fo)) {
      h.feed(inc);
      h.check("seed " + std::to_string(seed));
      if (::testing::Test::HasFatalFailure()) return;
    }
    marginalized += h.marginalized_;
    gone_on_arrival += h.gone_on_arrival_;
  }
  EXPECT_GT(marginalized, 20);
  EXPECT_GT(gone_on_arrival, 3) << "no state was marginalized in the update that brought it";
}

// ------------------------------------------------------------------ GTSAM's failure cases

/// Time-ordered feeding of a random graph, one state per update; `extra`
/// edits each increment before it goes in, `after` looks at the smoother.
template <class Extra, class After>
void runChain(const RandomGraph& g, Extra extra, LagHarness& h, After after) {
  std::mt19937 rng(5);
  FeedOptions fo;
  fo.max_states_per_update = 1;
  fo.defer_probability = 0.0;
  const auto schedule = makeSchedule(g, rng, fo);
  for (std::size_t k = 0; k < schedule.size(); ++k) {
    Increment inc = schedule[k];
    extra(static_cast<int>(k), inc);
    h.feed(inc);
    h.check("update " + std::to_string(k));
    if (::testing::Test::HasFatalFailure()) return;
    after(static_cast<int>(k));
  }
}

template <class Extra>
void runChain(const RandomGraph& g, Extra extra, LagHarness& h) {
  runChain(g, extra, h, [](int) {});
}

TEST(BayesTreeFixedLag, MarginalKeyInTheMiddleOfAClique) {
  // GTSAM #1638 / #1890: a key to marginalize that its clique eliminates
  // after a kept one. Every third state arrives linked by a long IMU factor to
  // state k-2 (plus a bias prior), and its regular link to k-1 comes one update
  // later: in update k, k-2 is a key of the new factors (ordered last) while
  // k-1 is not, so k-1 is eliminated before k-2 in the same clique; at k+1,
  // k-2 leaves the 0.5 s lag (states 0.2 s apart) and k-1 stays.
  int reordered = 0;
  for (std::uint64_t seed : {91u, 92u, 93u}) {
    RandomGraphOptions go;
    go.states = 16;
    go.skip_imu_probability = 0.0;
    go.dt_min_s = go.dt_max_s = 0.2;
    const RandomGraph g = makeRandomGraph(seed, go);
    LagHarness h(lagParams(0.5));
    FactorGraph held;
    runChain(g, [&](int k, Increment& inc) {
      for (const FactorPtr& f : held) inc.factors.add(f);
      held = FactorGraph();
      if (k < 3 || k % 3 != 0 || k >= go.states) return;
      const std::set<Key> previous = {X(k - 1), V(k - 1), B(k - 1)};
      FactorGraph rest;
      for (const FactorPtr& f : inc.factors) {
        const bool link = std::any_of(f->keys().begin(), f->keys().end(), [&](Key key) { return previous.count(key); });
        (link ? held : rest).add(f);
      }
      rest.add(testing::imuFactorBetween(g, k - 2, k));
      rest.emplace<PriorBiasFactor>(B(k), ImuBias(), Vec6((Vec6() << 0.1, 0.1, 0.1, 0.01, 0.01, 0.01).finished()));
      inc.factors = rest;
    }, h);
    if (::testing::Test::HasFatalFailure()) return;
    EXPECT_GT(h.marginalized_, 30);
    reordered += h.reordered_;
  }
  EXPECT_GT(reordered, 0) << "the middle-of-clique path was not exercised";
}

TEST(BayesTreeFixedLag, VariableWithOnlyAPriorIsMarginalized) {
  // GTSAM #1795 (SEGV): a timed variable with nothing but a prior is its own
  // root clique; marginalizing it must simply drop it.
  RandomGraphOptions go;
  go.states = 8;
  const RandomGraph g = makeRandomGraph(94, go);
  LagHarness h(lagParams(0.4));
  runChain(g, [&](int k, Increment& inc) {
    if (k == 0 || k == 3) {
      const Key lonely = X(100 + k);
      inc.factors.emplace<PriorPose3Factor>(lonely, Pose3(), Vec6(Vec6::Constant(0.5)));
      inc.values.insert(lonely, Pose3());
      inc.timestamps[lonely] = g.t_ns[k];
    }
  }, h);
  EXPECT_FALSE(h.smoother.exists(X(100)));
  EXPECT_FALSE(h.smoother.exists(X(103)));
  for (const auto& m : h.smoother.linearMarginals()) {
    for (Key k : m->keys()) EXPECT_LT(keyIndex(k), 100u) << "a marginal on " << keyString(k);
  }
}

TEST(BayesTreeFixedLag, VariablesConnectedOnlyToMarginalizedVariables) {
  // An anchor seen only from state 0, and a timed pair (X200, V200) hung on
  // state 0 alone by an IMU factor, stamped 0.3 s after state 1: once state 0
  // leaves they are connected only through its marginal, and stay until
  // their own time comes (the anchor for good).
  RandomGraphOptions go;
  go.states = 10;
  const RandomGraph g = makeRandomGraph(95, go);
  LagHarness h(lagParams(0.4));
  int seen_alone = 0;
  runChain(g, [&](int k, Increment& inc) {
    if (k == 0) {
      inc.factors.emplace<RangeFactor>(X(0), L(9), 4.0, 0.1, Vec3::Zero());
      inc.factors.emplace<PriorVec3Factor>(L(9), Vec3(4, 1, 2), Vec3(Vec3::Constant(1.0)));
      inc.values.insert(L(9), Variable(Vec3(4, 1, 2)));
    }
    if (k == 1) {
      inc.factors.add(testing::imuFactorBetween(g, 0, 1, X(200), V(200)));
      inc.values.insert(X(200), g.initial.at(X(1)));
      inc.values.insert(V(200), g.initial.at(V(1)));
      inc.timestamps[X(200)] = inc.timestamps[V(200)] = g.t_ns[1] + 300'000'000;
    }
  }, h, [&](int) {
    if (h.smoother.exists(X(0)) || !h.smoother.exists(X(200))) return;
    ++seen_alone;
    const auto frozen = h.smoother.frozenKeys();
    EXPECT_TRUE(std::count(frozen.begin(), frozen.end(), L(9)));
    EXPECT_TRUE(std::count(frozen.begin(), frozen.end(), X(200)));
    EXPECT_TRUE(std::count(frozen.begin(), frozen.end(), V(200)));
    EXPECT_TRUE(h.smoother.marginalCovariance(X(200)).has_value());
  });
  EXPECT_GT(seen_alone, 0);
  EXPECT_TRUE(h.smoother.exists(L(9)));
  EXPECT_FALSE(h.smoother.exists(X(200)));
  const auto frozen = h.smoother.frozenKeys();
  EXPECT_TRUE(std::count(frozen.begin(), frozen.end(), L(9)));
}

TEST(BayesTreeFixedLag, SeveralStatesMarginalizedAtOnce) {
  // A timestamp jump (a gap in the data): one update marginalizes many states,
  // spread over several cliques, some wholly marginal, some partial.
  RandomGraphOptions go;
  go.states = 12;
  const RandomGraph g = makeRandomGraph(96, go);
  LagHarness h(lagParams(1.0));
  runChain(g, [&](int k, Increment& inc) {
    if (k >= 8) {
      for (auto& [key, t] : inc.timestamps) t += 5'000'000'000;  // 5 s later than the IMU says
    }
  }, h);
  EXPECT_GE(h.marginalized_, 3 * 7);
  EXPECT_EQ(h.smoother.variableCount(), 3 * 4 + go.anchors) << "states 8..11 and the anchors";
}

TEST(BayesTreeFixedLag, LagShorterThanOneStateIntervalKeepsOnlyTheNewestState) {
  // The newest state's predecessor goes in the very update that links them.
  RandomGraphOptions go;
  go.states = 10;
  const RandomGraph g = makeRandomGraph(97, go);
  LagHarness h(lagParams(0.01));
  runChain(g, [](int, Increment&) {}, h);
  EXPECT_EQ(h.marginalized_, 3 * 9);
  const std::vector<Key> frozen = h.smoother.frozenKeys();
  EXPECT_TRUE(std::count(frozen.begin(), frozen.end(), X(9)));
}

TEST(BayesTreeFixedLag, RepeatedPartialMarginalizationOfOneClique) {
  // GTSAM #1101 / PR #1172: marginalizing frontals of the same clique over
  // several updates. One state per update with its own timestamp, all linked
  // into one clique by long IMU factors; lag such that they leave one by one.
  RandomGraphOptions go;
  go.states = 12;
  go.dt_min_s = go.dt_max_s = 0.1;
  go.skip_imu_probability = 0.0;
  const RandomGraph g = makeRandomGraph(98, go);
  LagHarness h(lagParams(0.35));
  runChain(g, [&](int k, Increment& inc) {
    if (k >= 3) inc.factors.add(testing::imuFactorBetween(g, k - 3, k));
    if (k >= 2) inc.factors.add(testing::imuFactorBetween(g, k - 2, k));
  }, h);
  EXPECT_GT(h.marginalized_, 20);
}

TEST(BayesTreeFixedLag, FactorOnAMarginalizedVariableIsRejectedWithNothingChanged) {
  RandomGraphOptions go;
  go.states = 8;
  const RandomGraph g = makeRandomGraph(99, go);
  LagHarness h(lagParams(0.3));
  runChain(g, [](int, Increment&) {}, h);
  ASSERT_FALSE(h.smoother.exists(X(0)));
  const Values before = h.smoother.estimate();
  const int factors = h.smoother.factorCount();
  FactorGraph late;
  late.emplace<RangeFactor>(X(0), L(0), 3.0, 0.1, Vec3::Zero());
  try {
    h.smoother.update(late, {});
    ADD_FAILURE() << "a factor on the marginalized x0 was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(keyString(X(0))), std::string::npos) << e.what();
  }
  EXPECT_TRUE(testing::sameValues(before, h.smoother.estimate()));
  EXPECT_EQ(factors, h.smoother.factorCount());
  EXPECT_EQ(h.smoother.checkInvariants(), "");
}

TEST(BayesTreeFixedLag, AllMethodsKeepTheSchurComplementConsistent) {
  // D-iSAM2 and dog-leg move the estimate differently, but marginalization is
  // the same linear algebra: invariants, kept keys and frozen keys hold, and
  // the error bookkeeping stays exact.
  for (Method method : {Method::kDamped, Method::kDogleg}) {
    RandomGraphOptions go;
    go.states = 12;
    const RandomGraph g = makeRandomGraph(100, go);
    std::mt19937 rng(3);
    SmootherParams p = testing::relinearizingParams(method, 1e-3);
    p.lag_s = 0.5;
    BayesTreeSmoother smoother(p);
    int marginalized = 0;
    for (const Increment& inc : makeSchedule(g, rng)) {
      Increment kept = inc;
      kept.factors = FactorGraph();
      for (const FactorPtr& f : inc.factors) {
        bool ok = true;
        for (Key k : f->keys()) ok &= inc.values.exists(k) || smoother.exists(k);
        if (ok) kept.factors.add(f);
      }
      if (kept.factors.size() == 0 && kept.values.empty()) continue;
      marginalized += smoother.update(kept.factors, kept.values, kept.timestamps).variables_marginalized;
      ASSERT_EQ(smoother.checkInvariants(), "") << "method " << static_cast<int>(method);
      EXPECT_NEAR(smoother.error(), smoother.errorFromScratch(), 1e-9 * std::max(1.0, smoother.errorFromScratch()));
      std::set<Key> touched;
      for (const auto& m : smoother.linearMarginals()) touched.insert(m->keys().begin(), m->keys().end());
      EXPECT_EQ(std::vector<Key>(touched.begin(), touched.end()), smoother.frozenKeys());
    }
    EXPECT_GT(marginalized, 10);
    for (int j = 0; j < go.anchors; ++j) EXPECT_TRUE(smoother.exists(L(j)));
  }
}

TEST(BayesTreeFixedLag, RelinearizingDeltaMatchesDenseWithLinearMarginals) {
  // With relinearization the reference is the dense problem of what the
  // smoother holds: the nonlinear factors still alive (those on no
  // marginalized variable) and its linear marginals, at its linearization point.
  int relinearized = 0;
  for (std::uint64_t seed : {111u, 112u}) {
    RandomGraphOptions go;
    go.states = 14;
    const RandomGraph g = makeRandomGraph(seed, go);
    std::mt19937 rng(static_cast<unsigned>(seed));
    SmootherParams p = testing::relinearizingParams(Method::kGaussNewton, 1e-4);
    p.lag_s = 0.5;
    LagHarness h(p);
    FactorGraph fed;
    for (const Increment& inc : makeSchedule(g, rng)) {
      const Increment kept = h.filtered(inc);
      const UpdateStats st = h.feed(inc);
      relinearized += st.variables_relinearized;
      for (const FactorPtr& f : kept.factors) fed.add(f);
      ASSERT_EQ(h.smoother.checkInvariants(), "");
      FactorGraph alive;
      for (const FactorPtr& f : fed) {
        const auto& keys = f->keys();
        if (std::all_of(keys.begin(), keys.end(), [&](Key k) { return h.smoother.exists(k); })) alive.add(f);
      }
      EXPECT_EQ(h.smoother.factorCount(), static_cast<int>(alive.size() + h.smoother.linearMarginals().size()));
      const auto c = testing::compareDeltaWithDense(h.smoother, alive);
      EXPECT_LT(c.worst / std::max(c.scale, 1e-2), 1e-9) << "seed " << seed << ": worst " << c.worst << " at "
                                                         << c.worst_key << ", scale " << c.scale;
    }
  }
  EXPECT_GT(relinearized, 50);
}

// ------------------------------------------------------------------ bounded memory

struct Sizes {
  int cliques = 0, variables = 0, factors = 0;
  std::size_t capacity = 0;
};

Sizes sizesOf(const BayesTreeSmoother& s) {
  return {s.cliqueCount(), s.variableCount(), s.factorCount(), s.slotCapacity()};
}

TEST(BayesTreeFixedLag, LongRunOnAChainStaysBounded) {
  // GTSAM #1452 / #150: thousands of updates; after a warm-up every pool and
  // count stays below what the first window after warm-up needed.
  RandomGraphOptions go;
  go.states = 2500;
  go.anchors = 4;
  go.dt_min_s = go.dt_max_s = 0.05;
  go.skip_imu_probability = 0.1;
  go.max_ranges_per_state = 2;
  const RandomGraph g = makeRandomGraph(101, go);
  std::mt19937 rng(101);
  FeedOptions fo;
  fo.max_states_per_update = 1;
  fo.defer_probability = 0.2;
  fo.loop_update_probability = 0.1;
  const auto schedule = makeSchedule(g, rng, fo);
  SmootherParams p = testing::relinearizingParams(Method::kDamped, 1e-3);
  p.wildfire_threshold = 1e-3;
  p.lag_s = 0.5;  // ~10 states
  BayesTreeSmoother smoother(p);
  const std::size_t warmup = 300, window_end = 600;
  Sizes bound;
  int marginalized = 0;
  for (std::size_t k = 0; k < schedule.size(); ++k) {
    Increment kept = schedule[k];
    kept.factors = FactorGraph();
    for (const FactorPtr& f : schedule[k].factors) {
      bool ok = true;
      for (Key key : f->keys()) ok &= schedule[k].values.exists(key) || smoother.exists(key);
      if (ok) kept.factors.add(f);
    }
    if (kept.factors.size() == 0 && kept.values.empty()) continue;
    marginalized += smoother.update(kept.factors, kept.values, kept.timestamps).variables_marginalized;
    const Sizes now = sizesOf(smoother);
    if (k >= warmup && k < window_end) {
      bound.cliques = std::max(bound.cliques, now.cliques);
      bound.variables = std::max(bound.variables, now.variables);
      bound.factors = std::max(bound.factors, now.factors);
      bound.capacity = std::max(bound.capacity, now.capacity);
    } else if (k >= window_end) {
      // The window's content fluctuates (ranges per state, loop closures):
      // 1.5x what the first window after warm-up needed is a fixed bound
      // that linear growth would cross within a few hundred updates.
      ASSERT_LE(now.cliques, bound.cliques * 3 / 2) << "update " << k;
      ASSERT_LE(now.variables, bound.variables * 3 / 2) << "update " << k;
      ASSERT_LE(now.factors, bound.factors * 3 / 2) << "update " << k;
      ASSERT_LE(now.capacity, bound.capacity * 3 / 2) << "update " << k;
    }
    if (k % 250 == 0) {
      ASSERT_EQ(smoother.checkInvariants(), "") << "update " << k;
    }
  }
  EXPECT_EQ(smoother.checkInvariants(), "");
  EXPECT_GT(marginalized, 3 * 2400);
  // The window itself: ~10 states of 3 variables plus the anchors.
  EXPECT_LE(bound.variables, 3 * 14 + go.anchors);
  EXPECT_NEAR(smoother.error(), smoother.errorFromScratch(), 1e-9 * std::max(1.0, smoother.errorFromScratch()));
}

// Regression: a marginal whose keys are all untimed (anchors) was never
// merged with the earlier ones on the same keys: one LinearMarginal per
// marginalized pose, and the root's elimination grew with them.
TEST(BayesTreeFixedLag, LongRunOfRangeOnlyPosesStaysBounded) {
  // Poses without a motion model, each ranging to the same four anchor
  // variables: every marginalized pose leaves a marginal on the anchors alone.
  // Those marginals must be merged (or otherwise bounded), not accumulated.
  const std::vector<Vec3> anchors = {Vec3(5, 0, 2.5), Vec3(-5, 1, 2.0), Vec3(0, -5, 0.5), Vec3(1, 5, 1.5)};
  SmootherParams p = testing::relinearizingParams(Method::kDamped, 1e-3);
  p.lag_s = 0.3;
  BayesTreeSmoother smoother(p);
  std::mt19937 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  Sizes bound;
  const int updates = 1500, warmup = 200, window_end = 400;
  for (int k = 0; k < updates; ++k) {
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
    v.insert(X(k), Pose3(Mat3::Identity(), p_true + 0.2 * testing::randomVec(rng, 1.0)));
    t[X(k)] = 100'000'000LL * k;  // 10 Hz
    smoother.update(f, v, t);
    const Sizes now = sizesOf(smoother);
    if (k >= warmup && k < window_end) {
      bound.cliques = std::max(bound.cliques, now.cliques);
      bound.variables = std::max(bound.variables, now.variables);
      bound.factors = std::max(bound.factors, now.factors);
      bound.capacity = std::max(bound.capacity, now.capacity);
    } else if (k >= window_end) {
      ASSERT_LE(now.variables, bound.variables * 3 / 2) << "update " << k;
      ASSERT_LE(now.cliques, bound.cliques * 3 / 2) << "update " << k;
      ASSERT_LE(now.factors, bound.factors * 3 / 2) << "update " << k << ": " << smoother.linearMarginals().size()
                                                    << " linear marginals";
      ASSERT_LE(now.capacity, bound.capacity * 3 / 2) << "update " << k;
    }
  }
  EXPECT_EQ(smoother.checkInvariants(), "");
  EXPECT_LE(bound.variables, 4 + 4);
}

}  // namespace
}  // namespace rilo
