// Initialization attempts in a runner (Localizer::setInitRunner, issue 37):
// the caller keeps feeding samples while an attempt solves its window, and
// the tracker starts at the attempt's state and catches up with everything
// that came meanwhile. A runner driven by hand places each attempt's end at
// a chosen sample: the same data as inline, a slow core, one that never
// finishes, or one whose result comes after its data were dropped.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <string>

#include "estimation/tracking/localizer.h"
#include "sim/range_imu_scenario.h"
#include "support/online_run.h"

namespace rilo {
namespace {

/// Runs the started attempt once the owner has fed `delay_samples` more
/// samples (runDue), or at wait(); a negative delay: only at wait().
class HandRunner final : public InitAttemptRunner {
 public:
  explicit HandRunner(int delay_samples) : delay_samples_(delay_samples) {}
  void start(std::function<void()> attempt) override {
    ASSERT_TRUE(idle()) << "started while an attempt runs";
    attempt_ = std::move(attempt);
    waited_ = 0;
    ++started;
  }
  bool idle() const override { return !attempt_; }
  void wait() override { run(); }
  bool waitFor(double /*seconds*/) override {
    run();
    return true;
  }
  /// Called after each sample the test feeds.
  void runDue() {
    if (attempt_ && delay_samples_ >= 0 && waited_++ >= delay_samples_) run();
  }
  int started = 0, ran = 0;

 private:
  void run() {
    if (!attempt_) return;
    std::function<void()> attempt = std::move(attempt_);
    attempt_ = nullptr;
    attempt();
    ++ran;
  }
  int delay_samples_;
  int waited_ = 0;
  std::function<void()> attempt_;
};

LocalizerParams paramsFor(const sim::Scenario& s) { return testing::localizerParamsFor(s); }

struct FedRun {
  std::int64_t first_track_ns = -1;  ///< data time of the first tracked estimate
  std::int64_t fed_at_first_track_ns = -1;  ///< newest sample fed when it came
  std::int64_t last_fed_ns = 0;
  int tracked_updates = 0;
  double mean_error_m = 0.0;
  int most_attempts_in_one_call = 0;  ///< attempts one process() call ran inline
};

FedRun feed(const sim::Scenario& s, Localizer& localizer, HandRunner* runner, double until_s = 1e9) {
  FedRun run;
  std::size_t i = 0, r = 0;
  double sum = 0.0;
  const std::int64_t end_ns = s.imu.front().t_ns + static_cast<std::int64_t>(until_s * 1e9);
  while (i < s.imu.size() || r < s.ranges.size()) {
    std::int64_t t_ns = 0;
    if (r < s.ranges.size() && (i >= s.imu.size() || s.ranges[r].t_ns <= s.imu[i].t_ns)) {
      t_ns = s.ranges[r].t_ns;
      if (t_ns >= end_ns) break;
      localizer.addRange(s.ranges[r++]);
    } else {
      t_ns = s.imu[i].t_ns;
      if (t_ns >= end_ns) break;
      localizer.addImu(s.imu[i++]);
    }
    run.last_fed_ns = t_ns;
    const int attempts_before = localizer.initStatus().attempts;
    const int updates = localizer.process();
    if (!localizer.tracking()) {
      // With a runner the count grows only by what it ran and process() adopted.
      const int inline_attempts = runner ? localizer.initStatus().attempts - runner->ran
                                         : localizer.initStatus().attempts - attempts_before;
      run.most_attempts_in_one_call = std::max(run.most_attempts_in_one_call, inline_attempts);
    }
    if (runner) runner->runDue();
    if (updates > 0 && localizer.tracking()) {
      if (run.first_track_ns < 0) {
        run.first_track_ns = localizer.latest().t_ns;
        run.fed_at_first_track_ns = t_ns;
      }
      sum += (localizer.latest().T_w_b.p - s.truthAt(localizer.latest().t_ns).T_w_b.p).norm();
      ++run.tracked_updates;
    }
  }
  if (run.tracked_updates > 0) run.mean_error_m = sum / run.tracked_updates;
  return run;
}

sim::Scenario walk(double duration_s) {
  sim::ScenarioParams sp;
  sp.duration_s = duration_s;
  sp.seed = 3;
  return sim::simulateScenario(sp);
}

// An attempt that ends before the next sample sees the data an inline one
// sees: the same start, the same track. Meanwhile process() runs none itself.
TEST(LocalizerInitRunner, AnAttemptOnTheSameDataStartsTheSameTracker) {
  const sim::Scenario s = walk(40.0);
  Localizer inline_localizer(s.p_w_anchors, paramsFor(s));
  const FedRun inline_run = feed(s, inline_localizer, nullptr);
  ASSERT_TRUE(inline_localizer.tracking()) << inline_localizer.initStatus().message;
  EXPECT_GE(inline_run.most_attempts_in_one_call, 1) << "inline, process() runs the attempts";

  Localizer localizer(s.p_w_anchors, paramsFor(s));
  auto owned = std::make_unique<HandRunner>(0);
  HandRunner& runner = *owned;
  localizer.setInitRunner(std::move(owned));
  const FedRun run = feed(s, localizer, &runner);
  ASSERT_TRUE(localizer.tracking()) << localizer.initStatus().message;
  EXPECT_EQ(run.most_attempts_in_one_call, 0) << "with a runner, process() runs none";
  EXPECT_EQ(runner.started, runner.ran);
  EXPECT_EQ(runner.started, localizer.initStatus().attempts);
  EXPECT_EQ(localizer.initStatus().attempts, inline_localizer.initStatus().attempts);
  EXPECT_EQ(localizer.initStatus().message, inline_localizer.initStatus().message);
  EXPECT_EQ(localizer.initializations(), 1u);
  // Adopted one sample later: the hand-over replays that sample too.
  EXPECT_NEAR(static_cast<double>(run.first_track_ns - inline_run.first_track_ns) * 1e-9, 0.0, 0.1);
  EXPECT_NEAR(run.tracked_updates, inline_run.tracked_updates, 2);
  EXPECT_NEAR(run.mean_error_m, inline_run.mean_error_m, 0.01);
}

// A slow core: each attempt ends 8 s of data after it started. The tracker starts later, at the attempt's state, and catches up
// at once with every sample buffered since; then it tracks as well.
TEST(LocalizerInitRunner, ASlowAttemptIsCaughtUpWithTheSamplesThatCameMeanwhile) {
  const sim::Scenario s = walk(60.0);
  Localizer inline_localizer(s.p_w_anchors, paramsFor(s));
  const FedRun inline_run = feed(s, inline_localizer, nullptr);
  ASSERT_TRUE(inline_localizer.tracking());

  const double samples_per_s = static_cast<double>(s.imu.size() + s.ranges.size()) / 60.0;
  Localizer localizer(s.p_w_anchors, paramsFor(s));
  auto owned = std::make_unique<HandRunner>(static_cast<int>(8.0 * samples_per_s));
  HandRunner& runner = *owned;
  localizer.setInitRunner(std::move(owned));
  const FedRun run = feed(s, localizer, &runner);
  ASSERT_TRUE(localizer.tracking()) << localizer.initStatus().message;
  EXPECT_EQ(localizer.reinitializations(), 0u) << localizer.lastFailure();
  EXPECT_GT(run.fed_at_first_track_ns, inline_run.fed_at_first_track_ns + 5'000'000'000) << "adopted seconds later";
  // Caught up: the first estimate after the adoption is at the newest sample
  // fed, not at the attempt's hand-over state seconds before.
  EXPECT_LE(run.fed_at_first_track_ns - run.first_track_ns, 100'000'000);
  EXPECT_NEAR(static_cast<double>(localizer.latest().t_ns - run.last_fed_ns) * 1e-9, 0.0, 0.5);
  EXPECT_LT(run.mean_error_m, 1.0);
  EXPECT_LT(run.mean_error_m, inline_run.mean_error_m + 0.1);
  const auto sec = [&](std::int64_t t_ns) { return static_cast<double>(t_ns - s.imu.front().t_ns) * 1e-9; };
  std::printf("inline: tracking from %.2f s (fed %.2f s), %.3f m; slow attempts: from %.2f s (fed %.2f s), %.3f m\n",
              sec(inline_run.first_track_ns), sec(inline_run.fed_at_first_track_ns), inline_run.mean_error_m,
              sec(run.first_track_ns), sec(run.fed_at_first_track_ns), run.mean_error_m);
}

// An attempt still running when the data end is the last one: finish() waits
// for it and starts the tracker. Until then one attempt was started, none ran
// inline, and the samples kept being buffered.
TEST(LocalizerInitRunner, FinishTakesTheAttemptStillRunning) {
  const sim::Scenario s = walk(40.0);
  Localizer localizer(s.p_w_anchors, paramsFor(s));
  auto owned = std::make_unique<HandRunner>(-1);
  HandRunner& runner = *owned;
  localizer.setInitRunner(std::move(owned));
  const FedRun run = feed(s, localizer, &runner, 25.0);
  EXPECT_FALSE(localizer.tracking());
  EXPECT_TRUE(localizer.initAttemptRunning());
  EXPECT_EQ(runner.started, 1);
  EXPECT_EQ(runner.ran, 0);
  EXPECT_EQ(run.most_attempts_in_one_call, 0);
  EXPECT_EQ(localizer.initStatus().attempts, 0) << "nothing adopted yet";
  localizer.finish();
  EXPECT_EQ(runner.ran, 1);
  EXPECT_FALSE(localizer.initAttemptRunning());
  EXPECT_EQ(localizer.initStatus().attempts, 1);
  // The first attempt (3 s of data) may not be enough; when it is, the
  // tracker caught up to the end.
  if (localizer.tracking()) {
    EXPECT_NEAR(static_cast<double>(localizer.latest().t_ns - run.last_fed_ns) * 1e-9, 0.0, 0.5);
  } else {
    EXPECT_NE(localizer.initStatus().state, InitState::kInitialized);
  }
}

// finish() keeps the budget: an attempt already over it is told to stop
// before the wait, and ends unfinished. After finish() no attempt starts.
// abandonInitAttempt (a stop request) drops a running attempt unadopted.
TEST(LocalizerInitRunner, FinishKeepsTheBudgetAndStartsNoMoreAttempts) {
  const sim::Scenario s = walk(40.0);
  LocalizerParams p = paramsFor(s);
  p.init_attempt_budget_s = 0.0;
  Localizer localizer(s.p_w_anchors, p);
  auto owned = std::make_unique<HandRunner>(-1);
  HandRunner& runner = *owned;
  localizer.setInitRunner(std::move(owned));
  feed(s, localizer, &runner, 25.0);
  ASSERT_EQ(runner.started, 1);
  localizer.finish();
  EXPECT_FALSE(localizer.tracking());
  EXPECT_EQ(localizer.initStatus().attempts, 1);
  EXPECT_NE(localizer.initStatus().message.find("stopped unfinished"), std::string::npos) << localizer.initStatus().message;
  // Samples after the data fed so far (an attempt would be due within 1 s).
  const std::int64_t t_fed = s.imu.front().t_ns + 25'000'000'000;
  std::size_t i = 0;
  while (s.imu[i].t_ns < t_fed) ++i;
  const std::uint64_t dropped_before = localizer.inputDropped().total();
  for (const std::size_t end = i + 2000; i < end; ++i) {
    localizer.addImu(s.imu[i]);
    localizer.process();
  }
  EXPECT_EQ(localizer.inputDropped().total(), dropped_before) << "the samples were taken";
  EXPECT_EQ(runner.started, 1) << "no attempt after finish()";

  Localizer stopped(s.p_w_anchors, paramsFor(s));
  auto owned2 = std::make_unique<HandRunner>(-1);
  HandRunner& runner2 = *owned2;
  stopped.setInitRunner(std::move(owned2));
  feed(s, stopped, &runner2, 25.0);
  ASSERT_TRUE(stopped.initAttemptRunning());
  stopped.abandonInitAttempt();
  EXPECT_FALSE(stopped.initAttemptRunning());
  EXPECT_EQ(runner2.ran, 1);
  EXPECT_EQ(stopped.initStatus().attempts, 0) << "dropped, not adopted";
}

// A result that comes after its data were dropped (over max_window_s of
// data later) cannot be caught up: refused, said so, and the next attempt
// starts.
TEST(LocalizerInitRunner, AResultWhoseDataWereDroppedIsRefused) {
  const sim::Scenario s = walk(90.0);
  LocalizerParams p = paramsFor(s);
  p.init.min_window_s = 20.0;  // a first window a start is sure on (it is, inline)
  p.init.window_s = 20.0;
  const double samples_per_s = static_cast<double>(s.imu.size() + s.ranges.size()) / 90.0;
  Localizer localizer(s.p_w_anchors, p);
  auto owned = std::make_unique<HandRunner>(static_cast<int>(62.0 * samples_per_s));
  HandRunner& runner = *owned;
  localizer.setInitRunner(std::move(owned));
  feed(s, localizer, &runner);
  EXPECT_FALSE(localizer.tracking());
  EXPECT_EQ(runner.ran, 1);
  EXPECT_EQ(runner.started, 2) << "the next attempt started at once";
  EXPECT_EQ(localizer.initStatus().attempts, 1);
  EXPECT_EQ(localizer.initStatus().state, InitState::kBatchRejected);
  EXPECT_NE(localizer.initStatus().message.find("no longer buffered"), std::string::npos) << localizer.initStatus().message;

  Localizer inline_localizer(s.p_w_anchors, p);
  feed(s, inline_localizer, nullptr, 20.6);
  EXPECT_TRUE(inline_localizer.tracking()) << "inline, the first attempt starts: " << inline_localizer.initStatus().message;
  EXPECT_EQ(inline_localizer.initStatus().attempts, 1);
}

// init_attempt_budget_s: an attempt still running at a process() call past
// its budget is told to stop; it ends unfinished, says so, and later ones
// keep coming. A budget of 0 stops every attempt.
TEST(LocalizerInitRunner, AnAttemptOverItsBudgetIsToldToStop) {
  const sim::Scenario s = walk(40.0);
  LocalizerParams p = paramsFor(s);
  p.init_attempt_budget_s = 0.0;
  Localizer localizer(s.p_w_anchors, p);
  auto owned = std::make_unique<HandRunner>(1);  // ends after the next call, which finds it over budget
  HandRunner& runner = *owned;
  localizer.setInitRunner(std::move(owned));
  feed(s, localizer, &runner);
  EXPECT_FALSE(localizer.tracking());
  EXPECT_GE(runner.started, 10) << "attempts keep coming";
  EXPECT_GE(localizer.initAttemptsOverBudget(), static_cast<std::uint64_t>(runner.started - 1));
  EXPECT_EQ(localizer.initStatus().state, InitState::kBatchRejected);
  EXPECT_NE(localizer.initStatus().message.find("stopped unfinished"), std::string::npos) << localizer.initStatus().message;

  LocalizerParams no_bound = paramsFor(s);
  no_bound.init_attempt_budget_s = std::numeric_limits<double>::infinity();
  Localizer unbounded(s.p_w_anchors, no_bound);
  auto owned2 = std::make_unique<HandRunner>(1);
  HandRunner& runner2 = *owned2;
  unbounded.setInitRunner(std::move(owned2));
  feed(s, unbounded, &runner2);
  EXPECT_TRUE(unbounded.tracking()) << unbounded.initStatus().message;
  EXPECT_EQ(unbounded.initAttemptsOverBudget(), 0u);
}

TEST(LocalizerInitRunner, TheBudgetIsValidated) {
  LocalizerParams p;
  p.init_attempt_budget_s = -1.0;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p.init_attempt_budget_s = std::nan("");
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p.init_attempt_budget_s = std::numeric_limits<double>::infinity();
  EXPECT_NO_THROW(p.validate());
}

}  // namespace
}  // namespace rilo
