#pragma once
// Shared helpers of the BayesTreeSmoother tests: parameter presets, the dense
// reference check of the linear step, small random graphs built from the real
// factors (priors, ranges to anchor variables, combined or separate IMU
// factors, bias Gauss-Markov factors, two-window IMU factors that close
// loops), and schedules feeding them in random orders and batch sizes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "estimation/factors/bias_factor.h"
#include "estimation/factors/imu_factor.h"
#include "estimation/factors/prior_factors.h"
#include "estimation/factors/range_factor.h"
#include "estimation/noise/noise_model_factory.h"
#include "estimation/smoother/bayes_tree_smoother.h"
#include "support/dense_reference.h"
#include "support/incremental_feed.h"
#include "support/random_states.h"

namespace rilo::testing {

// --- Parameter presets ----------------------------------------------------------

/// Exact linear algebra: no wildfire, no relinearization (theta stays at the
/// initial values, so the tree must equal the dense problem at those).
inline SmootherParams exactParams(SmootherParams::Method method) {
  SmootherParams p;
  p.method = method;
  // The Ranging-IMU Fusion paper's literal acceptance (whole-graph error), whose guarantee the
  // damped tests check; the service's default is kDampedFactors.
  p.d_isam2.acceptance = DIsam2Params::Acceptance::kGlobal;
  p.relinearize_max_age_s = 0.0;  // reference checks relinearize every state
  p.d_isam2.widen_damping = true;  // what kGlobal needs
  p.wildfire_threshold = 0.0;
  p.always_relinearize_recent_updates = 0;
  p.default_pose_threshold.setConstant(1e9);
  p.default_bias_threshold.setConstant(1e9);
  p.default_vec3_threshold.setConstant(1e9);
  return p;
}

/// Exact back-substitution with fluid relinearization at a small threshold.
inline SmootherParams relinearizingParams(SmootherParams::Method method, double threshold) {
  SmootherParams p;
  p.method = method;
  // The Ranging-IMU Fusion paper's literal acceptance (whole-graph error), whose guarantee the
  // damped tests check; the service's default is kDampedFactors.
  p.d_isam2.acceptance = DIsam2Params::Acceptance::kGlobal;
  p.relinearize_max_age_s = 0.0;  // reference checks relinearize every state
  p.d_isam2.widen_damping = true;  // what kGlobal needs
  p.wildfire_threshold = 0.0;
  p.default_pose_threshold.setConstant(threshold);
  p.default_bias_threshold.setConstant(threshold);
  p.default_vec3_threshold.setConstant(threshold);
  return p;
}

// --- Dense reference ------------------------------------------------------------

struct DeltaComparison {
  double worst = 0.0;   ///< max_k |delta_k - dense_k|_inf
  double scale = 0.0;   ///< max_k |dense_k|_inf
  std::string worst_key;
  double relative() const { return worst / std::max(scale, 1e-300); }
};

/// The smoother's delta against the dense solution over `graph` (the
/// nonlinear factors the smoother holds) plus its linear marginals, at its
/// linearization point.
inline DeltaComparison compareDeltaWithDense(const BayesTreeSmoother& smoother, const FactorGraph& graph) {
  const auto dense = linearizeDense(graph, smoother.linearMarginals(), smoother.linearizationPoint());
  const auto reference = solveDense(dense);
  DeltaComparison c;
  for (const auto& [key, x] : reference) c.scale = std::max(c.scale, x.cwiseAbs().maxCoeff());
  for (const auto& [key, x] : reference) {
    const double e = (smoother.delta(key) - x).cwiseAbs().maxCoeff();
    if (e >= c.worst) {
      c.worst = e;
      c.worst_key = keyString(key);
    }
  }
  return c;
}

/// max_k |delta_k - dense_k|_inf / max_k |dense_k|_inf (see compareDeltaWithDense).
inline double maxRelativeDeltaError(const BayesTreeSmoother& smoother, const FactorGraph& graph,
                                    std::string* worst_key = nullptr) {
  const DeltaComparison c = compareDeltaWithDense(smoother, graph);
  if (worst_key) *worst_key = c.worst_key;
  return c.relative();
}

/// Largest tangent-space difference between two value sets over `a`'s keys.
inline double maxLocalDifference(const Values& a, const Values& b) {
  double worst = 0.0;
  for (const auto& [key, value] : a) worst = std::max(worst, localVariable(value, b.at(key)).cwiseAbs().maxCoeff());
  return worst;
}

/// Exact equality of two value sets (same keys, same numbers).
inline bool sameValues(const Values& a, const Values& b) {
  if (a.size() != b.size()) return false;
  for (const auto& [key, value] : a) {
    if (!b.exists(key)) return false;
    if (!localVariable(value, b.at(key)).isZero(0.0)) return false;
  }
  return true;
}

// --- Random graphs ----------------------------------------------------------------

struct RandomGraphOptions {
  int states = 10;
  int anchors = 4;
  int prior_state = 0;                 ///< state carrying the priors on X, V, B
  double combined_probability = 0.5;   ///< CombinedImuFactor, else ImuFactor + BiasGaussMarkovFactor
  double skip_imu_probability = 0.2;   ///< extra ImuFactor over two windows (i, i + 2)
  int max_ranges_per_state = 3;
  bool random_losses = true;           ///< range losses drawn from every makeRangeLoss name
  bool convex_losses_only = false;     ///< ... or only from "gaussian" and "huber" (one optimum)
  double dt_min_s = 0.1, dt_max_s = 0.3;
  // Initial values: truth perturbed by these (rad, m, m/s; biases start at zero).
  double rotation_perturbation_rad = 0.05;
  double position_perturbation_m = 0.3;
  double velocity_perturbation_m_s = 0.2;
};

struct RandomGraph {
  /// IMU samples of the window between state i and i + 1, preintegrated at 200 Hz.
  struct Window {
    std::vector<std::pair<Vec3, Vec3>> samples;  ///< (specific force m/s^2, body rate rad/s)
    double dt_s = 0.0;
  };
  FactorGraph graph;
  Values truth;
  Values initial;
  std::vector<std::int64_t> t_ns;          ///< time of state i
  std::vector<std::vector<Key>> state_anchors;  ///< anchors each state ranges to
  /// Factors that add redundant information (ranges, two-window IMU factors): a
  /// schedule may hold them back without leaving the graph under-determined.
  std::vector<bool> deferrable;
  int states = 0;
  int anchors = 0;
  int prior_state = 0;
  std::vector<Window> windows;
  ImuParams imu;
};

inline constexpr double kRandomGraphImuRateHz = 200.0;

/// ImuFactor over windows i .. j - 1 (a long link) on keys {X_i, V_i, X_j', V_j', B_i},
/// j' the state j unless other keys are given (to hang new variables on state i).
inline FactorPtr imuFactorBetween(const RandomGraph& g, int i, int j, Key x_j = 0, Key v_j = 0) {
  PreintegratedImu pim(g.imu, g.truth.bias(sym::B(i)));
  for (int w = i; w < j; ++w) {
    for (const auto& [f, gyro] : g.windows[w].samples) pim.integrate(f, gyro, 1.0 / kRandomGraphImuRateHz);
  }
  return std::make_shared<ImuFactor>(sym::X(i), sym::V(i), x_j ? x_j : sym::X(j), v_j ? v_j : sym::V(j), sym::B(i), pim);
}

/// A walk of `states` states: random constant specific force and body rate
/// per window (preintegrated at 200 Hz), the truth predicted by the
/// preintegration itself (so IMU residuals vanish at the truth), ranges with
/// 0.1 m noise to anchor variables with survey priors.
inline RandomGraph makeRandomGraph(std::uint64_t seed, const RandomGraphOptions& o = {}) {
  std::mt19937 rng(static_cast<std::mt19937::result_type>(seed));
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  RandomGraph g;
  g.states = o.states;
  g.anchors = o.anchors;
  g.prior_state = o.prior_state;
  ImuParams& imu = g.imu;
  imu.accel_bias_tau_s = 50.0;  // Gauss-Markov: Phi visibly below 1 in the bias factors
  const Vec3 p_b_tag = randomVec(rng, 0.1);

  // Anchors around the area.
  std::vector<Vec3> anchors;
  for (int j = 0; j < o.anchors; ++j) {
    const double angle = 2.0 * std::numbers::pi * (j + 0.3 * u01(rng)) / o.anchors;
    anchors.emplace_back(6.0 * std::cos(angle), 6.0 * std::sin(angle), 0.5 + 2.5 * u01(rng));
    g.truth.insert(sym::L(j), Variable(anchors.back()));
  }

  // States: truth by preintegration, windows kept for the long-link factors.
  std::vector<RandomGraph::Window>& windows = g.windows;
  windows.resize(std::max(0, o.states - 1));
  Pose3 T(randomRotation(rng), randomVec(rng, 1.0));
  Vec3 v = randomVec(rng, 0.5);
  ImuBias b(randomVec(rng, 0.05), randomVec(rng, 0.005));
  const double rate_hz = kRandomGraphImuRateHz;
  std::int64_t t = 1'000'000'000;
  for (int i = 0; i < o.states; ++i) {
    g.truth.insert(sym::X(i), T);
    g.truth.insert(sym::V(i), Variable(v));
    g.truth.insert(sym::B(i), b);
    g.t_ns.push_back(t);
    if (i + 1 == o.states) break;
    RandomGraph::Window& w = windows[i];
    const int n = std::max(2, static_cast<int>(std::lround((o.dt_min_s + (o.dt_max_s - o.dt_min_s) * u01(rng)) * rate_hz)));
    const Vec3 accel_w = randomVec(rng, 1.5);
    const Vec3 gyro_b = randomVec(rng, 0.6);
    PreintegratedImu pim(imu, b);
    for (int k = 0; k < n; ++k) {
      // Specific force in body of a world acceleration, attitude of the window start (good enough:
      // the truth is defined by the preintegration, not by this).
      const Vec3 f_b = T.R.transpose() * (accel_w - imu.gravityWorld()) + b.accel + randomVec(rng, 0.05);
      const Vec3 w_b = gyro_b + b.gyro + randomVec(rng, 0.02);
      w.samples.emplace_back(f_b, w_b);
      pim.integrate(f_b, w_b, 1.0 / rate_hz);
    }
    w.dt_s = n / rate_hz;
    const PreintegratedImu::NavState next = pim.predict(T, v, b);
    T = next.T_w_b;
    v = next.v_w;
    const Vec6 phi = imu.biasTransition(w.dt_s);
    // The bias process of the IMU model itself, so the truth fits the bias factors.
    const Vec6 bias_sigma = imu.biasDiscreteVariance(w.dt_s).cwiseSqrt();
    Vec6 bv = phi.cwiseProduct(b.vector());
    for (int a = 0; a < 6; ++a) bv(a) += bias_sigma(a) * n01(rng);
    b = ImuBias(bv);
    t += static_cast<std::int64_t>(std::llround(w.dt_s * 1e9));
  }

  // IMU factors.
  for (int i = 0; i + 1 < o.states; ++i) {
    const ImuBias& bi = g.truth.bias(sym::B(i));
    PreintegratedImu pim(imu, bi);
    for (const auto& [f, w] : windows[i].samples) pim.integrate(f, w, 1.0 / rate_hz);
    if (u01(rng) < o.combined_probability) {
      g.graph.emplace<CombinedImuFactor>(sym::X(i), sym::V(i), sym::B(i), sym::X(i + 1), sym::V(i + 1), sym::B(i + 1), pim);
    } else {
      g.graph.emplace<ImuFactor>(sym::X(i), sym::V(i), sym::X(i + 1), sym::V(i + 1), sym::B(i), pim);
      g.graph.emplace<BiasGaussMarkovFactor>(sym::B(i), sym::B(i + 1), windows[i].dt_s, imu);
    }
    if (i + 2 < o.states && u01(rng) < o.skip_imu_probability) {
      PreintegratedImu pim2(imu, bi);
      for (int w = i; w <= i + 1; ++w) {
        for (const auto& [f, gy] : windows[w].samples) pim2.integrate(f, gy, 1.0 / rate_hz);
      }
      g.graph.emplace<ImuFactor>(sym::X(i), sym::V(i), sym::X(i + 2), sym::V(i + 2), sym::B(i), pim2);
      g.deferrable.resize(g.graph.size(), false);
      g.deferrable.back() = true;
    }
  }

  // Ranges.
  const std::vector<std::string> losses =
      o.convex_losses_only ? std::vector<std::string>{"gaussian", "huber"} : rangeLossNames();
  RangeNoiseParams noise;
  noise.sigma_m = 0.1;
  g.state_anchors.resize(o.states);
  std::uniform_int_distribution<int> n_ranges(1, std::max(1, o.max_ranges_per_state));
  std::uniform_int_distribution<int> pick_anchor(0, o.anchors - 1);
  std::uniform_int_distribution<int> pick_loss(0, static_cast<int>(losses.size()) - 1);
  std::vector<RobustLossPtr> loss_of;  // built once: the convolved NLOS loss is costly to set up
  for (const std::string& name : losses) loss_of.push_back(makeRangeLoss(name, noise));
  for (int i = 0; i < o.states && o.anchors > 0; ++i) {
    const int count = n_ranges(rng);
    for (int c = 0; c < count; ++c) {
      const int j = pick_anchor(rng);
      const Pose3& Ti = g.truth.pose(sym::X(i));
      const double range = (Ti.transformFrom(p_b_tag) - anchors[j]).norm() + noise.sigma_m * n01(rng);
      const RobustLossPtr loss = o.random_losses ? loss_of[pick_loss(rng)] : nullptr;
      g.graph.emplace<RangeFactor>(sym::X(i), sym::L(j), range, noise.sigma_m, p_b_tag, loss);
      g.deferrable.resize(g.graph.size(), false);
      g.deferrable.back() = true;
      if (std::find(g.state_anchors[i].begin(), g.state_anchors[i].end(), sym::L(j)) == g.state_anchors[i].end()) {
        g.state_anchors[i].push_back(sym::L(j));
      }
    }
  }

  // Priors: survey on the anchors, the start state.
  for (int j = 0; j < o.anchors; ++j) {
    g.graph.emplace<PriorVec3Factor>(sym::L(j), Vec3(anchors[j] + randomVec(rng, 0.02)), Vec3(Vec3::Constant(0.05)));
  }
  const int s = o.prior_state;
  g.graph.emplace<PriorPose3Factor>(sym::X(s), g.truth.pose(sym::X(s)), (Vec6() << 0.1, 0.1, 0.1, 0.3, 0.3, 0.3).finished());
  g.graph.emplace<PriorVec3Factor>(sym::V(s), g.truth.vec3(sym::V(s)), Vec3(Vec3::Constant(0.3)));
  g.graph.emplace<PriorBiasFactor>(sym::B(s), ImuBias(), (Vec6() << 0.1, 0.1, 0.1, 0.01, 0.01, 0.01).finished());

  g.deferrable.resize(g.graph.size(), false);

  // Initial values: perturbed truth, biases at zero, anchors at the truth + survey noise.
  for (const auto& [key, value] : g.truth) {
    if (const auto* Tk = std::get_if<Pose3>(&value)) {
      Vec6 d;
      d << randomVec(rng, o.rotation_perturbation_rad), randomVec(rng, o.position_perturbation_m);
      g.initial.insert(key, Tk->retract(d));
    } else if (std::holds_alternative<ImuBias>(value)) {
      g.initial.insert(key, ImuBias());
    } else if (keySymbol(key) == 'v') {
      g.initial.insert(key, Variable(Vec3(std::get<Vec3>(value) + randomVec(rng, o.velocity_perturbation_m_s))));
    } else {
      g.initial.insert(key, Variable(Vec3(std::get<Vec3>(value) + randomVec(rng, 0.02))));
    }
  }
  return g;
}

// --- Schedules ----------------------------------------------------------------------

enum class FeedOrder {
  kTime,          ///< states in time order
  kRandomGrowth,  ///< from the prior state, growing the covered interval left or right at random
};

struct FeedOptions {
  FeedOrder order = FeedOrder::kTime;
  int max_states_per_update = 3;
  /// A deferrable factor (RandomGraph::deferrable) is held back with this
  /// probability and added later, in a factor-only update (a loop closure),
  /// unless a new variable needs it.
  double defer_probability = 0.3;
  /// After each update, a factor-only update of held-back factors with this probability.
  double loop_update_probability = 0.35;
  bool timestamps = true;
};

/// Increments feeding `g` completely: every new variable comes with a factor,
/// held-back factors arrive in factor-only updates (and at the end).
inline std::vector<Increment> makeSchedule(const RandomGraph& g, std::mt19937& rng, const FeedOptions& o = {}) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::uniform_int_distribution<int> batch(1, std::max(1, o.max_states_per_update));
  std::vector<int> order;
  if (o.order == FeedOrder::kTime) {
    // Starting at the prior state keeps every batch covered; states before it follow in reverse.
    for (int i = g.prior_state; i < g.states; ++i) order.push_back(i);
    for (int i = g.prior_state - 1; i >= 0; --i) order.push_back(i);
  } else {
    int lo = g.prior_state, hi = g.prior_state;
    order.push_back(g.prior_state);
    while (static_cast<int>(order.size()) < g.states) {
      const bool left = lo > 0 && (hi + 1 >= g.states || u01(rng) < 0.5);
      order.push_back(left ? --lo : ++hi);
    }
  }

  // Factors become ready when their last key is present (counted per factor,
  // so long schedules stay linear in the graph size).
  std::unordered_set<Key> present;
  std::vector<bool> added(g.graph.size(), false);
  std::vector<int> missing(g.graph.size(), 0);
  std::unordered_map<Key, std::vector<std::size_t>> factors_of;
  for (std::size_t f = 0; f < g.graph.size(); ++f) {
    for (Key k : g.graph[f]->keys()) factors_of[k].push_back(f);
    missing[f] = static_cast<int>(g.graph[f]->keys().size());
  }
  std::vector<std::size_t> newly_ready;  // ready since the last update, not yet decided
  std::vector<std::size_t> held;         // ready, held back for a loop closure
  auto makePresent = [&](Key k) {
    if (!present.insert(k).second) return;
    for (std::size_t f : factors_of[k]) {
      if (--missing[f] == 0) newly_ready.push_back(f);
    }
  };
  std::vector<Increment> out;
  auto factorOnlyUpdate = [&](double take_probability) {
    Increment inc;
    std::vector<std::size_t> still_held;
    for (std::size_t f : held) {
      if (u01(rng) < take_probability) {
        inc.factors.add(g.graph[f]);
        added[f] = true;
      } else {
        still_held.push_back(f);
      }
    }
    held = std::move(still_held);
    if (inc.factors.size() > 0) out.push_back(std::move(inc));
  };

  std::size_t next = 0;
  while (next < order.size()) {
    Increment inc;
    std::unordered_set<Key> fresh;
    const int count = std::min<int>(batch(rng), static_cast<int>(order.size() - next));
    for (int c = 0; c < count; ++c, ++next) {
      const int i = order[next];
      for (Key k : {sym::X(i), sym::V(i), sym::B(i)}) {
        fresh.insert(k);
        inc.values.insert(k, g.initial.at(k));
        if (o.timestamps) inc.timestamps[k] = g.t_ns[i];
      }
      for (Key l : g.state_anchors[i]) {
        if (!present.count(l) && !fresh.count(l)) {
          fresh.insert(l);
          inc.values.insert(l, g.initial.at(l));
        }
      }
    }
    for (Key k : fresh) makePresent(k);
    // Ready factors, some held back for a later loop closure; held-back ones
    // come back when a new variable would otherwise have no factor.
    std::vector<std::size_t> take, maybe;
    for (std::size_t f : newly_ready) (g.deferrable[f] && u01(rng) < o.defer_probability ? maybe : take).push_back(f);
    newly_ready.clear();
    std::unordered_set<Key> covered;
    for (std::size_t f : take) covered.insert(g.graph[f]->keys().begin(), g.graph[f]->keys().end());
    for (std::size_t f : maybe) {
      const auto& keys = g.graph[f]->keys();
      if (std::any_of(keys.begin(), keys.end(), [&](Key k) { return fresh.count(k) && !covered.count(k); })) {
        take.push_back(f);
        covered.insert(keys.begin(), keys.end());
      } else {
        held.push_back(f);
      }
    }
    std::vector<FactorPtr> factors;
    for (std::size_t f : take) {
      factors.push_back(g.graph[f]);
      added[f] = true;
    }
    std::shuffle(factors.begin(), factors.end(), rng);
    for (auto& f : factors) inc.factors.add(f);
    out.push_back(std::move(inc));
    if (u01(rng) < o.loop_update_probability) factorOnlyUpdate(0.6);
  }
  // Anchors no state ranges to (only their prior) come last with their prior.
  Increment rest;
  for (Key k : g.initial.keys()) {
    if (!present.count(k)) {
      rest.values.insert(k, g.initial.at(k));
      makePresent(k);
    }
  }
  for (std::size_t f : newly_ready) {
    rest.factors.add(g.graph[f]);
    added[f] = true;
  }
  newly_ready.clear();
  if (!rest.values.empty()) out.push_back(std::move(rest));
  factorOnlyUpdate(1.0);
  return out;
}

/// Feeds `inc` and appends its factors to `so_far`.
inline UpdateStats feed(BayesTreeSmoother& smoother, const Increment& inc, FactorGraph& so_far) {
  const UpdateStats st = smoother.update(inc.factors, inc.values, inc.timestamps);
  for (const auto& f : inc.factors) so_far.add(f);
  return st;
}

}  // namespace rilo::testing
