#include <gtest/gtest.h>

#include <cstdint>
#include <stdexcept>
#include <vector>

#include "hal/dw3000/anchor_scheduler.h"

namespace rilo::dw3000 {
namespace {

using State = AnchorScheduler::State;
constexpr std::int64_t kMs = 1'000'000;

AnchorSchedulerParams params() {
  AnchorSchedulerParams p;
  p.max_active = 2;
  p.range_rate_hz = 10.0;
  p.rediscovery_period_ns = 250 * kMs;
  p.vacancy_rediscovery_period_ns = 20 * kMs;
  p.hysteresis_db = 3.0;
  p.strength_smoothing = 1.0;  // tests see each new value at once
  p.max_failures = 3;
  p.backoff_initial_ns = 20 * kMs;
  p.backoff_max_ns = 100 * kMs;
  return p;
}

TEST(Dw3000Scheduler, SweepsEveryAnchorThenKeepsTheStrongest) {
  AnchorScheduler s(4, params());
  const std::vector<double> strength{-10.0, -3.0, -20.0, -1.0};
  std::int64_t now = 0;
  for (std::size_t expected = 0; expected < 4; ++expected) {
    const auto pick = s.next(now);
    EXPECT_EQ(pick.index, expected);
    EXPECT_TRUE(pick.discovery);
    EXPECT_EQ(pick.at_ns, now);
    s.reportSuccess(pick.index, now, strength[pick.index]);
    now += kMs;
  }
  // 0 and 1 filled the set; 3 (-1 dB) beat the weakest (0, -10 dB); 2 did not.
  EXPECT_EQ(s.state(1), State::kActive);
  EXPECT_EQ(s.state(3), State::kActive);
  EXPECT_EQ(s.state(0), State::kCandidate);
  EXPECT_EQ(s.state(2), State::kCandidate);
  EXPECT_EQ(s.activeCount(), 2u);
}

TEST(Dw3000Scheduler, RangesActiveAnchorsAtTheRateAndRediscoversOnePerPeriod) {
  AnchorScheduler s(4, params());
  std::int64_t now = 0;
  const std::vector<double> strength{-1.0, -2.0, -20.0, -30.0};
  std::vector<int> polls(4, 0);
  std::vector<int> discovery(4, 0);
  while (now < 2'000 * kMs) {
    const auto pick = s.next(now);
    if (pick.at_ns > now) {
      now = pick.at_ns;
      continue;
    }
    ++polls[pick.index];
    if (pick.discovery) ++discovery[pick.index];
    s.reportSuccess(pick.index, now, strength[pick.index]);
    now += kMs;  // the exchange takes a millisecond
  }
  // 10 Hz over 2 s for the two strongest; the two weak ones share one
  // rediscovery poll per 250 ms (after the initial sweep).
  EXPECT_NEAR(polls[0], 20, 1);
  EXPECT_NEAR(polls[1], 20, 1);
  EXPECT_EQ(discovery[0], 1);
  EXPECT_EQ(discovery[1], 1);
  EXPECT_NEAR(discovery[2] + discovery[3], 2 + 8, 1);
  EXPECT_GE(discovery[2], 4);
  EXPECT_GE(discovery[3], 4);
  EXPECT_EQ(s.state(2), State::kCandidate);
}

TEST(Dw3000Scheduler, AStrongerCandidateIsSwappedInWithHysteresis) {
  AnchorScheduler s(3, params());
  s.reportSuccess(0, 0, -5.0);
  s.reportSuccess(1, 0, -6.0);
  s.reportSuccess(2, 0, -7.0);
  ASSERT_EQ(s.state(2), State::kCandidate);
  // Within the hysteresis: stays out.
  s.reportSuccess(2, 10 * kMs, -4.0);
  EXPECT_EQ(s.state(2), State::kCandidate);
  // Clearly stronger: replaces the weakest active (1).
  s.reportSuccess(2, 20 * kMs, 0.0);
  EXPECT_EQ(s.state(2), State::kActive);
  EXPECT_EQ(s.state(1), State::kCandidate);
  EXPECT_EQ(s.state(0), State::kActive);
}

TEST(Dw3000Scheduler, ActiveStrengthIsSmoothedCandidateStrengthIsTheLatest) {
  AnchorSchedulerParams p = params();
  p.max_active = 1;
  p.strength_smoothing = 0.5;
  AnchorScheduler s(2, p);
  s.reportSuccess(0, 0, -10.0);
  s.reportSuccess(1, 0, -30.0);
  ASSERT_EQ(s.state(0), State::kActive);
  s.reportSuccess(0, kMs, -20.0);
  EXPECT_DOUBLE_EQ(s.strengthDb(0), -15.0);
  // The candidate came close: one poll is enough to swap it in.
  s.reportSuccess(1, 2 * kMs, 0.0);
  EXPECT_DOUBLE_EQ(s.strengthDb(1), 0.0);
  EXPECT_EQ(s.state(1), State::kActive);
  EXPECT_EQ(s.state(0), State::kCandidate);
}

TEST(Dw3000Scheduler, FailuresBackOffThenDropAndRediscoverFaster) {
  AnchorSchedulerParams p = params();
  p.range_rate_hz = 0.1;  // anchor 1 is not due during this test
  AnchorScheduler s(3, p);
  s.reportSuccess(0, 0, -1.0);
  s.reportSuccess(1, 0, -2.0);
  s.reportSuccess(2, 0, -9.0);
  ASSERT_EQ(s.state(0), State::kActive);
  std::int64_t now = 100 * kMs;
  EXPECT_FALSE(s.reportFailure(0, now));
  EXPECT_EQ(s.consecutiveFailures(0), 1);
  auto pick = s.next(now);
  EXPECT_EQ(pick.index, 0u);
  EXPECT_EQ(pick.at_ns, now + 20 * kMs);  // first back-off
  now = pick.at_ns;
  EXPECT_FALSE(s.reportFailure(0, now));
  EXPECT_EQ(s.next(now).at_ns, now + 40 * kMs);  // doubled
  now += 40 * kMs;
  EXPECT_TRUE(s.reportFailure(0, now));  // third in a row: dropped
  EXPECT_EQ(s.state(0), State::kCandidate);
  EXPECT_EQ(s.activeCount(), 1u);
  // The vacancy makes the next rediscovery due within the vacancy period.
  pick = s.next(now);
  EXPECT_TRUE(pick.discovery);
  EXPECT_LE(pick.at_ns, now + 20 * kMs);
  // Whoever answers fills the vacancy.
  s.reportSuccess(pick.index, pick.at_ns, -9.0);
  EXPECT_EQ(s.state(pick.index), State::kActive);
  EXPECT_EQ(s.activeCount(), 2u);
}

TEST(Dw3000Scheduler, BackoffIsCappedAndParametersAreChecked) {
  AnchorScheduler s(1, params());
  EXPECT_EQ(s.backoffNs(1), 20 * kMs);
  EXPECT_EQ(s.backoffNs(2), 40 * kMs);
  EXPECT_EQ(s.backoffNs(3), 80 * kMs);
  EXPECT_EQ(s.backoffNs(4), 100 * kMs);
  EXPECT_EQ(s.backoffNs(60), 100 * kMs);
  EXPECT_GT(AnchorScheduler::strengthFromRangeDb(1.0), AnchorScheduler::strengthFromRangeDb(10.0));
  EXPECT_DOUBLE_EQ(AnchorScheduler::strengthFromRangeDb(10.0), -20.0);
  AnchorSchedulerParams bad = params();
  bad.strength_smoothing = 0.0;
  EXPECT_THROW(AnchorScheduler(2, bad), std::invalid_argument);
  EXPECT_THROW(AnchorScheduler(0, params()), std::invalid_argument);
}

TEST(Dw3000Scheduler, UnansweredDiscoveryMakesACandidateWithoutStrength) {
  AnchorScheduler s(2, params());
  EXPECT_FALSE(s.reportFailure(0, 0));
  EXPECT_EQ(s.state(0), State::kCandidate);
  const auto pick = s.next(0);
  EXPECT_EQ(pick.index, 1u);  // the sweep continues first
  s.reportSuccess(1, kMs, -3.0);
  EXPECT_EQ(s.state(1), State::kActive);
  // Room in the set: the unanswered one is retried at the vacancy period.
  const auto retry = s.next(2 * kMs);
  EXPECT_EQ(retry.index, 0u);
  EXPECT_TRUE(retry.discovery);
  EXPECT_EQ(retry.at_ns, kMs + 20 * kMs);
}

}  // namespace
}  // namespace rilo::dw3000
