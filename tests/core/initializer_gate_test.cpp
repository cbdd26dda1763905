// The Initializer's cost controls: the gate of the batch solve (predicted
// sigmas) and the verdict kept when an attempt sees no new data. Each must
// leave what is accepted unchanged.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "estimation/init/initializer.h"
#include "sim/range_imu_scenario.h"
#include "support/initializer_scenarios.h"
#include "support/online_run.h"

namespace rilo {
namespace {

using testing::movingScenario;
InitializerParams paramsFor(const sim::Scenario& s) { return testing::initializerParamsFor(s); }

/// Feeds the scenario in time order, process() after every IMU sample, until
/// initialized or the data ends; `on_attempt` sees the status after every
/// attempt that ran.
void feed(const sim::Scenario& s, Initializer& init, const std::function<void(const InitStatus&)>& on_attempt = {}) {
  std::size_t i = 0, r = 0;
  int attempts = 0;
  while ((i < s.imu.size() || r < s.ranges.size()) && !init.initialized()) {
    if (r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns)) {
      init.addRange(s.ranges[r++]);
    } else {
      init.addImu(s.imu[i++]);
      init.process();
      if (on_attempt && init.status().attempts != attempts) on_attempt(init.status());
      attempts = init.status().attempts;
    }
  }
}

double yawDiffRad(const Mat3& a, const Mat3& b) {
  const Mat3 E = a * b.transpose();
  return std::abs(std::atan2(E(1, 0), E(0, 0)));
}

TEST(InitializerBatchGate, AcceptsTheSameSolveAsWithoutTheGate) {
  // Smooth walks: yaw takes 10-20 s, so most batches are rejected for their
  // sigmas first. The gate skips some of them; the accepted solve is the same.
  int gated = 0;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const sim::Scenario s = movingScenario(seed, 40.0, 35.0);
    InitializerParams p_off = paramsFor(s);
    p_off.batch_gate_sigma_factor = std::numeric_limits<double>::infinity();
    Initializer with_gate(s.p_w_anchors, paramsFor(s)), without(s.p_w_anchors, p_off);
    feed(s, with_gate);
    feed(s, without);
    ASSERT_TRUE(without.initialized()) << "seed " << seed << ": " << without.status().message;
    ASSERT_TRUE(with_gate.initialized()) << "seed " << seed << ": " << with_gate.status().message;
    const InitResult &a = with_gate.result(), &b = without.result();
    EXPECT_EQ(a.state.t_ns, b.state.t_ns) << "seed " << seed;
    EXPECT_EQ(a.window_start_ns, b.window_start_ns) << "seed " << seed;
    EXPECT_LT((a.state.T_w_b.p - b.state.T_w_b.p).norm(), 1e-9) << "seed " << seed;
    EXPECT_LT(yawDiffRad(a.state.T_w_b.R, b.state.T_w_b.R), 1e-9) << "seed " << seed;
    EXPECT_EQ(without.status().gated_solves, 0);
    EXPECT_EQ(with_gate.status().attempts, without.status().attempts);
    EXPECT_EQ(with_gate.status().batch_solves + with_gate.status().gated_solves, without.status().batch_solves);
    gated += with_gate.status().gated_solves;
  }
  EXPECT_GT(gated, 0) << "the gate never skipped a solve: these walks no longer test it";
}

TEST(InitializerBatchGate, SolvesAtLeastEveryMaxSeconds) {
  // Acceptance made impossible (yaw sigma <= 1e-6 rad): every prediction
  // fails the gate, yet a solve runs at least every batch_gate_max_s.
  const sim::Scenario s = movingScenario(2, 40.0, 20.0);
  InitializerParams p = paramsFor(s);
  p.max_yaw_sigma_rad = 1e-6;
  p.batch_gate_max_s = 2.0;
  // The alignment's gate as before the noise-scaled yaw gap: with it this
  // 25 %-NLOS walk reaches the batch stage too late for two solves in 20 s.
  p.max_yaw_gap_noise_scale = 1.0;
  Initializer init(s.p_w_anchors, p);
  std::vector<std::int64_t> solve_t_ns;
  std::int64_t first_batch_stage_ns = -1;
  int solves = 0;
  feed(s, init, [&](const InitStatus& st) {
    if (st.state == InitState::kBatchRejected && first_batch_stage_ns < 0) first_batch_stage_ns = st.t_ns;
    if (st.batch_solves != solves) solve_t_ns.push_back(st.t_ns);
    solves = st.batch_solves;
  });
  EXPECT_FALSE(init.initialized());
  ASSERT_GE(first_batch_stage_ns, 0);
  ASSERT_GE(solve_t_ns.size(), 2u);
  EXPECT_GT(init.status().gated_solves, 0);
  // Between solves: at most batch_gate_max_s plus one attempt interval.
  const auto limit_ns = static_cast<std::int64_t>((p.batch_gate_max_s + p.max_attempt_interval_s) * 1e9) + 1;
  EXPECT_LE(solve_t_ns.front() - first_batch_stage_ns, limit_ns);
  for (std::size_t k = 1; k < solve_t_ns.size(); ++k) EXPECT_LE(solve_t_ns[k] - solve_t_ns[k - 1], limit_ns);
  const std::int64_t t_end = s.imu.back().t_ns;
  EXPECT_LE(t_end - solve_t_ns.back(), limit_ns);
}

TEST(InitializerBatchGate, ARejectedAttemptIsNotRepeatedWithoutNewData) {
  const sim::Scenario s = movingScenario(3, 40.0, 20.0);
  InitializerParams p = paramsFor(s);
  p.max_yaw_sigma_rad = 1e-6;  // every solve is rejected
  p.batch_gate_sigma_factor = std::numeric_limits<double>::infinity();
  Initializer init(s.p_w_anchors, p);
  std::size_t i = 0, r = 0;
  while (i < s.imu.size() && init.status().state != InitState::kBatchRejected) {
    if (r < s.ranges.size() && s.ranges[r].t_ns <= s.imu[i].t_ns) {
      init.addRange(s.ranges[r++]);
    } else {
      init.addImu(s.imu[i++]);
      init.process();
    }
  }
  ASSERT_EQ(init.status().state, InitState::kBatchRejected) << init.status().message;
  const int solves = init.status().batch_solves;
  const std::string message = init.status().message;
  EXPECT_FALSE(init.attempt());
  EXPECT_FALSE(init.attempt());
  EXPECT_EQ(init.status().batch_solves, solves);
  EXPECT_EQ(init.status().state, InitState::kBatchRejected);
  EXPECT_EQ(init.status().message, message);
  // New data: the attempt runs again.
  ASSERT_LT(i, s.imu.size());
  init.addImu(s.imu[i]);
  EXPECT_FALSE(init.attempt());
  EXPECT_EQ(init.status().batch_solves, solves + 1);
}

TEST(InitializerBatchGate, InvalidGateParamsThrow) {
  const sim::Scenario s = movingScenario(1, 40.0, 1.0);
  InitializerParams p = paramsFor(s);
  p.batch_gate_sigma_factor = 0.9;
  EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument);
  p = paramsFor(s);
  p.batch_gate_max_s = 0.0;
  EXPECT_THROW(Initializer(s.p_w_anchors, p), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
