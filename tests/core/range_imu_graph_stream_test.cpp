// RangeImuGraphStream: the Ranging-IMU Fusion paper's graph delivered state by state. The oracle
// is the batch builder as it was before it moved onto the stream (kept below),
// so the stream and today's buildRangeImuGraph are both checked against an
// independent implementation.
#include "estimation/assembly/range_imu_graph_stream.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <typeinfo>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/factors/imu_factor.h"
#include "estimation/factors/prior_factors.h"
#include "estimation/factors/range_factor.h"
#include "estimation/factors/tdoa_factor.h"
#include "estimation/factors/ultrasonic_factor.h"
#include "estimation/noise/noise_model_factory.h"
#include "estimation/noise/weighted_loss.h"
#include "estimation/solver/batch_lm.h"
#include "sim/range_imu_scenario.h"
#include "support/resting_imu.h"

namespace rilo {
namespace {

// ---------------------------------------------------------------------------
// Oracle: buildRangeImuGraph as of commit 510bdb0 (before the stream), logic
// unchanged but for one later rule: a range later than its state is predicted
// at its own time (RangeTimeOffset on the state's velocity).
void legacyIntegrateInterval(const std::vector<ImuSample>& imu, std::size_t& cursor, std::int64_t t_a_ns,
                             std::int64_t t_b_ns, PreintegratedImu& pim) {
  std::int64_t t = t_a_ns;
  while (t < t_b_ns) {
    const std::int64_t t_next = cursor + 1 < imu.size() ? std::min(imu[cursor + 1].t_ns, t_b_ns) : t_b_ns;
    if (t_next > t) {
      pim.integrate(imu[cursor].accel_m_s2, imu[cursor].gyro_rad_s, static_cast<double>(t_next - t) * 1e-9);
      t = t_next;
    }
    if (cursor + 1 < imu.size() && imu[cursor + 1].t_ns <= t) ++cursor;
  }
}

RangeImuGraph legacyBuild(const std::vector<ImuSample>& imu, const std::vector<RangeSample>& ranges,
                          const std::vector<Vec3>& p_w_anchors, const Pose3& T_w_b0_guess, const Vec3& v_w0_guess,
                          const RangeImuGraphParams& params) {
  RangeImuGraph out;
  const RobustLossPtr loss = makeRangeLoss(params.range_loss, params.range_noise);
  std::vector<bool> anchor_used(p_w_anchors.size(), false);
  std::vector<std::size_t> state_of_range(ranges.size());
  for (std::size_t k = 0; k < ranges.size(); ++k) {
    if (out.state_t_ns.empty() || ranges[k].t_ns - out.state_t_ns.back() > params.same_state_window_ns) {
      if (!out.state_t_ns.empty()) {
        const std::int64_t t_last = out.state_t_ns.back();
        const std::int64_t gap = ranges[k].t_ns - t_last;
        const std::int64_t pieces = (gap + params.max_state_interval_ns - 1) / params.max_state_interval_ns;
        for (std::int64_t j = 1; j < pieces; ++j) out.state_t_ns.push_back(t_last + gap * j / pieces);
      }
      out.state_t_ns.push_back(ranges[k].t_ns);
    }
    state_of_range[k] = out.state_t_ns.size() - 1;
  }
  out.graph.emplace<PriorPose3Factor>(sym::X(0), T_w_b0_guess, params.first_pose_sigmas);
  out.graph.emplace<PriorVec3Factor>(sym::V(0), v_w0_guess, Vec3(Vec3::Constant(params.first_velocity_sigma_m_s)));
  Vec6 bias_sigmas;
  bias_sigmas << Vec3::Constant(params.first_accel_bias_sigma), Vec3::Constant(params.first_gyro_bias_sigma);
  out.graph.emplace<PriorBiasFactor>(sym::B(0), ImuBias(), bias_sigmas);
  std::size_t cursor = 0;
  while (cursor + 1 < imu.size() && imu[cursor + 1].t_ns <= out.state_t_ns.front()) ++cursor;
  PreintegratedImu pim(params.imu, ImuBias(), PreintegratedImu::CovarianceMode::kCombined);
  for (std::size_t i = 0; i + 1 < out.state_t_ns.size(); ++i) {
    pim.reset(ImuBias());
    legacyIntegrateInterval(imu, cursor, out.state_t_ns[i], out.state_t_ns[i + 1], pim);
    out.graph.emplace<CombinedImuFactor>(sym::X(i), sym::V(i), sym::B(i), sym::X(i + 1), sym::V(i + 1),
                                         sym::B(i + 1), pim);
    ++out.imu_factors;
  }
  for (std::size_t k = 0; k < ranges.size(); ++k) {
    const RangeSample& r = ranges[k];
    const Key x = sym::X(state_of_range[k]);
    std::optional<RangeTimeOffset> offset;
    const std::int64_t state_t_ns = out.state_t_ns[state_of_range[k]];
    if (r.t_ns != state_t_ns) offset = RangeTimeOffset{sym::V(state_of_range[k]), 1e-9 * static_cast<double>(r.t_ns - state_t_ns)};
    if (params.anchors_as_variables) {
      out.graph.emplace<RangeFactor>(x, sym::L(r.anchor_id), r.range_m, params.range_noise.sigma_m, params.p_b_tag,
                                     loss, offset);
      anchor_used[r.anchor_id] = true;
    } else {
      out.graph.emplace<RangeFactor>(x, p_w_anchors[r.anchor_id], r.range_m, params.range_noise.sigma_m,
                                     params.p_b_tag, loss, offset);
    }
    ++out.range_factors;
  }
  for (std::size_t a = 0; a < p_w_anchors.size(); ++a) {
    if (!anchor_used[a]) continue;
    out.graph.emplace<PriorVec3Factor>(sym::L(a), p_w_anchors[a], Vec3(Vec3::Constant(params.anchor_sigma_m)));
    out.anchor_keys.push_back(sym::L(a));
  }
  return out;
}
// ---------------------------------------------------------------------------

sim::Scenario makeScenario(double seconds, double range_rate_hz = 40.0, std::uint64_t seed = 3) {
  sim::ScenarioParams sp;
  sp.seed = seed;
  sp.duration_s = seconds;
  sp.range_rate_hz = range_rate_hz;
  return sim::simulateScenario(sp);
}

RangeImuGraphParams graphParams(const sim::Scenario& s) {
  RangeImuGraphParams gp;
  gp.p_b_tag = s.p_b_tag;
  gp.imu = sim::imuParamsOf(s.params);
  gp.range_noise.sigma_m = s.params.range_sigma_m;
  return gp;
}

/// How samples reach the stream.
struct Feed {
  /// A range is fed when IMU time reaches t + delay (negative: ahead of the IMU).
  /// Ties: the range first.
  std::int64_t range_delay_ns = 0;
  std::size_t warmup_imu = 0;  ///< IMU samples fed before start()
  bool previous_with_true_bias = false;  ///< else bias zero, as the batch builder
  std::size_t drain_every = 1;  ///< next() is drained after every n-th add (a busy smoother)
};

/// Everything the stream emitted, in order, and what was seen on the way.
struct Collected {
  std::vector<std::int64_t> state_t_ns;
  std::vector<FactorPtr> factors;
  std::vector<Key> anchor_keys;  ///< sorted
  Values values;                 ///< all initial values
  std::size_t increments = 0, ranges_only = 0, imu_only_states = 0;
  std::size_t ranges_on_previous_state = 0;  ///< in new-state increments (late ranges riding along)
  std::size_t max_imu_buffer = 0, max_pending_ranges = 0, max_pending_states = 0;
  std::vector<std::int64_t> newest_range_fed_at_emission;  ///< per new state
};

using IncrementHook = std::function<void(const GraphIncrement&, const RangeImuGraphStream&)>;

Collected feedStream(const sim::Scenario& s, const std::vector<RangeSample>& ranges, const RangeImuGraphParams& gp,
                     const RangeImuStreamOptions& options, const Feed& feed, const IncrementHook& hook = {}) {
  RangeImuGraphStream stream(s.p_w_anchors, gp, options);
  Collected c;
  std::int64_t newest_range_fed = std::numeric_limits<std::int64_t>::min();
  StateEstimate previous;
  auto collect = [&](const GraphIncrement& inc) {
    ++c.increments;
    if (inc.new_state) {
      c.state_t_ns.push_back(inc.t_ns);
      c.newest_range_fed_at_emission.push_back(newest_range_fed);
      if (inc.state_index > 0 && inc.range_factors == 0) ++c.imu_only_states;
      for (const FactorPtr& f : inc.factors) {
        const auto* range = dynamic_cast<const RangeFactor*>(f.get());
        if (range && inc.state_index > 0 && range->poseKey() == sym::X(inc.state_index - 1)) {
          ++c.ranges_on_previous_state;
        }
      }
      const sim::KinematicState st = s.truthAt(inc.t_ns);
      previous.index = inc.state_index;
      previous.t_ns = inc.t_ns;
      previous.T_w_b = st.T_w_b;
      previous.v_w = st.v_w;
      previous.bias = feed.previous_with_true_bias ? ImuBias(s.biasAt(inc.t_ns)) : ImuBias();
    } else {
      ++c.ranges_only;
    }
    for (const FactorPtr& f : inc.factors) c.factors.push_back(f);
    for (const auto& kv : inc.values) c.values.insert(kv.first, kv.second);
    for (Key l : inc.new_anchor_keys) c.anchor_keys.push_back(l);
    if (hook) hook(inc, stream);
  };
  std::size_t adds = 0;
  auto drain = [&] {
    if (++adds % feed.drain_every != 0) return;
    while (std::optional<GraphIncrement> inc = stream.next(previous)) collect(*inc);
    c.max_imu_buffer = std::max(c.max_imu_buffer, stream.imuBufferSize());
    c.max_pending_ranges = std::max(c.max_pending_ranges, stream.pendingRanges());
    c.max_pending_states = std::max(c.max_pending_states, stream.pendingStates());
  };
  // The feed ends 100 ms after the last range: IMU long past it would be a
  // ranging outage, which the stream bridges with IMU-only states the batch
  // graph (ending at the last range) does not have.
  const std::int64_t t_end_ns = ranges.back().t_ns + 100'000'000;
  std::size_t n_imu = s.imu.size();
  while (n_imu > 0 && s.imu[n_imu - 1].t_ns > t_end_ns) --n_imu;
  std::size_t i = 0, k = 0;
  for (; i < feed.warmup_imu; ++i) stream.addImu(s.imu[i]);
  collect(stream.start(ranges.front().t_ns, s.truthAt(ranges.front().t_ns).T_w_b, s.truthAt(ranges.front().t_ns).v_w));
  drain();
  while (i < n_imu || k < ranges.size()) {
    if (k < ranges.size() && (i == n_imu || ranges[k].t_ns + feed.range_delay_ns <= s.imu[i].t_ns)) {
      newest_range_fed = ranges[k].t_ns;
      stream.addRange(ranges[k++]);
    } else {
      stream.addImu(s.imu[i++]);
    }
    drain();
  }
  stream.finish();
  adds = feed.drain_every - 1;
  drain();
  EXPECT_EQ(stream.pendingStates(), 0u);
  EXPECT_EQ(stream.pendingRanges(), 0u);
  std::sort(c.anchor_keys.begin(), c.anchor_keys.end());
  return c;
}

/// Same factors (type, keys, whitened residual at `at`) up to order: both sides
/// are stably sorted by (type, keys), which keeps range factors in range order.
void expectSameFactors(std::vector<FactorPtr> got, std::vector<FactorPtr> want, const Values& at, double rel_tol) {
  ASSERT_EQ(got.size(), want.size());
  auto signature = [](const FactorPtr& f) {
    const Factor& ref = *f;
    return std::make_tuple(std::string(typeid(ref).name()), f->keys());
  };
  auto by_signature = [&](const FactorPtr& a, const FactorPtr& b) { return signature(a) < signature(b); };
  std::stable_sort(got.begin(), got.end(), by_signature);
  std::stable_sort(want.begin(), want.end(), by_signature);
  int mismatches = 0;
  for (std::size_t n = 0; n < got.size() && mismatches < 5; ++n) {
    if (signature(got[n]) != signature(want[n])) {
      ADD_FAILURE() << "factor " << n << ": type or keys differ (" << std::get<0>(signature(got[n])) << " on "
                    << keyString(got[n]->keys()[0]) << " vs " << std::get<0>(signature(want[n])) << " on "
                    << keyString(want[n]->keys()[0]) << ")";
      ++mismatches;
      continue;
    }
    Residual r_got, r_want;
    got[n]->evaluate(at, r_got, nullptr);
    want[n]->evaluate(at, r_want, nullptr);
    const double e_got = got[n]->error(at), e_want = want[n]->error(at);
    const bool ok = (r_got - r_want).norm() <= rel_tol * std::max(1.0, r_want.norm()) &&
                    std::abs(e_got - e_want) <= rel_tol * std::max(1.0, std::abs(e_want));
    if (!ok) {
      ADD_FAILURE() << "factor " << n << " (" << std::get<0>(signature(got[n])) << "): error " << e_got << " vs "
                    << e_want << ", |dr| = " << (r_got - r_want).norm();
      ++mismatches;
    }
  }
}

void expectMatchesLegacy(const sim::Scenario& s, const std::vector<RangeSample>& ranges, const RangeImuGraphParams& gp,
                         const Collected& c) {
  const sim::KinematicState st0 = s.truthAt(ranges.front().t_ns);
  const RangeImuGraph want = legacyBuild(s.imu, ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp);
  for (std::size_t i = 0; i < std::min(c.state_t_ns.size(), want.state_t_ns.size()); ++i) {
    if (c.state_t_ns[i] != want.state_t_ns[i]) {
      ADD_FAILURE() << "first state time differing: state " << i << ": " << c.state_t_ns[i] << " vs " << want.state_t_ns[i];
      break;
    }
  }
  ASSERT_EQ(c.state_t_ns, want.state_t_ns);
  EXPECT_EQ(c.anchor_keys, want.anchor_keys);
  const Values truth = sim::truthValues(s, want.state_t_ns, want.anchor_keys);
  expectSameFactors(c.factors, std::vector<FactorPtr>(want.graph.begin(), want.graph.end()), truth, 1e-9);
}

TEST(GrowingRing, KeepsFifoOrderAcrossWrapAndGrowth) {
  detail::GrowingRing<int> ring(4);
  EXPECT_EQ(ring.capacity(), 4u);
  int next_in = 0, next_out = 0;
  for (int round = 0; round < 50; ++round) {
    for (int k = 0; k < 3 + round % 4; ++k) ring.push_back(next_in++);
    for (int k = 0; k < 2 + round % 3 && !ring.empty(); ++k) {
      ASSERT_EQ(ring.front(), next_out++);
      ring.pop_front();
    }
    ASSERT_EQ(ring.size(), static_cast<std::size_t>(next_in - next_out));
    for (std::size_t k = 0; k < ring.size(); ++k) ASSERT_EQ(ring[k], next_out + static_cast<int>(k));
  }
  EXPECT_EQ(ring.capacity() & (ring.capacity() - 1), 0u);
  ring.pop_front(ring.size());
  EXPECT_TRUE(ring.empty());
}

TEST(RangeImuGraphStream, SampleBySampleMatchesTheBatchGraph) {
  const sim::Scenario s = makeScenario(20.0);
  const RangeImuGraphParams gp = graphParams(s);
  const Collected c = feedStream(s, s.ranges, gp, RangeImuStreamOptions(), Feed());
  expectMatchesLegacy(s, s.ranges, gp, c);
  // 40 Hz, ranges never late: one increment per state plus state 0's ranges.
  EXPECT_EQ(c.ranges_only, 1u);
  EXPECT_EQ(c.increments, c.state_t_ns.size() + 1);
  EXPECT_EQ(c.imu_only_states, 0u);

  // Today's batch builder (on top of the stream) is the legacy one, factor for factor in the same order.
  const sim::KinematicState st0 = s.truthAt(s.ranges.front().t_ns);
  const RangeImuGraph now = buildRangeImuGraph(s.imu, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp);
  const RangeImuGraph legacy = legacyBuild(s.imu, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp);
  EXPECT_EQ(now.state_t_ns, legacy.state_t_ns);
  EXPECT_EQ(now.anchor_keys, legacy.anchor_keys);
  EXPECT_EQ(now.imu_factors, legacy.imu_factors);
  EXPECT_EQ(now.range_factors, legacy.range_factors);
  ASSERT_EQ(now.graph.size(), legacy.graph.size());
  const Values truth = sim::truthValues(s, legacy.state_t_ns, legacy.anchor_keys);
  for (std::size_t n = 0; n < now.graph.size(); ++n) {
    ASSERT_EQ(now.graph[n]->keys(), legacy.graph[n]->keys()) << "factor " << n;
    const double e_now = now.graph[n]->error(truth), e_legacy = legacy.graph[n]->error(truth);
    ASSERT_NEAR(e_now, e_legacy, 1e-12 * std::max(1.0, e_legacy)) << "factor " << n;
  }
}

TEST(RangeImuGraphStream, LateEarlyAndWarmupArrivalsGiveTheSameGraph) {
  const sim::Scenario s = makeScenario(10.0);
  RangeImuGraphParams gp = graphParams(s);
  gp.same_state_window_ns = 60'000'000;  // groups of two or three ranges
  struct Case {
    const char* name;
    Feed feed;
    bool anchors_as_variables;
  };
  const Case cases[] = {
      {"in time order", Feed{0, 0, false}, true},
      {"ranges 20 ms late", Feed{20'000'000, 0, false}, true},
      {"ranges 500 ms early", Feed{-500'000'000, 0, false}, true},
      {"IMU warm-up before start", Feed{0, 200, false}, true},
      {"constant anchors, late ranges", Feed{20'000'000, 0, false}, false},
      // Late ranges then travel with the next state's increment.
      {"late ranges, drained every 150 adds", Feed{20'000'000, 0, false, 150}, true},
  };
  for (const Case& cs : cases) {
    SCOPED_TRACE(cs.name);
    gp.anchors_as_variables = cs.anchors_as_variables;
    const Collected c = feedStream(s, s.ranges, gp, RangeImuStreamOptions(), cs.feed);
    expectMatchesLegacy(s, s.ranges, gp, c);
    if (cs.feed.range_delay_ns > gp.same_state_window_ns / 2 && cs.feed.drain_every == 1) {
      EXPECT_GT(c.ranges_only, 10u) << "late ranges of a closed group come in ranges-only increments";
    }
    if (cs.feed.drain_every > 1) {
      EXPECT_GT(c.ranges_on_previous_state, 5u);
    }
    if (cs.feed.range_delay_ns < 0) {
      EXPECT_GE(c.max_pending_states, 5u);
    }
    if (!cs.anchors_as_variables) {
      EXPECT_TRUE(c.anchor_keys.empty());
    }
  }
}

TEST(RangeImuGraphStream, OneHertzAndFortyHertzRanging) {
  for (double rate_hz : {1.0, 40.0}) {
    SCOPED_TRACE(rate_hz);
    const sim::Scenario s = makeScenario(30.0, rate_hz, 5);
    const RangeImuGraphParams gp = graphParams(s);
    const Collected c = feedStream(s, s.ranges, gp, RangeImuStreamOptions(), Feed());
    expectMatchesLegacy(s, s.ranges, gp, c);
    for (std::size_t i = 1; i < c.state_t_ns.size(); ++i) {
      ASSERT_GT(c.state_t_ns[i], c.state_t_ns[i - 1]);
      ASSERT_LE(c.state_t_ns[i] - c.state_t_ns[i - 1], gp.max_state_interval_ns);
    }
    if (rate_hz == 1.0) {
      // 1 s between ranges, 0.5 s at most between states: one IMU-only state per gap.
      EXPECT_GT(c.imu_only_states, 20u);
      EXPECT_GE(c.imu_only_states + 3, s.ranges.size());
    } else {
      EXPECT_EQ(c.imu_only_states, 0u);
    }
  }
}

std::vector<RangeSample> withBlackout(const sim::Scenario& s, std::int64_t from_ns, std::int64_t to_ns) {
  std::vector<RangeSample> r = s.ranges;
  std::erase_if(r, [&](const RangeSample& m) { return m.t_ns > from_ns && m.t_ns < to_ns; });
  return r;
}

TEST(RangeImuGraphStream, RangingGapWaitingForeverGivesTheBatchGapStates) {
  const sim::Scenario s = makeScenario(12.0);
  const std::int64_t gap_start = s.t0_ns + 4'000'000'000, gap_end = s.t0_ns + 8'000'000'000;
  std::vector<RangeSample> ranges = withBlackout(s, gap_start, gap_end);
  // Ranges after the gap 7.777 us later: the gap is no multiple of anything, so
  // the gap states' times need the exact rounding (floor(gap j / pieces)).
  for (RangeSample& r : ranges) r.t_ns += r.t_ns >= gap_end ? 7'777 : 0;
  RangeImuGraphParams gp = graphParams(s);
  gp.max_state_interval_ns = 400'000'000;
  RangeImuStreamOptions options;
  options.max_range_wait_ns = RangeImuStreamOptions::kWaitForever;
  const Collected c = feedStream(s, ranges, gp, options, Feed());
  expectMatchesLegacy(s, ranges, gp, c);
  EXPECT_GE(c.imu_only_states, 9u);
  // The gap's states depend on the range that ends it: none is out before that range.
  const auto end_range = std::find_if(ranges.begin(), ranges.end(), [&](const RangeSample& r) { return r.t_ns >= gap_end; });
  ASSERT_NE(end_range, ranges.end());
  for (std::size_t i = 0; i < c.state_t_ns.size(); ++i) {
    if (c.state_t_ns[i] > gap_start && c.state_t_ns[i] < gap_end) {
      EXPECT_GE(c.newest_range_fed_at_emission[i], end_range->t_ns) << "state " << i;
    }
  }
  // ... which costs an IMU buffer over the whole gap (800 Hz x 4 s).
  EXPECT_GT(c.max_imu_buffer, 3000u);
}

TEST(RangeImuGraphStream, RangingGapWithBoundedWaitCommitsImuOnlyStatesEarly) {
  const sim::Scenario s = makeScenario(12.0);
  const std::int64_t gap_start = s.t0_ns + 4'000'000'000, gap_end = s.t0_ns + 8'300'000'000;
  const std::vector<RangeSample> ranges = withBlackout(s, gap_start, gap_end);
  RangeImuGraphParams gp = graphParams(s);
  gp.max_state_interval_ns = 400'000'000;
  RangeImuStreamOptions options;
  options.max_range_wait_ns = 1'000'000'000;
  const Collected c = feedStream(s, ranges, gp, options, Feed());

  const sim::KinematicState st0 = s.truthAt(ranges.front().t_ns);
  const RangeImuGraph batch = buildRangeImuGraph(s.imu, ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp);
  // Identical up to the gap; inside it, committed states every max_state_interval_ns...
  const auto last_before = std::find_if(ranges.rbegin(), ranges.rend(), [&](const RangeSample& r) { return r.t_ns <= gap_start; });
  const auto first_after = std::find_if(ranges.begin(), ranges.end(), [&](const RangeSample& r) { return r.t_ns >= gap_end; });
  const std::size_t i0 = static_cast<std::size_t>(
      std::find(c.state_t_ns.begin(), c.state_t_ns.end(), last_before->t_ns) - c.state_t_ns.begin());
  ASSERT_LT(i0, c.state_t_ns.size());
  ASSERT_LE(i0 + 1, batch.state_t_ns.size());
  EXPECT_TRUE(std::equal(c.state_t_ns.begin(), c.state_t_ns.begin() + static_cast<std::ptrdiff_t>(i0) + 1,
                         batch.state_t_ns.begin()));
  std::size_t committed = 0, early = 0;
  std::size_t i = i0 + 1;
  for (; i < c.state_t_ns.size() && c.state_t_ns[i] < first_after->t_ns; ++i) {
    ASSERT_LE(c.state_t_ns[i] - c.state_t_ns[i - 1], gp.max_state_interval_ns);
    if (c.state_t_ns[i] - c.state_t_ns[i - 1] == gp.max_state_interval_ns) ++committed;
    if (c.newest_range_fed_at_emission[i] < first_after->t_ns) ++early;
  }
  ASSERT_LT(i, c.state_t_ns.size());
  EXPECT_EQ(c.state_t_ns[i], first_after->t_ns);
  // (4.3 s - 1 s of waiting) / 0.4 s: 8 committed states out before ranging resumed.
  EXPECT_GE(committed, 8u);
  EXPECT_GE(early, 8u);
  // From the range that ends the gap on, the batch states again.
  const auto j = std::find(batch.state_t_ns.begin(), batch.state_t_ns.end(), first_after->t_ns);
  ASSERT_NE(j, batch.state_t_ns.end());
  EXPECT_TRUE(std::equal(c.state_t_ns.begin() + static_cast<std::ptrdiff_t>(i), c.state_t_ns.end(), j,
                         batch.state_t_ns.end()));
  // ... and the IMU buffer stays within the wait plus one interval.
  const double imu_rate_hz = s.params.imu_rate_hz;
  EXPECT_LE(static_cast<double>(c.max_imu_buffer), 1e-9 * static_cast<double>(options.max_range_wait_ns +
                                                                               gp.max_state_interval_ns) * imu_rate_hz + 4.0);

  // The graph is the batch one apart from the gap's states: solvable to well under a metre.
  const Values truth = sim::truthValues(s, c.state_t_ns, c.anchor_keys);
  FactorGraph g;
  for (const FactorPtr& f : c.factors) g.add(f);
  BatchLevenbergMarquardt lm;
  const auto out = lm.optimize(g, truth);
  EXPECT_TRUE(out.result.converged()) << out.result.message;
  double max_err = 0.0;
  for (std::size_t n = 0; n < c.state_t_ns.size(); ++n) {
    max_err = std::max(max_err, (out.values.pose(sym::X(n)).p - truth.pose(sym::X(n)).p).norm());
  }
  EXPECT_LT(max_err, 1.0);
}

TEST(RangeImuGraphStream, IncrementsCarryKeyTimesValuesAndBiasHat) {
  const sim::Scenario s = makeScenario(5.0);
  const RangeImuGraphParams gp = graphParams(s);
  Values known;
  std::set<Key> anchors_seen;
  std::size_t checked_states = 0;
  std::int64_t prev_state_t_ns = 0;
  const IncrementHook hook = [&](const GraphIncrement& inc, const RangeImuGraphStream& stream) {
    // Key times: exactly the new state's X, V, B; anchors never.
    if (inc.new_state) {
      ASSERT_EQ(inc.key_times_ns.size(), 3u);
      for (const auto& [key, t] : inc.key_times_ns) {
        EXPECT_EQ(keyIndex(key), inc.state_index);
        EXPECT_EQ(t, inc.t_ns);
      }
      EXPECT_EQ(inc.values.size(), 3u + inc.new_anchor_keys.size());
      EXPECT_EQ(stream.lastStateIndex(), inc.state_index);
    } else {
      EXPECT_TRUE(inc.key_times_ns.empty());
      EXPECT_EQ(inc.values.size(), inc.new_anchor_keys.size());
    }
    for (Key l : inc.new_anchor_keys) {
      EXPECT_TRUE(anchors_seen.insert(l).second) << "anchor introduced twice";
      EXPECT_TRUE(inc.values.vec3(l).isApprox(s.p_w_anchors[keyIndex(l)]));
    }
    for (const auto& kv : inc.values) known.insert(kv.first, kv.second);
    // Every factor only uses keys already introduced.
    for (const FactorPtr& f : inc.factors) {
      for (Key k : f->keys()) EXPECT_TRUE(known.exists(k)) << keyString(k);
    }
    if (inc.new_state && inc.state_index > 0) {
      const auto* imu = dynamic_cast<const CombinedImuFactor*>(inc.factors[0].get());
      ASSERT_NE(imu, nullptr);
      // bias_hat = the previous state's bias (the collector passes the true one).
      const ImuBias b_prev(s.biasAt(prev_state_t_ns));
      EXPECT_TRUE(imu->preintegrated().biasHat().vector().isApprox(b_prev.vector(), 1e-12));
      // Initial values: the IMU prediction from the true previous state, close to the truth.
      const sim::KinematicState st = s.truthAt(inc.t_ns);
      EXPECT_LT((inc.values.pose(sym::X(inc.state_index)).p - st.T_w_b.p).norm(), 0.01);
      EXPECT_LT((inc.values.vec3(sym::V(inc.state_index)) - st.v_w).norm(), 0.05);
      ++checked_states;
    }
    if (inc.new_state) prev_state_t_ns = inc.t_ns;
  };
  Feed feed;
  feed.previous_with_true_bias = true;
  const Collected c = feedStream(s, s.ranges, gp, RangeImuStreamOptions(), feed, hook);
  EXPECT_EQ(checked_states + 1, c.state_t_ns.size());
  EXPECT_FALSE(anchors_seen.empty());
}

TEST(RangeImuGraphStream, RejectsBadInput) {
  const sim::Scenario s = makeScenario(2.0);
  const RangeImuGraphParams gp = graphParams(s);
  auto expectMessage = [](const std::function<void()>& f, const std::string& part) {
    try {
      f();
      ADD_FAILURE() << "no exception, expected one mentioning " << part;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };

  // Parameters.
  RangeImuGraphParams bad = gp;
  bad.same_state_window_ns = -1;
  expectMessage([&] { RangeImuGraphStream(s.p_w_anchors, bad); }, "same_state_window_ns");
  bad = gp;
  bad.max_state_interval_ns = bad.same_state_window_ns;
  expectMessage([&] { RangeImuGraphStream(s.p_w_anchors, bad); }, "max_state_interval_ns");
  bad = gp;
  bad.range_loss = "nonsense";
  EXPECT_THROW(RangeImuGraphStream(s.p_w_anchors, bad), std::invalid_argument);
  RangeImuStreamOptions bad_options;
  bad_options.max_range_wait_ns = gp.max_state_interval_ns - 1;
  expectMessage([&] { RangeImuGraphStream(s.p_w_anchors, gp, bad_options); }, "max_range_wait_ns");

  RangeImuGraphStream stream(s.p_w_anchors, gp);
  StateEstimate prev;
  // Call order.
  EXPECT_THROW(stream.next(prev), std::logic_error);
  EXPECT_THROW(stream.finish(), std::logic_error);
  const std::int64_t t0 = s.ranges.front().t_ns;
  const GraphIncrement inc0 = stream.start(t0, s.truthAt(t0).T_w_b, s.truthAt(t0).v_w);
  EXPECT_EQ(inc0.factors.size(), 3u);
  EXPECT_EQ(inc0.state_index, 0u);
  EXPECT_THROW(stream.start(t0, Pose3(), Vec3::Zero()), std::logic_error);
  // `previous` must be the last emitted state.
  prev.t_ns = t0;
  EXPECT_FALSE(stream.next(prev).has_value());
  prev.index = 1;
  expectMessage([&] { stream.next(prev); }, "previous");
  prev.index = 0;
  prev.t_ns = t0 + 1;
  expectMessage([&] { stream.next(prev); }, "previous");
  prev.t_ns = t0;
  prev.v_w.x() = std::nan("");
  expectMessage([&] { stream.next(prev); }, "not finite");
  prev.v_w.setZero();

  // IMU time must increase; the message names the offending t_ns.
  stream.addImu(s.imu[0]);
  stream.addImu(s.imu[1]);
  expectMessage([&] { stream.addImu(s.imu[1]); }, "t_ns=" + std::to_string(s.imu[1].t_ns));
  expectMessage([&] { stream.addImu(s.imu[0]); }, "t_ns=" + std::to_string(s.imu[0].t_ns));
  ImuSample nan_sample = s.imu[2];
  nan_sample.gyro_rad_s.y() = std::nan("");
  expectMessage([&] { stream.addImu(nan_sample); }, "not finite");
  EXPECT_EQ(stream.imuBufferSize(), 2u);

  // Ranges: unknown anchor, time going backwards, before the start, non-finite.
  RangeSample r = s.ranges[1];
  r.anchor_id = static_cast<std::uint32_t>(s.p_w_anchors.size());
  expectMessage([&] { stream.addRange(r); }, "unknown anchor " + std::to_string(s.p_w_anchors.size()));
  stream.addRange(s.ranges[1]);
  r = s.ranges[0];
  expectMessage([&] { stream.addRange(r); }, "before the previous measurement");
  RangeImuGraphStream fresh(s.p_w_anchors, gp);
  fresh.start(s.ranges[1].t_ns, Pose3(), Vec3::Zero());
  expectMessage([&] { fresh.addRange(s.ranges[0]); }, "before the newest state");
  r = s.ranges[2];
  r.range_m = std::numeric_limits<double>::infinity();
  expectMessage([&] { stream.addRange(r); }, "range at t_ns=" + std::to_string(r.t_ns) + ": the value is not finite");
  // TDoA: both anchors known and distinct; ultrasonic: a configured beacon.
  TdoaSample d;
  d.t_ns = s.ranges[2].t_ns;
  d.anchor_a = 0;
  d.anchor_b = static_cast<std::uint32_t>(s.p_w_anchors.size());
  expectMessage([&] { stream.addTdoa(d); }, "tdoa at t_ns=" + std::to_string(d.t_ns) + " names unknown anchor");
  d.anchor_b = 0;
  expectMessage([&] { stream.addTdoa(d); }, "anchor_b equals anchor_a");
  UltrasonicSample u;
  u.t_ns = s.ranges[2].t_ns;
  expectMessage([&] { stream.addUltrasonic(u); }, "unknown ultrasonic beacon 0 (0 known)");

  stream.finish();
  EXPECT_THROW(stream.addImu(s.imu[5]), std::logic_error);
  EXPECT_THROW(stream.addRange(s.ranges[3]), std::logic_error);

  // The batch builder reports the stream's input errors.
  std::vector<RangeSample> unknown = s.ranges;
  unknown[4].anchor_id = 99;
  const sim::KinematicState st0 = s.truthAt(t0);
  EXPECT_THROW(buildRangeImuGraph(s.imu, unknown, s.p_w_anchors, st0.T_w_b, st0.v_w, gp), std::invalid_argument);
  std::vector<ImuSample> unsorted = s.imu;
  std::swap(unsorted[10], unsorted[11]);
  EXPECT_THROW(buildRangeImuGraph(unsorted, s.ranges, s.p_w_anchors, st0.T_w_b, st0.v_w, gp), std::invalid_argument);
}

TEST(RangeImuGraphStream, RefusesAGapBeyondMaxGapInsteadOfPlanningAcrossIt) {
  // One range stamped 28 years ahead planned a state every 0.5 s up to it
  // (issue 37: 23 GB, then the kernel's OOM killer). Refused, nothing planned.
  const sim::Scenario s = makeScenario(2.0);
  const RangeImuGraphParams gp = graphParams(s);
  RangeImuStreamOptions options;
  options.max_gap_ns = 60'000'000'000;  // the default is 600 s
  RangeImuGraphStream stream(s.p_w_anchors, gp, options);
  const std::int64_t t0 = s.ranges.front().t_ns;
  stream.start(t0, s.truthAt(t0).T_w_b, s.truthAt(t0).v_w);
  RangeSample far = s.ranges[1];
  far.t_ns = 900'000'000'000'000'000;
  try {
    stream.addRange(far);
    ADD_FAILURE() << "a range 28 years ahead was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("past the newest state (max_gap_ns"), std::string::npos) << e.what();
  }
  RangeSample edge = s.ranges[1];
  edge.t_ns = t0 + options.max_gap_ns;  // at the bound: planned
  stream.addRange(edge);
  // The IMU likewise, where IMU-only states would be committed across the gap.
  RangeImuGraphStream imu_stream(s.p_w_anchors, gp, options);
  imu_stream.start(t0, s.truthAt(t0).T_w_b, s.truthAt(t0).v_w);
  ImuSample jump = s.imu.back();
  jump.t_ns = t0 + options.max_range_wait_ns + options.max_gap_ns + 1;
  EXPECT_THROW(imu_stream.addImu(jump), std::invalid_argument);
  EXPECT_EQ(imu_stream.imuBufferSize(), 0u);
  RangeImuStreamOptions bad;
  bad.max_gap_ns = gp.max_state_interval_ns - 1;
  EXPECT_THROW(RangeImuGraphStream(s.p_w_anchors, gp, bad), std::invalid_argument);
}

TEST(RangeImuGraphStream, StartKeepsWarmupFromT0AndFinishClosesTheLastGroup) {
  const sim::Scenario s = makeScenario(2.0);
  const RangeImuGraphParams gp = graphParams(s);
  RangeImuGraphStream stream(s.p_w_anchors, gp);
  // Warm-up: 0.5 s of IMU and the ranges in it, before start at the 6th range.
  const std::int64_t t0 = s.ranges[5].t_ns;
  std::size_t i = 0, k = 0;
  for (; s.imu[i].t_ns <= s.t0_ns + 500'000'000; ++i) {
    while (k < s.ranges.size() && s.ranges[k].t_ns <= s.imu[i].t_ns) stream.addRange(s.ranges[k++]);
    stream.addImu(s.imu[i]);
  }
  stream.start(t0, s.truthAt(t0).T_w_b, s.truthAt(t0).v_w);
  EXPECT_EQ(stream.droppedRanges(), 5u);
  // Only the sample in effect at t0 and the later ones are kept.
  const auto in_effect = std::upper_bound(s.imu.begin(), s.imu.end(), t0,
                                          [](std::int64_t t, const ImuSample& m) { return t < m.t_ns; }) - 1;
  EXPECT_EQ(stream.imuBufferSize(), i - static_cast<std::size_t>(in_effect - s.imu.begin()));
  StateEstimate prev;
  prev.t_ns = t0;
  prev.T_w_b = s.truthAt(t0).T_w_b;
  std::size_t ranges_out = 0;
  while (auto inc = stream.next(prev)) {
    ranges_out += inc->range_factors;
    if (inc->new_state) {
      prev.index = inc->state_index;
      prev.t_ns = inc->t_ns;
    }
  }
  // Feed up to exactly the last range's time: its group stays open until finish().
  const std::int64_t t_end = s.ranges[30].t_ns;
  for (; s.imu[i].t_ns <= t_end; ++i) {
    while (k <= 30 && s.ranges[k].t_ns <= s.imu[i].t_ns) stream.addRange(s.ranges[k++]);
    stream.addImu(s.imu[i]);
    while (auto inc = stream.next(prev)) {
      ranges_out += inc->range_factors;
      if (inc->new_state) {
        prev.index = inc->state_index;
        prev.t_ns = inc->t_ns;
      }
    }
  }
  ASSERT_EQ(s.imu[i - 1].t_ns, t_end);
  EXPECT_EQ(stream.pendingStates(), 1u);
  stream.finish();
  while (auto inc = stream.next(prev)) {
    ranges_out += inc->range_factors;
    if (inc->new_state) {
      prev.index = inc->state_index;
      prev.t_ns = inc->t_ns;
    }
  }
  EXPECT_EQ(stream.pendingStates(), 0u);
  EXPECT_EQ(stream.pendingRanges(), 0u);
  EXPECT_EQ(stream.lastStateTime(), t_end);
  EXPECT_EQ(ranges_out, 31u - 5u);
}

TEST(RangeImuGraphStream, BuffersStayBoundedOverALongFeed) {
  const sim::Scenario s = makeScenario(300.0, 40.0, 9);
  const RangeImuGraphParams gp = graphParams(s);
  std::size_t capacity_after_warmup = 0;
  std::size_t capacity_changes = 0;
  const IncrementHook hook = [&](const GraphIncrement& inc, const RangeImuGraphStream& stream) {
    if (inc.t_ns - s.t0_ns < 10'000'000'000) {
      capacity_after_warmup = stream.imuBufferCapacity();
    } else if (stream.imuBufferCapacity() != capacity_after_warmup) {
      ++capacity_changes;
    }
  };
  const Collected c = feedStream(s, s.ranges, gp, RangeImuStreamOptions(), Feed(), hook);
  EXPECT_GT(c.state_t_ns.size(), 10000u);
  // 40 Hz ranging with 5 % dropouts: at most a few state intervals of 800 Hz IMU.
  EXPECT_LE(c.max_imu_buffer, 128u);
  EXPECT_LE(c.max_pending_ranges, 4u);
  EXPECT_LE(c.max_pending_states, 1u);
  EXPECT_EQ(capacity_changes, 0u);
  EXPECT_LE(capacity_after_warmup, RangeImuStreamOptions().initial_imu_capacity);
}

}  // namespace
}  // namespace rilo

namespace rilo {
namespace {

TEST(RangeImuGraphStream, MotionPriorsOnEveryStateWhenEnabled) {
  const sim::Scenario s = makeScenario(3.0);
  RangeImuGraphParams gp = graphParams(s);
  gp.height_band = HeightBand();  // 0.9-1.9 m above the floor
  gp.height_band.floor_z_m = -1.0;
  gp.vertical_speed_sigma_m_s = 0.3;
  std::size_t states = 0;
  std::int64_t t_prev_ns = 0;
  const IncrementHook hook = [&](const GraphIncrement& inc, const RangeImuGraphStream&) {
    if (!inc.new_state) return;
    ++states;
    int bands = 0, holds = 0, vertical = 0;
    for (const FactorPtr& f : inc.factors) {
      if (const auto* b = dynamic_cast<const HeightBandFactor*>(f.get())) {
        EXPECT_EQ(b->keys()[0], sym::X(inc.state_index));
        if (b->zMin() < b->zMax()) {
          ++bands;
          // The band is on the tag; the factor holds the body, an upright lever arm below it.
          EXPECT_DOUBLE_EQ(b->zMin(), -0.1 - gp.p_b_tag.z());
          EXPECT_DOUBLE_EQ(b->zMax(), 0.9 - gp.p_b_tag.z());
          EXPECT_DOUBLE_EQ(b->sigma(), gp.height_band.sigma_m);
        } else {
          ++holds;  // towards the band's middle (no learning here), the same weight per second
          EXPECT_DOUBLE_EQ(b->zMin(), 0.4 - gp.p_b_tag.z());
          const double interval_s = 1e-9 * static_cast<double>(inc.t_ns - t_prev_ns);
          EXPECT_NEAR(b->sigma(), gp.height_band.hold_sigma_m / std::sqrt(interval_s), 1e-9);
        }
      }
      const auto* v = dynamic_cast<const PriorVec3Factor*>(f.get());
      if (v != nullptr && f->keys()[0] == sym::V(inc.state_index) && v->sqrtInformation()(0, 0) < 1e-3) {
        ++vertical;  // horizontal speed left free; state 0's own velocity prior holds all axes
        EXPECT_TRUE(v->prior().isZero());
        // 0.3 per correlation time (0.25 s): states closer share it, state 0 has it whole.
        const double interval_s = inc.state_index == 0 ? 0.25 : 1e-9 * static_cast<double>(inc.t_ns - t_prev_ns);
        EXPECT_NEAR(v->sqrtInformation()(2, 2), 1.0 / (0.3 * std::sqrt(0.25 / std::min(interval_s, 0.25))), 1e-9);
        EXPECT_NEAR(v->sqrtInformation()(2, 2), 1.0 / verticalSpeedPriorSigma(gp, std::llround(interval_s * 1e9)), 1e-6);
      }
    }
    EXPECT_EQ(bands, 1) << "state " << inc.state_index;
    EXPECT_EQ(holds, inc.state_index == 0 ? 0 : 1) << "state " << inc.state_index;
    EXPECT_EQ(vertical, 1) << "state " << inc.state_index;
    t_prev_ns = inc.t_ns;
  };
  feedStream(s, s.ranges, gp, RangeImuStreamOptions(), Feed(), hook);
  EXPECT_GT(states, 10u);
}

TEST(RangeImuGraphStream, RangesOfOneStateArePredictedAtTheirOwnTimes) {
  // Exact LOS ranges at 40 Hz on a walk; 50 ms windows (config/rilod.yaml)
  // group them two or three a state. At the true states every range must fit to well
  // under a centimetre; predicted at the state's own time instead, the later
  // ones would miss by the walk's speed times their delay.
  sim::ScenarioParams sp;
  sp.seed = 7;
  sp.duration_s = 6.0;
  sp.range_rate_hz = 40.0;
  sp.range_sigma_m = 1e-4;
  sp.nlos_fraction = 0.0;
  sp.outlier_probability = 0.0;
  const sim::Scenario s = sim::simulateScenario(sp);
  RangeImuGraphParams gp = graphParams(s);
  gp.same_state_window_ns = 50'000'000;  // the shipped configuration's
  const Collected c = feedStream(s, s.ranges, gp, RangeImuStreamOptions(), Feed());
  EXPECT_LT(c.state_t_ns.size(), s.ranges.size() * 2 / 3);  // grouped
  const Values truth = sim::truthValues(s, c.state_t_ns, c.anchor_keys);
  std::size_t later = 0;
  double worst_m = 0.0, worst_uncompensated_m = 0.0;
  for (const FactorPtr& f : c.factors) {
    const auto* r = dynamic_cast<const RangeFactor*>(f.get());
    if (r == nullptr) continue;
    const std::uint64_t state = keyIndex(r->poseKey());
    const std::int64_t delay_ns = static_cast<std::int64_t>(std::llround(r->timeOffset() * 1e9));
    ASSERT_GE(delay_ns, 0);
    ASSERT_LE(delay_ns, gp.same_state_window_ns);
    worst_m = std::max(worst_m, std::abs(r->measuredRange() - r->predictedRange(truth)));
    if (!r->hasTimeOffset()) continue;
    ++later;
    EXPECT_EQ(r->keys().back(), sym::V(state));
    const RangeFactor at_state(r->poseKey(), r->anchorKey(), r->measuredRange(), r->sigma(), r->leverArm());
    worst_uncompensated_m =
        std::max(worst_uncompensated_m, std::abs(at_state.measuredRange() - at_state.predictedRange(truth)));
  }
  EXPECT_GT(later, s.ranges.size() / 3);
  EXPECT_LT(worst_m, 0.005);
  EXPECT_GT(worst_uncompensated_m, 0.02);
}

/// What TdoaRowsOfOneStateArePredictedAtTheirOwnTimes measures over the
/// factors of one kind: how many, how many later than their state, and the
/// worst miss at the true states with and without their time offset.
struct OwnTimeFit {
  std::size_t factors = 0, later = 0;
  double worst_m = 0.0, worst_uncompensated_m = 0.0;
};

TEST(RangeImuGraphStream, TdoaRowsOfOneStateArePredictedAtTheirOwnTimes) {
  // Exact TDoA rows every 12.5 ms (the office TDoA sims' rate) and exact
  // ultrasonic ranges every 50 ms on a walk, 25 ms windows
  // (LocalizerParams::with_tdoa): two or three measurements a state. At the
  // true states every one must fit to well under a centimetre, the later ones
  // by the state's velocity, as a state's later two-way ranges; with anchors
  // as variables (the service) and as constants.
  const sim::Scenario s = makeScenario(6.0);
  const std::int64_t t0_ns = s.ranges.front().t_ns;
  const std::int64_t t_end_ns = s.ranges.back().t_ns;
  const std::uint32_t n_anchors = static_cast<std::uint32_t>(s.p_w_anchors.size());
  RangeImuGraphParams gp = graphParams(s);
  gp.same_state_window_ns = 25'000'000;
  gp.tdoa_sigma_m = 0.1;
  gp.p_b_ultrasonic = Vec3(0.0, 0.03, 0.14);
  gp.p_w_ultrasonic = {Vec3(2.0, 2.0, 3.0), Vec3(6.0, 4.0, 3.0)};
  std::vector<TdoaSample> rows;
  for (std::int64_t t = t0_ns, k = 0; t < t_end_ns; t += 12'500'000, ++k) {
    TdoaSample d;
    d.t_ns = t;
    d.anchor_a = static_cast<std::uint32_t>(k % n_anchors);
    d.anchor_b = static_cast<std::uint32_t>((k + 3) % n_anchors);
    const Vec3 p_w_tag = s.truthAt(t).T_w_b.transformFrom(s.p_b_tag);
    d.diff_m = (p_w_tag - s.p_w_anchors[d.anchor_b]).norm() - (p_w_tag - s.p_w_anchors[d.anchor_a]).norm();
    rows.push_back(d);
  }
  std::vector<UltrasonicSample> pings;
  for (std::int64_t t = t0_ns + 6'000'000, k = 0; t < t_end_ns; t += 50'000'000, ++k) {
    UltrasonicSample u;
    u.t_ns = t;
    u.anchor_id = static_cast<std::uint32_t>(k % 2);
    u.range_m = (s.truthAt(t).T_w_b.transformFrom(gp.p_b_ultrasonic) - gp.p_w_ultrasonic[u.anchor_id]).norm();
    pings.push_back(u);
  }

  for (const bool vars : {true, false}) {
    gp.anchors_as_variables = vars;
    RangeImuGraphStream stream(s.p_w_anchors, gp);
    std::vector<FactorPtr> factors;
    std::vector<std::int64_t> state_t_ns;
    std::vector<Key> anchor_keys;
    StateEstimate previous;
    auto collect = [&](const GraphIncrement& inc) {
      if (inc.new_state) {
        state_t_ns.push_back(inc.t_ns);
        previous.index = inc.state_index;
        previous.t_ns = inc.t_ns;
        previous.T_w_b = s.truthAt(inc.t_ns).T_w_b;
        previous.v_w = s.truthAt(inc.t_ns).v_w;
      }
      for (const FactorPtr& f : inc.factors) factors.push_back(f);
      for (Key l : inc.new_anchor_keys) anchor_keys.push_back(l);
    };
    collect(stream.start(t0_ns, s.truthAt(t0_ns).T_w_b, s.truthAt(t0_ns).v_w));
    std::size_t i = 0, k = 0, u = 0;
    while (i < s.imu.size() && s.imu[i].t_ns <= t_end_ns + 100'000'000) {
      if (k < rows.size() && rows[k].t_ns <= s.imu[i].t_ns && (u == pings.size() || rows[k].t_ns <= pings[u].t_ns)) {
        stream.addTdoa(rows[k++]);
      } else if (u < pings.size() && pings[u].t_ns <= s.imu[i].t_ns) {
        stream.addUltrasonic(pings[u++]);
      } else {
        stream.addImu(s.imu[i++]);
      }
      while (std::optional<GraphIncrement> inc = stream.next(previous)) collect(*inc);
    }
    stream.finish();
    while (std::optional<GraphIncrement> inc = stream.next(previous)) collect(*inc);
    std::sort(anchor_keys.begin(), anchor_keys.end());
    const Values truth = sim::truthValues(s, state_t_ns, anchor_keys);
    OwnTimeFit tdoa, ultrasonic;
    for (const FactorPtr& f : factors) {
      if (const auto* t = dynamic_cast<const TdoaFactor*>(f.get())) {
        ++tdoa.factors;
        ASSERT_GE(t->timeOffset(), 0.0);
        ASSERT_LE(t->timeOffset(), 0.025 + 1e-9);
        tdoa.worst_m = std::max(tdoa.worst_m, std::abs(t->measuredDifference() - t->predictedDifference(truth)));
        if (!t->hasTimeOffset()) continue;
        ++tdoa.later;
        EXPECT_EQ(t->keys().back(), sym::V(keyIndex(t->poseKey())));
        EXPECT_EQ(t->anchorsAreVariables(), vars);
        const TdoaFactor at_state = vars ? TdoaFactor(t->poseKey(), t->anchorAKey(), t->anchorBKey(),
                                                      t->measuredDifference(), t->sigma(), t->leverArm())
                                         : TdoaFactor(t->poseKey(), t->anchorAPosition(truth), t->anchorBPosition(truth),
                                                      t->measuredDifference(), t->sigma(), t->leverArm());
        tdoa.worst_uncompensated_m = std::max(tdoa.worst_uncompensated_m,
                                              std::abs(at_state.measuredDifference() - at_state.predictedDifference(truth)));
      } else if (const auto* us = dynamic_cast<const UltrasonicFactor*>(f.get())) {
        ++ultrasonic.factors;
        ultrasonic.worst_m = std::max(ultrasonic.worst_m, std::abs(us->measuredRange() - us->predictedRange(truth)));
        if (!us->hasTimeOffset()) continue;
        ++ultrasonic.later;
        EXPECT_EQ(us->keys().back(), sym::V(keyIndex(us->poseKey())));
        const UltrasonicFactor at_state(us->poseKey(), us->anchorPosition(truth), us->measuredRange(), us->sigmaRange(),
                                        us->leverArm());
        ultrasonic.worst_uncompensated_m = std::max(ultrasonic.worst_uncompensated_m,
                                                    std::abs(at_state.measuredRange() - at_state.predictedRange(truth)));
      }
    }
    SCOPED_TRACE(vars ? "anchors as variables" : "anchors as constants");
    EXPECT_GT(tdoa.factors, rows.size() * 9 / 10);
    EXPECT_GT(tdoa.later, tdoa.factors / 3);
    EXPECT_LT(tdoa.worst_m, 0.005);
    EXPECT_GT(tdoa.worst_uncompensated_m, 0.01);
    EXPECT_GT(ultrasonic.factors, pings.size() * 9 / 10);
    EXPECT_GT(ultrasonic.later, ultrasonic.factors / 2) << "6 ms after a row's state at least";
    EXPECT_LT(ultrasonic.worst_m, 0.002);
    EXPECT_GT(ultrasonic.worst_uncompensated_m, 0.005);
  }
}

TEST(RangeImuGraphStream, RangesSpeakToTheHeightByTheirVerticalLever) {
  const sim::Scenario s = makeScenario(3.0);
  RangeImuGraphParams gp = graphParams(s);
  gp.height_band = HeightBand();  // 0.9-1.9 m: middle 1.4 m, half-width 0.5 m
  gp.height_band.floor_z_m = -1.0;
  const double mid_z = 0.4;
  const double s0 = gp.range_noise.sigma_m / 0.5;
  int zero = 0, full = 0, between = 0;
  const IncrementHook hook = [&](const GraphIncrement& inc, const RangeImuGraphStream&) {
    for (const FactorPtr& f : inc.factors) {
      const auto* r = dynamic_cast<const RangeFactor*>(f.get());
      if (r == nullptr) continue;
      const Vec3 p_w_anchor = s.p_w_anchors[keyIndex(r->anchorKey())];
      const double dz = mid_z - p_w_anchor.z();
      const double sine = std::abs(dz) / std::max(std::abs(dz), r->measuredRange());
      if (sine <= s0) {
        EXPECT_EQ(r->verticalWeight(), 0.0) << "sine " << sine;
        ++zero;
      } else if (sine >= 2.0 * s0) {
        EXPECT_EQ(r->verticalWeight(), 1.0) << "sine " << sine;
        ++full;
      } else {
        EXPECT_GT(r->verticalWeight(), 0.0) << "sine " << sine;
        EXPECT_LT(r->verticalWeight(), 1.0) << "sine " << sine;
        ++between;
      }
    }
  };
  feedStream(s, s.ranges, gp, RangeImuStreamOptions(), Feed(), hook);
  EXPECT_GT(zero + full + between, 50);
  EXPECT_GT(full, 0);  // the scenario has anchors well above and below the middle
  // Without the band, or with the lever off, every range keeps its full weight.
  for (const bool band_on : {false, true}) {
    RangeImuGraphParams off = gp;
    off.height_band.enabled = band_on;
    off.height_band.range_lever = false;
    int reduced = 0;
    feedStream(s, s.ranges, off, RangeImuStreamOptions(), Feed(),
               [&](const GraphIncrement& inc, const RangeImuGraphStream&) {
                 for (const FactorPtr& f : inc.factors) {
                   const auto* r = dynamic_cast<const RangeFactor*>(f.get());
                   if (r != nullptr && r->verticalWeight() != 1.0) ++reduced;
                 }
               });
    EXPECT_EQ(reduced, 0) << "band " << band_on;
  }
}

// With learning on, the hold's centre moves from the band's middle to the
// heights the tracker estimated where ranges told the height (here the
// truth, fed back as the post-fit estimate); off, it stays in the middle.
TEST(RangeImuGraphStream, CarryHeightLearntWhereRangesTellTheHeight) {
  const sim::Scenario s = makeScenario(20.0);
  RangeImuGraphParams gp = graphParams(s);
  gp.height_band = HeightBand();  // 0.9-1.9 m above a floor at 0: middle 1.4 m
  const double truth_z = s.truthAt(s.t0_ns).T_w_b.transformFrom(s.p_b_tag).z();
  ASSERT_LT(std::abs(truth_z - 1.4), 0.4) << "the walk must lie in the band, away from its middle";
  ASSERT_GT(std::abs(truth_z - 1.4), 0.05);
  for (const bool learn : {false, true}) {
    RangeImuStreamOptions options;
    options.learn_carry_height = learn;
    double carry_m = 0.0, hold_z_m = 0.0;
    feedStream(s, s.ranges, gp, options, Feed(), [&](const GraphIncrement& inc, const RangeImuGraphStream& stream) {
      carry_m = stream.carryHeightM();
      for (const FactorPtr& f : inc.factors) {
        const auto* b = dynamic_cast<const HeightBandFactor*>(f.get());
        if (b != nullptr && b->zMin() == b->zMax()) hold_z_m = b->zMin() + gp.p_b_tag.z();
      }
    });
    if (learn) {
      EXPECT_NEAR(carry_m, truth_z, 0.05);
      EXPECT_NEAR(hold_z_m, truth_z, 0.05) << "new states are held at the learnt height";
    } else {
      EXPECT_DOUBLE_EQ(carry_m, 1.4);
      EXPECT_DOUBLE_EQ(hold_z_m, 1.4);
    }
  }
}

TEST(RangeImuGraphStream, RejectsBadMotionPriors) {
  const sim::Scenario s = makeScenario(1.0);
  RangeImuGraphParams gp = graphParams(s);
  gp.vertical_speed_sigma_m_s = -1.0;
  EXPECT_THROW(RangeImuGraphStream(s.p_w_anchors, gp), std::invalid_argument);
  gp.vertical_speed_sigma_m_s = 0.3;
  for (double tau_s : {0.0, -0.1, std::numeric_limits<double>::infinity(), std::nan("")}) {
    gp.vertical_speed_correlation_s = tau_s;
    EXPECT_THROW(RangeImuGraphStream(s.p_w_anchors, gp), std::invalid_argument) << tau_s;
  }
  gp.vertical_speed_correlation_s = 0.25;
  gp.vertical_speed_sigma_m_s = 0.0;
  gp.height_band = HeightBand();
  gp.height_band.max_height_m = 0.1;  // below min_height_m
  EXPECT_THROW(RangeImuGraphStream(s.p_w_anchors, gp), std::invalid_argument);
}

// The zero-velocity prior: on each state whose interval the IMU shows still
// (a stop, turning on the spot, from 4 to 8 s), none while walking, weighted
// per second of standstill whatever the state spacing.
TEST(RangeImuGraphStream, ZeroVelocityPriorOnStatesTheImuShowsStill) {
  const sim::Scenario s = testing::withRestingImu(makeScenario(12.0), 4.0, 8.0);
  for (const double sigma : {0.0, 0.05}) {
    RangeImuGraphParams gp = graphParams(s);
    gp.zero_velocity_sigma_m_s = sigma;
    gp.standstill.max_speed_m_s = std::numeric_limits<double>::infinity();  // only the IMU rests, not the truth
    std::size_t still_states = 0, walking_states = 0, priors = 0;
    std::int64_t t_prev_ns = 0;
    const IncrementHook hook = [&](const GraphIncrement& inc, const RangeImuGraphStream&) {
      if (!inc.new_state) return;
      const double t = 1e-9 * static_cast<double>(inc.t_ns - s.t0_ns);
      const double t_prev = 1e-9 * static_cast<double>(t_prev_ns - s.t0_ns);
      const bool inside = t_prev >= 4.0 + gp.standstill.window_s && t <= 8.0;  // the whole window rests
      const bool outside = t < 4.0 || t_prev > 8.0;  // steps in the interval or its window
      int found = 0;
      for (const FactorPtr& f : inc.factors) {
        const auto* v = dynamic_cast<const PriorVec3Factor*>(f.get());
        if (v == nullptr || f->keys()[0] != sym::V(inc.state_index) || inc.state_index == 0) continue;
        ++found;
        EXPECT_TRUE(v->prior().isZero());
        const double dt_s = 1e-9 * static_cast<double>(inc.t_ns - t_prev_ns);
        for (int a = 0; a < 3; ++a) EXPECT_NEAR(v->sqrtInformation()(a, a), 1.0 / (sigma / std::sqrt(dt_s)), 1e-9);
      }
      priors += found;
      if (inside) {
        ++still_states;
        EXPECT_EQ(found, sigma > 0.0 ? 1 : 0) << "still state at " << t << " s";
      } else if (outside && inc.state_index > 0) {
        ++walking_states;
        EXPECT_EQ(found, 0) << "walking state at " << t << " s";
      }
      t_prev_ns = inc.t_ns;
    };
    feedStream(s, s.ranges, gp, RangeImuStreamOptions(), Feed(), hook);
    EXPECT_GT(still_states, 100u);  // 3.5 s at 40 Hz less dropouts
    EXPECT_GT(walking_states, 200u);
    if (sigma == 0.0) {
      EXPECT_EQ(priors, 0u);
    }
  }
}

// A glide (the analytic walk has no gait, so its accelerometer is as still
// as a stop's at times): no prior on a state whose predecessor moves faster
// than standstill.max_speed_m_s.
TEST(RangeImuGraphStream, NoZeroVelocityPriorWhileGliding) {
  const sim::Scenario s = makeScenario(12.0);
  RangeImuGraphParams gp = graphParams(s);
  gp.zero_velocity_sigma_m_s = 0.05;
  for (const double max_speed : {std::numeric_limits<double>::infinity(), 0.5}) {
    gp.standstill.max_speed_m_s = max_speed;
    std::size_t fast_priors = 0, priors = 0;
    double v_prev = 0.0;
    const IncrementHook hook = [&](const GraphIncrement& inc, const RangeImuGraphStream&) {
      if (!inc.new_state) return;
      for (const FactorPtr& f : inc.factors) {
        const auto* v = dynamic_cast<const PriorVec3Factor*>(f.get());
        if (v == nullptr || f->keys()[0] != sym::V(inc.state_index) || inc.state_index == 0) continue;
        ++priors;
        fast_priors += v_prev >= 0.5;
      }
      v_prev = s.truthAt(inc.t_ns).v_w.norm();  // feedStream's previous estimate is the truth
    };
    feedStream(s, s.ranges, gp, RangeImuStreamOptions(), Feed(), hook);
    if (std::isinf(max_speed)) {
      EXPECT_GT(fast_priors, 0u) << "the IMU alone takes the glide for a stop";
    } else {
      EXPECT_EQ(fast_priors, 0u);
    }
    EXPECT_LE(priors, 200u);
  }
}

TEST(RangeImuGraphStream, RejectsABadZeroVelocityPrior) {
  const sim::Scenario s = makeScenario(1.0);
  RangeImuGraphParams gp = graphParams(s);
  for (const double bad : {-0.1, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    gp.zero_velocity_sigma_m_s = bad;
    try {
      RangeImuGraphStream stream(s.p_w_anchors, gp);
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("zero_velocity_sigma_m_s"), std::string::npos) << e.what();
    }
  }
  gp.zero_velocity_sigma_m_s = 0.05;
  gp.standstill.window_s = 0.0;
  EXPECT_THROW(RangeImuGraphStream(s.p_w_anchors, gp), std::invalid_argument);
  gp.standstill = StandstillParams();
  gp.standstill.max_speed_m_s = 0.0;
  EXPECT_THROW(RangeImuGraphStream(s.p_w_anchors, gp), std::invalid_argument);
}

TEST(HeightBand, PlausibleOnlyWhenTheAnchorsSitAboveItsFloor) {
  HeightBand band;  // floor z = 0
  const std::vector<Vec3> wall_mounted = {Vec3(0, 0, 2.5), Vec3(10, 0, 2.1), Vec3(0, 8, 2.8), Vec3(1e6, 1e6, 1e6)};
  EXPECT_TRUE(band.plausibleFor(wall_mounted));
  // A headset frame: the origin at eye height, the anchors around it.
  const std::vector<Vec3> headset_frame = {Vec3(0, 0, 0.9), Vec3(10, 0, 0.5), Vec3(0, 8, -0.3)};
  EXPECT_FALSE(band.plausibleFor(headset_frame));
  band.floor_z_m = -1.6;  // ... unless the floor is given in that frame
  EXPECT_TRUE(band.plausibleFor(headset_frame));
  const std::vector<Vec3> below_floor = {Vec3(0, 0, 2.5), Vec3(10, 0, 2.1), Vec3(0, 8, -1.0)};
  EXPECT_FALSE(HeightBand().plausibleFor(below_floor));
  EXPECT_FALSE(HeightBand().plausibleFor(std::vector<Vec3>{}));
}

}  // namespace
}  // namespace rilo

namespace rilo {
namespace {

// RangeImuStreamOptions::range_repeats (range_repeats.h): with a correlation
// time of 1 s, a two-way range counts one over its anchor's ranges in a
// second, through a WeightedLoss around the configured loss; at 1 Hz an
// anchor is heard every few seconds and no range is weighed down; off (the
// default) the graph is the legacy one.
TEST(RangeImuGraphStream, AnAnchorsRangesWithinTheCorrelationTimeCountAsOne) {
  for (double rate_hz : {1.0, 40.0}) {
    SCOPED_TRACE(rate_hz);
    const sim::Scenario s = makeScenario(30.0, rate_hz, 5);
    const RangeImuGraphParams gp = graphParams(s);
    RangeImuStreamOptions options;
    EXPECT_EQ(options.range_repeats.error_correlation_s, 0.0) << "off unless the tracker asks";
    const auto weighed = [](const FactorPtr& f) { return dynamic_cast<const WeightedLoss*>(f->loss()) != nullptr; };
    const Collected off = feedStream(s, s.ranges, gp, options, Feed());
    EXPECT_TRUE(std::none_of(off.factors.begin(), off.factors.end(), weighed)) << "off: the legacy graph";
    options.range_repeats.error_correlation_s = 1.0;
    const Collected c = feedStream(s, s.ranges, gp, options, Feed());
    std::vector<double> weights;
    std::size_t ranges = 0;
    for (const FactorPtr& f : c.factors) {
      if (dynamic_cast<const RangeFactor*>(f.get()) == nullptr) continue;
      ++ranges;
      if (const auto* w = dynamic_cast<const WeightedLoss*>(f->loss())) {
        EXPECT_EQ(w->inner()->name(), makeRangeLoss(gp.range_loss, gp.range_noise)->name());
        weights.push_back(w->w());
      }
    }
    ASSERT_GT(ranges, 20u);
    if (rate_hz == 1.0) {
      EXPECT_TRUE(weights.empty());
      continue;
    }
    // An anchor's ranges are weighed from its second on (one right after a
    // pause as long as the window may count alone), each by one over the
    // ranges its anchor gets a second while it is heard: the mean interval,
    // a pause counted as one second (per range, the median over all ranges).
    std::map<std::uint32_t, std::vector<std::int64_t>> times;
    for (const RangeSample& r : s.ranges) times[r.anchor_id].push_back(r.t_ns);
    EXPECT_GE(weights.size() + 2 * times.size(), ranges);
    std::vector<double> per_anchor_w;
    for (const auto& [id, t] : times) {
      if (t.size() < 10) continue;
      double sum_s = 0.0;
      for (std::size_t k = 1; k < t.size(); ++k) sum_s += std::min(1.0, 1e-9 * static_cast<double>(t[k] - t[k - 1]));
      per_anchor_w.insert(per_anchor_w.end(), t.size(), sum_s / static_cast<double>(t.size() - 1));
    }
    std::nth_element(weights.begin(), weights.begin() + static_cast<std::ptrdiff_t>(weights.size() / 2), weights.end());
    std::nth_element(per_anchor_w.begin(), per_anchor_w.begin() + static_cast<std::ptrdiff_t>(per_anchor_w.size() / 2),
                     per_anchor_w.end());
    const double expected_w = per_anchor_w[per_anchor_w.size() / 2];
    EXPECT_NEAR(weights[weights.size() / 2], expected_w, 0.25 * expected_w);
    EXPECT_LT(expected_w, 0.5) << "the test must weigh ranges down";
  }
}

}  // namespace
}  // namespace rilo
